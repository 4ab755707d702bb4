//! The landmark checks on real images: the sample cases' own picks pass without warning; umbo
//! and IMJ exchanged, or IMJ and ISJ, are refused as swaps that the distances and the image
//! both confirm; umbo and ISJ exchanged is refused where the distances confirm it too and a
//! warning from the image alone where they stay typical (bands widened to overlap); a swap the distances suggest is only a warning without an
//! image or on an image that shows no bone. End to end: `run` refuses a swapped file with exit
//! code 2 naming it, and writes an unusual pick's warning into metrics.json and report.html;
//! `landmarks` reports a suspected swap in its JSON.

use std::path::{Path, PathBuf};

use crate::common;
use otoatlas::atlas::{Atlas, load_atlas};
use otoatlas::config::Config;
use otoatlas::ear::{Side, read_landmarks, write_json};
use otoatlas::image::{LoadedImage, Sampler};
use otoatlas::register::landmarks::{
    ImageCheck, LandmarkError, LandmarkWarning, check_landmarks, check_landmarks_on_image,
};
use otoatlas::register::{LandmarkName, Landmarks};

struct Case {
    landmarks: Landmarks,
    side: Side,
    atlas: Atlas,
    image: LoadedImage,
    config: Config,
}

fn case(name: &str) -> Case {
    let dir = common::root().join("sample_cases").join(name);
    let file = read_landmarks(&dir.join("landmarks.json")).unwrap();
    let side = file.side.expect("the sample cases name their side");
    let config = Config::default_config().unwrap();
    Case {
        landmarks: file.landmarks,
        side,
        atlas: load_atlas(None, Some(side)).unwrap(),
        image: otoatlas::image::load(&dir.join("image.nii.gz"), None, &config.ingest).unwrap(),
        config,
    }
}

fn exchanged(l: &Landmarks, x: LandmarkName, y: LandmarkName) -> Landmarks {
    let mut pts = l.points();
    pts.swap(x as usize, y as usize);
    Landmarks::from_points(pts)
}

fn on_image(c: &Case, l: &Landmarks) -> Result<Vec<LandmarkWarning>, LandmarkError> {
    let sampler = Sampler::new(&c.image.volume).unwrap();
    on(c, l, &sampler)
}

fn on(c: &Case, l: &Landmarks, sampler: &Sampler) -> Result<Vec<LandmarkWarning>, LandmarkError> {
    let step = c
        .image
        .volume
        .spacing
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let check = ImageCheck {
        atlas: &c.atlas,
        sampler,
        step_mm: step,
        probe: &c.config.deform.probe,
        with_scale: c.config.rigid.with_scale,
    };
    check_landmarks_on_image(l, &check, &c.config.landmarks)
}

use LandmarkName::{Incudomalleolar as Imj, Incudostapedial as Isj, Umbo};

