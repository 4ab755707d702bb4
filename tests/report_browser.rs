//! The reports in a real browser, headless Chromium (Debian's `chromium`), opening them from disk
//! with the network blocked.
//!
//! - The case report of `otoatlas run` on sample case-001: Chromium renders a screenshot without
//!   a loading error, and the inline overlay PNGs decoded: pixels of each contour colour (colours
//!   nothing else on the page uses) lie on grey CT pixels, not on the white page.
//! - The charts of a case report and of the cohort report (`otoatlas batch` over the sample
//!   cases): a copy of each page with `report_browser/chart_layout.js` appended is dumped by
//!   Chromium (`--dump-dom`) with the script's measures of the rendered charts; every text lies
//!   within its chart, no two tick labels of an axis overlap, no legend covers a curve or a point,
//!   frequency axes read in Hz on a log scale, iteration axes in whole numbers, and the cohort's
//!   box plots show every case and the 0.2 mm and 0.5 mm target lines where those values lie.
//!
//! Skips, saying why, when `chromium` is not installed, unless `OTOATLAS_REQUIRE_BROWSER=1`
//! (`common::chromium`).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::common;
use otoatlas::report::slices::{REGISTERED_COLOUR, RIGID_COLOUR, SEGMENTATION_COLOUR};

/// Screenshot size: tall enough to hold the summary, metrics and the nine overlays.
const WIDTH: usize = 1280;
const HEIGHT: usize = 3200;
/// Chromium gets this long before the test gives up on it (it takes a few seconds).
const BROWSER_LIMIT: Duration = Duration::from_secs(180);

/// Runs headless Chromium on `page` with `action` (`--screenshot=...` or `--dump-dom`) to
/// completion (killed after `BROWSER_LIMIT`): (success, stdout, stderr).
fn chromium(browser: &Path, page: &Path, action: &str, profile: &Path) -> (bool, String, String) {
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
            "--disable-background-networking",
            "--no-first-run",
            "--enable-logging=stderr",
            "--host-resolver-rules=MAP * ~NOTFOUND",
            &format!("--user-data-dir={}", profile.display()),
            &format!("--window-size={WIDTH},{HEIGHT}"),
            action,
            &format!("file://{}", page.display()),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("chromium starts");
    let read = |mut pipe: Box<dyn std::io::Read + Send>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            pipe.read_to_string(&mut text).ok();
            text
        })
    };
    let stdout = read(Box::new(child.stdout.take().expect("stdout piped")));
    let stderr = read(Box::new(child.stderr.take().expect("stderr piped")));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("chromium runs") {
            break status;
        }
        if started.elapsed() > BROWSER_LIMIT {
            child.kill().ok();
            child.wait().ok();
            panic!("chromium did not finish within {BROWSER_LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    (
        status.success(),
        stdout.join().unwrap_or_default(),
        stderr.join().unwrap_or_default(),
    )
}

/// Fails on any loading or script problem Chromium logged.
fn assert_clean_load(stderr: &str) {
    for problem in [
        "net::ERR",
        "Failed to load",
        "Not allowed to load",
        "Refused to",
        "Uncaught",
        "CONSOLE",
    ] {
        let line = stderr.lines().find(|l| l.contains(problem));
        assert!(line.is_none(), "chromium reported a problem: {line:?}");
    }
}

/// The screenshot as RGB rows.
fn decode(path: &Path) -> (usize, usize, Vec<[u8; 3]>) {
    let file = std::fs::File::open(path).expect("chromium wrote the screenshot");
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .expect("a PNG screenshot");
    let mut buf = vec![0; reader.output_buffer_size().expect("a sane size")];
    let info = reader.next_frame(&mut buf).expect("PNG data decodes");
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("unexpected screenshot colour type {other:?}"),
    };
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    let pixels = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (info.width as usize, info.height as usize, pixels)
}

/// A CT pixel: grey (equal channels), neither the white page nor pure black text.
fn is_ct_grey(p: [u8; 3]) -> bool {
    p[0] == p[1] && p[1] == p[2] && p[0] > 0 && p[0] < 250
}

