//! `otoatlas landmarks --auto`: the three landmarks proposed from the image alone. The cases
//! are given as bare NIfTI images, which carry no laterality, so the side comes from the
//! chain's handedness in the image. Truth: each phantom's `truth.json` (the exact landmarks
//! of its anatomy, before pick noise). Every proposed landmark must be within 0.5 mm of the
//! truth (0.25 mm where the truth is the atlas's own) and the side right; an image without a
//! chain must fail with exit code 2.

use std::path::Path;

use serde_json::Value;

use crate::common::python::run_python;
use crate::common::{otoatlas, otoatlas_json, root, shared_anatomy};
use crate::registration_accuracy::{check, copy_case, score};
use crate::registration_real_anatomy::{
    HD95_MAX_MM_CT, MASD_MAX_MM, chain_scores, ct_chain, phantom, sofa_chain, transformed_ct_chain,
};

/// The largest distance of a proposed landmark from the truth \[mm\] (the target).
const MAX_ERROR_MM: f64 = 0.5;

/// The same where the truth is the atlas's own landmarks (atlas-shape phantoms), so that no
/// definition differs \[mm\]: the atlas placed again after its first registration
/// (`[auto_landmarks] rescale_passes`) brought the worst landmark of the sample cases from
/// 0.31-0.46 to 0.06-0.12 mm and of the held-out atlas-shape phantoms (with and without
/// cone-beam artefacts) from 0.40 to 0.19 mm.
const ATLAS_SHAPE_MAX_ERROR_MM: f64 = 0.25;

fn point(v: &Value) -> [f64; 3] {
    [0, 1, 2].map(|k| v[k].as_f64().unwrap())
}

/// `otoatlas landmarks IMAGE --auto --out OUT` with `extra` arguments: the report and the
/// `.json` written beside `out`.
fn propose(image: &Path, out: &Path, extra: &[&str]) -> (Value, Value) {
    let mut args = vec![
        "landmarks",
        image.to_str().unwrap(),
        "--auto",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (code, report) = otoatlas_json(&args);
    assert_eq!(code, 0, "{}: {report}", image.display());
    let written: Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("json")).unwrap())
            .unwrap();
    (report, written)
}

/// Each landmark of `written` (a landmark file's JSON) and its distance from `truth`'s.
fn distances(written: &Value, truth: &Value) -> Vec<(&'static str, f64)> {
    ["umbo", "incudomalleolar", "incudostapedial"]
        .into_iter()
        .map(|key| {
            let (p, t) = (point(&written[key]), point(&truth["landmarks"][key]));
            (
                key,
                (0..3).map(|k| (p[k] - t[k]).powi(2)).sum::<f64>().sqrt(),
            )
        })
        .collect()
}

/// Proposes the landmarks of `image` and checks them against `truth.json`; returns the worst
/// distance.
fn check_proposal(image: &Path, truth: &Path, out: &Path, what: &str) -> f64 {
    let (report, written) = propose(image, out, &[]);
    let truth: Value = serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
    assert_eq!(report["side"], truth["side"], "{what}: side");
    // the written file's landmarks against the truth
    let mut worst = 0.0f64;
    for (key, d) in distances(&written, &truth) {
        let confidence = written["proposal"]["support"][key]["confidence"]
            .as_f64()
            .unwrap();
        eprintln!("{what}: {key} {d:.3} mm from the truth, confidence {confidence:.2}");
        assert!(
            d <= MAX_ERROR_MM,
            "{what}: {key} is {d:.3} mm from the truth"
        );
        worst = worst.max(d);
    }
    assert!(
        std::fs::read_to_string(out)
            .unwrap()
            .contains("proposed by otoatlas"),
        "{what}: the .fcsv says how the landmarks were found"
    );
    worst
}