#[test]
fn the_sample_cases_picks_pass_and_swaps_are_refused_or_warned_by_the_image() {
    let (mut refused_by_both, mut warned_by_image) = (0, 0);
    for name in ["case-001", "case-002", "case-003"] {
        let c = case(name);
        assert_eq!(on_image(&c, &c.landmarks).unwrap(), vec![], "{name}");
        // the distances and the image agree: refused, naming the pair, with the figures
        for (x, y) in [(Umbo, Imj), (Imj, Isj)] {
            match on_image(&c, &exchanged(&c.landmarks, x, y)) {
                Err(
                    e @ LandmarkError::Swapped {
                        a,
                        b,
                        swapped_found,
                        given_found,
                        swapped_offset_mm,
                        given_offset_mm,
                        ..
                    },
                ) => {
                    // exchanged back, the atlas lies on the chain
                    assert_eq!([a, b], [x.key(), y.key()], "{name}");
                    assert!(swapped_found > 80.0, "{name} {x:?}-{y:?}: {e}");
                    assert!(given_found < 40.0, "{name} {x:?}-{y:?}: {e}");
                    assert!(swapped_offset_mm < given_offset_mm, "{name}: {e}");
                    let text = e.to_string();
                    assert!(text.contains(&format!("exchange {a} and {b}")), "{text}");
                }
                other => panic!("{name} {x:?}-{y:?}: {other:?}"),
            }
        }
        // umbo and ISJ exchanged: umbo-IMJ and IMJ-ISJ trade places. With the default bands
        // the exchanged distances leave their typical bands on every sample case (case-001:
        // umbo-IMJ 5.98 mm becomes IMJ-ISJ, above its 5.4 mm), so the distances and the image
        // agree and it is refused. Where the two typical bands overlap enough for both to stay
        // typical (here widened to 3.4-6.6 mm, umbo-IMJ possible from 3.0 mm), the distances cannot tell and the image's word
        // is a warning.
        let s = exchanged(&c.landmarks, Umbo, Isj);
        let mut overlapping = c.config.clone();
        overlapping.landmarks.umbo_imj_typical_mm = [3.4, 6.6];
        overlapping.landmarks.imj_isj_typical_mm = [3.4, 6.6];
        overlapping.landmarks.umbo_imj_possible_mm = [3.0, 8.0];
        for config in [&c.config, &overlapping] {
            let bands = config.landmarks.bands();
            let [p, q, r] = s.points();
            let d = [(p - q).norm(), (p - r).norm(), (q - r).norm()];
            let typical = (0..3).all(|k| {
                let [lo, hi] = bands[k].typical_mm;
                (lo..=hi).contains(&d[k])
            });
            let sampler = Sampler::new(&c.image.volume).unwrap();
            let check = ImageCheck {
                atlas: &c.atlas,
                sampler: &sampler,
                step_mm: c
                    .image
                    .volume
                    .spacing
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min),
                probe: &config.deform.probe,
                with_scale: config.rigid.with_scale,
            };
            match (
                typical,
                check_landmarks_on_image(&s, &check, &config.landmarks),
            ) {
                (false, Err(LandmarkError::Swapped { a, b, .. })) => {
                    assert_eq!([a, b], [Umbo.key(), Isj.key()], "{name}");
                    refused_by_both += 1;
                }
                (true, Ok(w)) => match &w[..] {
                    [
                        LandmarkWarning::SuspectedSwap {
                            a,
                            b,
                            by_distances: false,
                            image: Some(e),
                            ..
                        },
                    ] => {
                        assert_eq!([a.as_str(), b.as_str()], [Umbo.key(), Isj.key()]);
                        assert!(e.confirms_swap, "{name}: {e:?}");
                        assert!(w[0].to_string().contains("the distances cannot tell"));
                        warned_by_image += 1;
                    }
                    other => panic!("{name}: {other:?}"),
                },
                (typical, other) => panic!("{name}: typical {typical} {d:?}: {other:?}"),
            }
        }
    }
    // each outcome of the umbo-ISJ exchange on every case: refused with the default bands,
    // a warning from the image alone with the overlapping ones
    assert_eq!((refused_by_both, warned_by_image), (3, 3));
}

/// Umbo and IMJ exchanged on case-001: the distances suggest the swap (exchanged back, all
/// typical). Without an image, or on an image with no bone in it (the case's geometry, every
/// voxel soft tissue), nothing confirms it: a warning naming the pair, not a refusal.
#[test]
fn a_swap_only_the_distances_suggest_is_a_warning() {
    let c = case("case-001");
    let swapped = exchanged(&c.landmarks, Umbo, Imj);
    let atlas = c.atlas.landmark_positions(c.atlas.nodes());
    let sampler = Sampler::new(&c.image.volume).unwrap();
    let without = check_landmarks(&swapped, Some(&sampler), Some(&atlas), &c.config.landmarks)
        .expect("a warning, not an error");
    let mut blank = c.image.volume.clone();
    blank.data.iter_mut().for_each(|v| *v = 40.0);
    let blank_sampler = Sampler::new(&blank).unwrap();
    let on_blank = on(&c, &swapped, &blank_sampler).expect("a warning, not an error");
    for (what, w, expect_image) in [("no image", &without, false), ("blank", &on_blank, true)] {
        let swap: Vec<&LandmarkWarning> = w
            .iter()
            .filter(|w| matches!(w, LandmarkWarning::SuspectedSwap { .. }))
            .collect();
        match swap[..] {
            [
                LandmarkWarning::SuspectedSwap {
                    a,
                    b,
                    by_distances: true,
                    image,
                    given_mm,
                    swapped_mm,
                    ..
                },
            ] => {
                assert_eq!([a.as_str(), b.as_str()], [Umbo.key(), Imj.key()], "{what}");
                assert_eq!(image.is_some(), expect_image, "{what}");
                assert!(image.is_none_or(|e| !e.confirms_swap), "{what}");
                // exchanging umbo and IMJ exchanges umbo-ISJ and IMJ-ISJ
                assert_eq!(
                    [given_mm[1], given_mm[2]],
                    [swapped_mm[2], swapped_mm[1]],
                    "{what}"
                );
            }
            _ => panic!("{what}: {w:?}"),
        }
        let text = swap[0].to_string();
        let expected = match expect_image {
            false => "no image was checked, kept as given",
            true => "but the image does not confirm it",
        };
        assert!(text.contains(expected), "{what}: {text}");
    }
}