#[test]
fn report_renders_in_chromium_with_the_overlays_decoded() {
    let Some(browser) = common::chromium() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_cases/case-001");
    let run = Command::new(env!("CARGO_BIN_EXE_otoatlas"))
        .arg("run")
        .arg(&case)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "run failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let page = out.join("report.html").canonicalize().unwrap();
    let shot = dir.path().join("shot.png");
    let action = format!("--screenshot={}", shot.display());
    let (ok, _, stderr) = chromium(&browser, &page, &action, &dir.path().join("profile"));
    assert!(ok, "chromium failed:\n{stderr}");
    assert_clean_load(&stderr);

    let (width, height, pixels) = decode(&shot);
    assert_eq!((width, height), (WIDTH, HEIGHT));
    for (name, colour) in [
        ("rigid", RIGID_COLOUR),
        ("registered", REGISTERED_COLOUR),
        ("segmentation", SEGMENTATION_COLOUR),
    ] {
        // the contour pixels, and how many of them sit on CT: ≥ 20 grey pixels around them
        let at: Vec<(usize, usize)> = (0..pixels.len())
            .filter(|&k| pixels[k] == colour)
            .map(|k| (k % width, k / width))
            .collect();
        let on_ct = at
            .iter()
            .filter(|&&(x, y)| {
                let grey = (y.saturating_sub(4)..(y + 5).min(height))
                    .flat_map(|yy| {
                        (x.saturating_sub(4)..(x + 5).min(width)).map(move |xx| (xx, yy))
                    })
                    .filter(|&(xx, yy)| is_ct_grey(pixels[yy * width + xx]))
                    .count();
                grey >= 20
            })
            .count();
        println!("{name}: {} contour pixels, {on_ct} on CT", at.len());
        assert!(at.len() >= 1000, "{name}: {} contour pixels", at.len());
        assert!(
            on_ct * 10 >= at.len() * 8,
            "{name}: only {on_ct} of {} contour pixels lie on CT pixels",
            at.len()
        );
    }
}