/// `otoatlas run CASE --out OUT --auto-landmarks --config CONFIG`, then `extra`: the exit code
/// and the JSON report.
fn run_auto(case: &Path, out: &Path, config: &Path, extra: &[&str]) -> (i32, Value) {
    let mut args = vec![
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--auto-landmarks",
        "--config",
        config.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    otoatlas_json(&args)
}

#[test]
#[ignore = "heavy: three chain searches and registrations; scripts/test.sh runs it"]
fn the_sample_cases_landmarks_are_found_within_half_a_millimetre() {
    let tmp = tempfile::tempdir().unwrap();
    for case in ["case-001", "case-002", "case-003"] {
        let dir = root().join("sample_cases").join(case);
        let worst = check_proposal(
            &dir.join("image.nii.gz"),
            &dir.join("truth.json"),
            &tmp.path().join(format!("{case}.fcsv")),
            case,
        );
        assert!(
            worst <= ATLAS_SHAPE_MAX_ERROR_MM,
            "{case}: a landmark {worst:.3} mm from the atlas's own"
        );
    }
}

#[test]
#[ignore = "heavy: two real-chain phantoms, chain searches and registrations; scripts/test.sh runs it"]
fn a_real_chains_landmarks_are_found_on_both_sides() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let chain = ct_chain(&anatomy, tmp.path());
    for (seed, spacing, side) in [("101", "0.15", "left"), ("104", "0.3", "right")] {
        let case = phantom(&tmp.path().join(seed), seed, spacing, side, &chain);
        check_proposal(
            &case.join("image.nii.gz"),
            &case.join("truth.json"),
            &tmp.path().join(format!("ct-{seed}.fcsv")),
            &format!("CT chain, seed {seed}, {spacing} mm, {side}"),
        );
    }
}

/// A chain whose search's best pose is wrong. The CT chain stretched and sheared (seed 705 of
/// the randomly varied chains, docs/registration.md "Landmarks from the image": x 1.047,
/// y 1.125, z 0.909, shear 0.087, turned 1.3°), at 0.2 mm, a left ear: the search's best pose
/// (score 0.511) has the chain turned about its incudomalleolar joint, its umbo and ISJ 2.8
/// and 3.4 mm from the truth, and its registration leaves 0.05 of the stapes on a bone edge;
/// the next distinct pose (0.503) is the chain's. Without alternatives the proposal stays
/// wrong (checked here too, so that the case keeps testing the fallback); with them, the
/// registration from the next pose is kept.
#[test]
#[ignore = "heavy: a real-chain phantom, two chain searches and five registrations; scripts/test.sh runs it"]
fn a_pose_the_image_does_not_support_is_replaced_by_the_search_s_next() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    #[rustfmt::skip]
    let a = nalgebra::Matrix3::new(
        1.046689, -0.008736, 0.067459,
        0.007894, 1.124817, -0.01498,
        0.013793, 0.019161, 0.910091,
    );
    let chain = transformed_ct_chain(&anatomy, tmp.path(), "varied", a);
    let case = phantom(&tmp.path().join("case"), "705", "0.2", "left", &chain);
    let image = case.join("image.nii.gz");
    let truth = case.join("truth.json");
    // the search's best pose alone
    let config = tmp.path().join("no-alternatives.toml");
    let default = std::fs::read_to_string(root().join("pipeline.toml")).unwrap();
    let without = default.replacen("alternative_poses = 3", "alternative_poses = 0", 1);
    assert_ne!(
        without, default,
        "alternative_poses = 3 not in pipeline.toml"
    );
    std::fs::write(&config, without).unwrap();
    let truth_json: Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let (_, written) = propose(
        &image,
        &tmp.path().join("best-only.fcsv"),
        &["--config", config.to_str().unwrap()],
    );
    let worst = distances(&written, &truth_json)
        .into_iter()
        .fold(0.0f64, |w, (_, d)| w.max(d));
    eprintln!("the search's best pose alone: worst landmark {worst:.3} mm from the truth");
    assert!(
        worst > 1.0,
        "the best pose is no longer wrong here ({worst:.3} mm)"
    );
    // with the search's next poses
    let out = tmp.path().join("proposed.fcsv");
    check_proposal(&image, &truth, &out, "CT chain varied, seed 705");
    let written: Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("json")).unwrap())
            .unwrap();
    let tried = written["proposal"]["poses_tried"].as_array().unwrap();
    eprintln!("poses tried: {tried:?}");
    assert!(tried.len() >= 2, "{tried:?}");
    assert_eq!(tried[0]["kept"], false, "{tried:?}");
    let kept = tried.iter().find(|t| t["kept"] == true).unwrap();
    assert!(
        kept["stapes_support"].as_f64().unwrap() > tried[0]["stapes_support"].as_f64().unwrap()
    );
}