fn write_landmarks(dir: &Path, l: &Landmarks, side: Side) -> PathBuf {
    let path = dir.join("picks.json");
    std::fs::write(&path, write_json(l, Some(side))).unwrap();
    path
}

#[test]
fn run_refuses_a_swapped_file_with_exit_2_naming_it() {
    let c = case("case-001");
    let dir = tempfile::tempdir().unwrap();
    let picks = write_landmarks(dir.path(), &exchanged(&c.landmarks, Umbo, Imj), c.side);
    let case_dir = common::root().join("sample_cases/case-001");
    let out = common::otoatlas(&[
        "run",
        case_dir.to_str().unwrap(),
        "--out",
        dir.path().join("out").to_str().unwrap(),
        "--landmarks",
        picks.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("picks.json") && stderr.contains("umbo and incudomalleolar are swapped"),
        "{stderr}"
    );
    assert!(!dir.path().join("out/stages/rigid.json").exists());
}

/// An ISJ picked 0.6 mm off, away from the umbo (umbo-ISJ 3.6 mm, above its typical band):
/// the case runs, and the warning with its figures is in the log, metrics.json and the report.
#[test]
fn run_reports_an_unusual_pick_in_metrics_and_report() {
    let c = case("case-001");
    let mut l = c.landmarks;
    let away = (l.incudostapedial - l.umbo).normalize();
    l.incudostapedial += away * 0.6;
    let dir = tempfile::tempdir().unwrap();
    let picks = write_landmarks(dir.path(), &l, c.side);
    let config = common::config_without_validation(dir.path());
    let out_dir = dir.path().join("out");
    let case_dir = common::root().join("sample_cases/case-001");
    let out = common::otoatlas(&[
        "run",
        case_dir.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--landmarks",
        picks.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("landmark warning: umbo-ISJ is 3.62 mm"),
        "{stderr}"
    );
    let metrics: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("metrics.json")).unwrap()).unwrap();
    let warnings = metrics["landmark_warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert_eq!(w["kind"], "unusual_distance");
    assert_eq!(w["pair"], "umbo-ISJ");
    assert!(
        (w["patient_mm"].as_f64().unwrap() - 3.62).abs() < 0.005,
        "{w}"
    );
    assert_eq!(w["typical_mm"], serde_json::json!([2.1, 3.35]));
    assert!(
        w["message"]
            .as_str()
            .unwrap()
            .contains("the atlas has 2.77 mm")
    );
    // typed: the report's reader gets the same warning back
    let typed: LandmarkWarning = serde_json::from_value(w.clone()).unwrap();
    assert!(matches!(typed, LandmarkWarning::UnusualDistance { .. }));
    let html = std::fs::read_to_string(out_dir.join("report.html")).unwrap();
    assert!(
        html.contains("<p class=\"warn\">landmark warning: umbo-ISJ is 3.62 mm"),
        "report note"
    );
}

#[test]
fn landmarks_command_warns_of_a_suspected_swap_in_its_json() {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let c = case("case-001");
    let s = exchanged(&c.landmarks, Umbo, Imj);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("picks.fcsv");
    let case_dir = common::root().join("sample_cases/case-001");
    let mut child = Command::new(env!("CARGO_BIN_EXE_otoatlas"))
        .args([
            "landmarks",
            case_dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--json",
            "--quiet",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let input: String = s
        .points()
        .iter()
        .map(|p| format!("{} {} {}\n", p.x, p.y, p.z))
        .collect();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let result = child.wait_with_output().unwrap();
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    let warnings: Vec<&str> = json["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("landmarks umbo and incudomalleolar may be swapped")),
        "{warnings:?}"
    );
    assert!(out.exists());
}