/// The measures `chart_layout.js` takes of every chart of `page`, as Chromium rendered them.
fn chart_layout(browser: &Path, page: &Path, dir: &Path) -> Vec<Value> {
    let html = std::fs::read_to_string(page).expect("the report");
    let script = include_str!("report_browser/chart_layout.js");
    let measured = dir.join("measured.html");
    let body_end = html.rfind("</body>").expect("the report's </body>");
    let copy = format!(
        "{}<script>{script}</script>{}",
        &html[..body_end],
        &html[body_end..]
    );
    std::fs::write(&measured, copy).unwrap();
    let (ok, dom, stderr) = chromium(browser, &measured, "--dump-dom", &dir.join("profile"));
    assert!(ok, "chromium failed:\n{stderr}");
    assert_clean_load(&stderr);
    let start = dom
        .find("<pre id=\"chart-layout\">")
        .expect("the script ran")
        + 23;
    let end = start + dom[start..].find("</pre>").expect("</pre>");
    let layout: Value = serde_json::from_str(&dom[start..end]).expect("the layout is JSON");
    layout["charts"].as_array().expect("charts").clone()
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// [x, y, width, height] of a measured box.
fn rect(v: &Value) -> [f64; 4] {
    let n = numbers(v);
    [n[0], n[1], n[2], n[3]]
}

/// Whether two boxes share any area.
fn overlap(a: [f64; 4], b: [f64; 4]) -> bool {
    a[0] < b[0] + b[2] && b[0] < a[0] + a[2] && a[1] < b[1] + b[3] && b[1] < a[1] + a[3]
}

fn inside(p: (f64, f64), r: [f64; 4]) -> bool {
    p.0 > r[0] && p.0 < r[0] + r[2] && p.1 > r[1] && p.1 < r[1] + r[3]
}

/// The tick labels of an axis: (text, box).
fn ticks(axis: &Value) -> Vec<(String, [f64; 4])> {
    axis["ticks"]
        .as_array()
        .expect("ticks")
        .iter()
        .map(|t| (t["text"].as_str().unwrap().to_string(), rect(&t["box"])))
        .collect()
}

/// The centre of a label along its axis (x for the horizontal axis, y for the vertical).
fn along(b: [f64; 4], horizontal: bool) -> f64 {
    if horizontal {
        b[0] + b[2] / 2.0
    } else {
        b[1] + b[3] / 2.0
    }
}

/// Checks that the labels' centres lie on a straight line of `position(label)`; returns the
/// line (position → page coordinate) as (offset, slope).
fn assert_axis_maps(chart: &str, labels: &[(f64, f64)]) -> (f64, f64) {
    let (first, last) = (labels[0], labels[labels.len() - 1]);
    let slope = (last.1 - first.1) / (last.0 - first.0);
    let offset = first.1 - slope * first.0;
    for (value, at) in labels {
        let expected = offset + slope * value;
        assert!(
            (expected - at).abs() < 1.5,
            "{chart}: the label of {value} sits at {at:.1}, not at {expected:.1} on its scale"
        );
    }
    (offset, slope)
}

/// What holds for every chart: every text inside the figure, no two texts overlapping (the tick
/// labels of an axis, those of the two axes in the corner, titles, legend), no legend over a
/// curve or a point.
fn assert_chart_reads_cleanly(chart: &Value) {
    let title = chart["title"].as_str().unwrap_or("?");
    let view = rect(&chart["view_box"]);
    for t in chart["texts"].as_array().unwrap() {
        let b = rect(&t["box"]);
        assert!(
            b[0] >= view[0] - 0.5
                && b[1] >= view[1] - 0.5
                && b[0] + b[2] <= view[0] + view[2] + 0.5
                && b[1] + b[3] <= view[1] + view[3] + 0.5,
            "{title}: the text {:?} at {b:?} leaves the figure {view:?}",
            t["text"]
        );
    }
    let texts: Vec<(&str, [f64; 4])> = chart["texts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (t["text"].as_str().unwrap(), rect(&t["box"])))
        .collect();
    for (i, a) in texts.iter().enumerate() {
        for b in &texts[i + 1..] {
            assert!(
                !overlap(a.1, b.1),
                "{title}: the texts {:?} at {:?} and {:?} at {:?} overlap",
                a.0,
                a.1,
                b.0,
                b.1
            );
        }
    }
    if let Some(legend) = chart["legend"].as_object() {
        let b = rect(&legend["box"]);
        for curve in chart["curves"].as_array().unwrap() {
            let points: Vec<Vec<f64>> = curve.as_array().unwrap().iter().map(numbers).collect();
            // the vertices and 20 points along every segment
            for pair in points.windows(2) {
                for k in 0..=20 {
                    let t = k as f64 / 20.0;
                    let p = (
                        pair[0][0] + t * (pair[1][0] - pair[0][0]),
                        pair[0][1] + t * (pair[1][1] - pair[0][1]),
                    );
                    assert!(
                        !inside(p, b),
                        "{title}: the legend {b:?} covers the curve at {p:?}"
                    );
                }
            }
        }
        for p in chart["points"].as_array().unwrap() {
            let p = numbers(p);
            assert!(
                !inside((p[0], p[1]), b),
                "{title}: the legend {b:?} covers the point {p:?}"
            );
        }
    }
}

/// A frequency label in Hz: "250", "1k", "2.5k".
fn hertz(label: &str) -> Option<f64> {
    match label.strip_suffix('k') {
        Some(thousands) => thousands.parse::<f64>().ok().map(|v| v * 1000.0),
        None => label.parse().ok(),
    }
}

#[test]
#[ignore = "heavy: a batch of the sample cases and Chromium, about 90 s in debug; scripts/test.sh runs it"]
fn charts_read_cleanly_in_chromium() {
    let Some(browser) = common::chromium() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cohort");
    let samples = common::root().join("sample_cases");
    let (samples, out_arg) = (samples.to_str().unwrap(), out.to_str().unwrap());
    let batch = common::otoatlas(&["batch", "--jobs", "2", "--quiet", samples, "--out", out_arg]);
    assert!(
        batch.status.success(),
        "batch failed: {}",
        String::from_utf8_lossy(&batch.stderr)
    );

    // the case report: histograms, convergence, transfer function and static pressure
    let case = chart_layout(
        &browser,
        &out.join("cases/case-001/report.html")
            .canonicalize()
            .unwrap(),
        dir.path(),
    );
    assert_eq!(
        case.len(),
        9,
        "5 histograms (the 4 structures and the chain as one solid), convergence and 3 mechanics charts"
    );
    case.iter().for_each(assert_chart_reads_cleanly);
    let texts: Vec<&str> = case
        .iter()
        .flat_map(|c| c["texts"].as_array().unwrap())
        .filter_map(|t| t["text"].as_str())
        .collect();
    assert!(
        !texts.iter().any(|t| t.contains("log10")),
        "frequency as log10"
    );
    let frequency: Vec<&Value> = case
        .iter()
        .filter(|c| c["x"]["numbers"] == "hertz")
        .collect();
    assert_eq!(
        frequency.len(),
        2,
        "the transfer function's magnitude and phase"
    );
    for chart in frequency {
        assert_eq!(chart["x"]["scale"], "log");
        let labels: Vec<(f64, f64)> = ticks(&chart["x"])
            .iter()
            .map(|(text, b)| {
                let hz = hertz(text).unwrap_or_else(|| panic!("{text:?} is no frequency in Hz"));
                (hz.log10(), along(*b, true))
            })
            .collect();
        let hz: Vec<f64> = labels.iter().map(|l| 10f64.powf(l.0).round()).collect();
        assert!(hz.contains(&1000.0) && hz.contains(&4000.0), "{hz:?}");
        // the positions follow log10 of the frequencies the labels read
        assert_axis_maps(chart["title"].as_str().unwrap(), &labels);
    }
    let convergence = case
        .iter()
        .find(|c| c["title"] == "deformable registration")
        .expect("the convergence chart");
    assert_eq!(convergence["x"]["numbers"], "integer");
    let iterations: Vec<(f64, f64)> = ticks(&convergence["x"])
        .iter()
        .map(|(text, b)| {
            let n: i64 = text
                .parse()
                .unwrap_or_else(|_| panic!("iteration tick {text:?} is not a whole number"));
            (n as f64, along(*b, true))
        })
        .collect();
    assert!(iterations.len() >= 2);
    assert_axis_maps("convergence", &iterations);

    // the cohort report: a point per scored case and structure, the targets where they lie
    let cohort = chart_layout(
        &browser,
        &out.join("cohort.html").canonicalize().unwrap(),
        dir.path(),
    );
    assert_eq!(cohort.len(), 2, "the MASD and HD95 box plots");
    cohort.iter().for_each(assert_chart_reads_cleanly);
    let csv = std::fs::read_to_string(out.join("cohort.csv")).unwrap();
    let mut rows = csv.lines().map(|l| l.split(',').collect::<Vec<&str>>());
    let header = rows.next().unwrap();
    let rows: Vec<Vec<&str>> = rows.filter(|r| r[1] == "ok").collect();
    for (chart, column, target) in [
        (&cohort[0], "registered_masd", 0.2),
        (&cohort[1], "registered_hd95", 0.5),
    ] {
        let title = chart["title"].as_str().unwrap();
        let col = header.iter().position(|h| *h == column).unwrap();
        let values: Vec<f64> = rows.iter().map(|r| r[col].parse().unwrap()).collect();
        assert!(values.len() >= 9, "3 cases × their structures");
        let labels: Vec<(f64, f64)> = ticks(&chart["y"])
            .iter()
            .map(|(text, b)| (text.parse().unwrap(), along(*b, false)))
            .collect();
        let (offset, slope) = assert_axis_maps(title, &labels);
        let points = chart["points"].as_array().unwrap();
        assert_eq!(points.len(), values.len(), "{title}: one point per case");
        for p in points {
            let y = numbers(p)[1];
            assert!(
                values.iter().any(|v| (offset + slope * v - y).abs() < 1.0),
                "{title}: a point at y = {y} holds none of the cases' values"
            );
        }
        let targets = chart["targets"].as_array().unwrap();
        assert_eq!(targets.len(), 1, "{title}: one target line");
        assert_eq!(targets[0]["value"].as_f64(), Some(target));
        let y = targets[0]["y"].as_f64().unwrap();
        assert!(
            (offset + slope * target - y).abs() < 1.0,
            "{title}: the {target} mm target line is drawn at y = {y}"
        );
        let legend = chart["legend"]["texts"].as_array().expect("a legend");
        assert!(
            legend
                .iter()
                .any(|t| t.as_str().unwrap().contains(&format!("{target} mm"))),
            "{title}: the target line is named in the legend: {legend:?}"
        );
    }
}