/// With cone-beam artefacts (cupping, rings, streaks): an atlas-shape phantom at the finest
/// spacing (0.125 mm, a left ear) and SOFA's chain at 0.2 mm (a right ear).
#[test]
#[ignore = "heavy: two phantoms with artefacts, chain searches and registrations; scripts/test.sh runs it"]
fn with_cone_beam_artefacts_the_landmarks_are_still_found() {
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let atlas_cases = tmp.path().join("atlas-shape");
    let mut runs = vec![(
        atlas_cases.clone(),
        vec!["--seed", "300", "--spacing", "0.125", "--side", "left"],
        None,
    )];
    if let Some(anatomy) = shared_anatomy() {
        let chain = sofa_chain(&anatomy, tmp.path());
        runs.push((
            tmp.path().join("sofa-cases"),
            vec!["--seed", "301", "--spacing", "0.2", "--side", "right"],
            Some(chain),
        ));
    }
    for (out, args, chain) in runs {
        let mut all = vec![
            "phantom".to_string(),
            "--out".into(),
            s(&out),
            "--artefacts".into(),
        ];
        all.extend(args.iter().map(|a| a.to_string()));
        if let Some(chain) = &chain {
            all.extend(["--anatomy".to_string(), s(chain)]);
        }
        all.push("--quiet".into());
        let made = otoatlas(&all.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(made.status.success(), "{made:?}");
        let case = out.join("case-001");
        let worst = check_proposal(
            &case.join("image.nii.gz"),
            &case.join("truth.json"),
            &tmp.path().join(format!(
                "{}.fcsv",
                out.file_name().unwrap().to_string_lossy()
            )),
            &format!(
                "{} with artefacts",
                out.file_name().unwrap().to_string_lossy()
            ),
        );
        if chain.is_none() {
            assert!(
                worst <= ATLAS_SHAPE_MAX_ERROR_MM,
                "atlas-shape phantom with artefacts: a landmark {worst:.3} mm from the atlas's own"
            );
        }
    }
}

/// `run --auto-landmarks` on a case without a landmark file (a bare NIfTI image, so the side
/// comes from the chain's handedness) meets the bounds the picked landmarks meet
/// (`registration_accuracy::check`), and its metrics say the landmarks were proposed.
#[test]
#[ignore = "heavy: a chain search and two registrations; scripts/test.sh runs it"]
fn run_with_proposed_landmarks_meets_the_picked_landmarks_bounds() {
    let tmp = tempfile::tempdir().unwrap();
    let case = copy_case(
        &root().join("sample_cases/case-003"),
        &tmp.path().join("case-003"),
        &["image.nii.gz", "truth.json"],
    );
    let from = root().join("sample_cases/case-003/segmentation");
    std::fs::create_dir_all(case.join("segmentation")).unwrap();
    for f in ["malleus.ply", "incus.ply", "stapes.ply", "eardrum.ply"] {
        std::fs::copy(from.join(f), case.join("segmentation").join(f)).unwrap();
    }
    let out = tmp.path().join("out");
    let scored = score(&case, &out, &["--auto-landmarks"]);
    check(&scored);
    assert_eq!(scored.side, "left");
    let metrics: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["side_source"], "chain's handedness in the image");
    let proposal = &metrics["landmarks"]["proposal"];
    assert!(
        proposal["search"]["best"]["score"].as_f64().unwrap() > 0.45,
        "{proposal}"
    );
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(report.contains("confidence (proposed)"));
    // resumed after the landmarks stage, the record is kept
    let (code, resumed) = crate::common::otoatlas_json(&[
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--from",
        "rigid",
        "--config",
        out.parent()
            .unwrap()
            .join("pipeline.toml")
            .to_str()
            .unwrap(),
    ]);
    assert_eq!(code, 0, "{resumed}");
    assert_eq!(resumed["side_source"], "chain's handedness in the image");
    assert_eq!(resumed["landmarks"]["proposal"], *proposal);
}

