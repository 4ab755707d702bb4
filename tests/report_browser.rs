//! The case report in a real browser: `otoatlas run` on sample case-001 writes report.html,
//! headless Chromium (Debian's `chromium`) opens it from disk with the network blocked and
//! renders a screenshot; the test checks that Chromium succeeded without a loading error and
//! that the inline overlay PNGs decoded: pixels of each contour colour (colours nothing else on
//! the page uses) lying on grey CT pixels, not on the white page.
//!
//! Skips, saying why, when `chromium` is not installed, unless `OTOATLAS_REQUIRE_BROWSER=1`
//! (`common::chromium`).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common;
use otoatlas::report::slices::{REGISTERED_COLOUR, RIGID_COLOUR, SEGMENTATION_COLOUR};

/// Screenshot size: tall enough to hold the summary, metrics and the nine overlays.
const WIDTH: usize = 1280;
const HEIGHT: usize = 3200;
/// Chromium gets this long before the test gives up on it (it takes a few seconds).
const BROWSER_LIMIT: Duration = Duration::from_secs(180);

/// Runs Chromium to completion (killed after `BROWSER_LIMIT`): (success, stderr).
fn screenshot(browser: &Path, page: &Path, shot: &Path, profile: &Path) -> (bool, String) {
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
            &format!("--screenshot={}", shot.display()),
            &format!("file://{}", page.display()),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("chromium starts");
    let mut stderr = child.stderr.take().expect("stderr piped");
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut text).ok();
        text
    });
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
    (status.success(), reader.join().unwrap_or_default())
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
    let (ok, stderr) = screenshot(&browser, &page, &shot, &dir.path().join("profile"));
    assert!(ok, "chromium failed:\n{stderr}");
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