/// `run --auto-landmarks` on a CT-chain phantom ends within the bounds the real-chain test
/// holds with picked landmarks (chain MASD, HD95). The improvement over the rigid fit is not
/// asked: the rigid fit from the proposed landmarks starts much nearer (about 0.3 mm instead of
/// 0.3-0.46 mm on the CT chain; README).
#[test]
#[ignore = "heavy: a real-chain phantom, a chain search and two registrations; scripts/test.sh runs it"]
fn run_with_proposed_landmarks_on_a_real_chain_meets_its_bounds() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let chain = ct_chain(&anatomy, tmp.path());
    let case = phantom(&tmp.path().join("104"), "104", "0.3", "right", &chain);
    let out = tmp.path().join("out");
    let config = crate::common::config_without_validation(tmp.path());
    let (code, m) = run_auto(&case, &out, &config, &[]);
    assert_eq!(code, 0, "{m}");
    assert_eq!(m["side"], "right");
    let (masd, hd95) = chain_scores(&m, "registered");
    eprintln!(
        "CT chain seed 104 with proposed landmarks: chain MASD {masd:.3} mm, HD95 {hd95:.3} mm"
    );
    assert!(masd <= MASD_MAX_MM, "MASD {masd}");
    assert!(hd95 <= HD95_MAX_MM_CT, "HD95 {hd95}");
}

/// A sample case with its ossicles (and 0.4 mm around them) replaced by air, and a bone block
/// with an empty air cavity: no chain to find, exit 2 naming what was searched.
#[test]
fn an_image_without_ossicles_fails_saying_what_was_searched() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = root().join("sample_cases/case-001");
    let image = tmp.path().join("no-ossicles.nii.gz");
    let args = [
        dir.join("image.nii.gz"),
        dir.join("segmentation/labels.nii.gz"),
        image.clone(),
    ];
    let Some(removed) = run_python("remove_ossicles.py", &args, &["nibabel", "numpy"]) else {
        return;
    };
    assert!(removed.trim().parse::<usize>().unwrap() > 1000, "{removed}");
    let out = otoatlas(&[
        "landmarks",
        image.to_str().unwrap(),
        "--auto",
        "--out",
        tmp.path().join("p.fcsv").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no ossicular chain found") && stderr.contains("orientations"),
        "{stderr}"
    );
    assert!(!tmp.path().join("p.fcsv").exists());
}

/// On a pipe with `--suggest`, an empty answer accepts the proposed landmark and a typed one
/// replaces it.
#[test]
fn the_prompt_offers_the_proposal_and_enter_accepts_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = root().join("sample_cases/case-002");
    let truth: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    // Enter, Enter, then the true ISJ typed in mm
    let isj = point(&truth["landmarks"]["incudostapedial"]);
    let answers = format!("\n\n{} {} {}\n", isj[0], isj[1], isj[2]);
    let out = tmp.path().join("picks.fcsv");
    let done = crate::common::otoatlas_with_stdin(
        &[
            "landmarks".as_ref(),
            "--suggest".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
            dir.join("image.nii.gz").as_os_str(),
        ],
        answers.as_bytes(),
    );
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(done.status.success(), "{stderr}");
    assert!(stderr.contains("Enter accepts the proposal"), "{stderr}");
    let written: Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("json")).unwrap())
            .unwrap();
    for key in ["umbo", "incudomalleolar"] {
        let (p, t) = (point(&written[key]), point(&truth["landmarks"][key]));
        let d = (0..3).map(|k| (p[k] - t[k]).powi(2)).sum::<f64>().sqrt();
        assert!(
            d <= MAX_ERROR_MM,
            "{key}: the accepted proposal is {d:.3} mm from the truth"
        );
    }
    let typed = point(&written["incudostapedial"]);
    assert!(
        (0..3).all(|k| (typed[k] - isj[k]).abs() < 1e-3),
        "{typed:?}"
    );
    // the side of a NIfTI without laterality: the chain's handedness
    assert_eq!(written["side"], truth["side"]);
}

/// A pick 1.5 mm off the umbo (out of the landmark triangle's plane, so that every distance
/// stays in its band) is what the registration does not follow: `run` warns, naming the
/// landmark and the distance, and keeps the case.
#[test]
#[ignore = "heavy: a registration of case-002, 5 s in debug; scripts/test.sh runs it"]
fn a_pick_the_registration_does_not_follow_is_warned_about() {
    let tmp = tempfile::tempdir().unwrap();
    let case = copy_case(
        &root().join("sample_cases/case-002"),
        &tmp.path().join("case-002"),
        &["image.nii.gz", "landmarks.json"],
    );
    let mut picks: Value =
        serde_json::from_str(&std::fs::read_to_string(case.join("landmarks.json")).unwrap())
            .unwrap();
    let [u, m, s] = ["umbo", "incudomalleolar", "incudostapedial"].map(|k| point(&picks[k]));
    let (a, b) = (
        [0, 1, 2].map(|k| m[k] - u[k]),
        [0, 1, 2].map(|k| s[k] - u[k]),
    );
    let n = [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ];
    let len = n.iter().map(|v| v * v).sum::<f64>().sqrt();
    picks["umbo"] = serde_json::json!([0, 1, 2].map(|k| u[k] + 1.5 * n[k] / len));
    std::fs::write(case.join("landmarks.json"), picks.to_string()).unwrap();
    let out = tmp.path().join("out");
    let (code, _) = crate::common::otoatlas_json(&[
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--config",
        crate::common::config_without_validation(tmp.path())
            .to_str()
            .unwrap(),
    ]);
    assert_eq!(code, 0);
    let metrics: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    let warnings = metrics["landmark_warnings"].as_array().unwrap();
    let far: Vec<&Value> = warnings
        .iter()
        .filter(|w| w["kind"] == "far_from_registration")
        .collect();
    assert_eq!(far.len(), 1, "{warnings:?}");
    assert_eq!(far[0]["landmark"], "umbo");
    let d = far[0]["distance_mm"].as_f64().unwrap();
    assert!(d > 1.0 && d < 2.0, "{d}");
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(report.contains("from its pick"));
}

/// `--side` against the chain's handedness (case-002 is a right ear): the stated side is
/// kept, and the warning says the image's chain is the other ear's, with the margin.
#[test]
#[ignore = "heavy: a chain search and a registration of case-002; scripts/test.sh runs it"]
fn a_stated_side_the_chain_contradicts_is_warned_about() {
    let tmp = tempfile::tempdir().unwrap();
    let case = copy_case(
        &root().join("sample_cases/case-002"),
        &tmp.path().join("case-002"),
        &["image.nii.gz"],
    );
    let out = tmp.path().join("out");
    let config = crate::common::config_without_validation(tmp.path());
    let (code, v) = run_auto(&case, &out, &config, &["--side", "left"]);
    assert_eq!(code, 0, "{v}");
    assert_eq!(v["side"], "left");
    assert_eq!(v["side_source"], "--side");
    let warnings = v["landmark_warnings"].as_array().unwrap();
    let w = warnings
        .iter()
        .find(|w| w["kind"] == "handedness_disagrees")
        .unwrap_or_else(|| panic!("{warnings:?}"));
    assert!(w["margin"].as_f64().unwrap() > 0.05, "{w}");
    assert!(
        w["message"].as_str().unwrap().contains("the other ear's"),
        "{w}"
    );
}

/// Proposed landmarks that fail a check are named as proposed, not as the case folder's
/// landmark file (which `--auto-landmarks` does not read): here an umbo-IMJ band no ear has.
#[test]
#[ignore = "heavy: a chain search and registrations of case-003; scripts/test.sh runs it"]
fn proposed_landmarks_that_fail_a_check_are_named_as_proposed() {
    let tmp = tempfile::tempdir().unwrap();
    let case = copy_case(
        &root().join("sample_cases/case-003"),
        &tmp.path().join("case-003"),
        &["image.nii.gz", "landmarks.fcsv"],
    );
    let config = crate::common::config_without_validation(tmp.path());
    let text = std::fs::read_to_string(&config).unwrap();
    let narrowed = text
        .replacen(
            "umbo_imj_typical_mm = [4.55, 6.6]",
            "umbo_imj_typical_mm = [7.9, 8.0]",
            1,
        )
        .replacen(
            "umbo_imj_possible_mm = [4.0, 8.0]",
            "umbo_imj_possible_mm = [7.9, 8.0]",
            1,
        );
    assert_eq!(
        narrowed.matches("[7.9, 8.0]").count(),
        2,
        "the bands were found"
    );
    std::fs::write(&config, narrowed).unwrap();
    let out = tmp.path().join("out");
    let (code, v) = run_auto(&case, &out, &config, &[]);
    assert_eq!(code, 2, "{v}");
    let error = v["error"].as_str().unwrap();
    assert!(
        error.starts_with("the landmarks proposed from the image: ") && error.contains("umbo-IMJ"),
        "{error}"
    );
    assert!(!error.contains("landmarks.fcsv"), "{error}");
}
