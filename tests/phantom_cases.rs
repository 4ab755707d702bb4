//! The phantom generator end to end: generated case folders read back exactly by our ingest and
//! by pydicom/nibabel, byte-identical for a seed, different across seeds, mirrored for a left
//! ear, with landmarks on the true surfaces; bad arguments exit with code 2.

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

use crate::common;
use nalgebra::{Matrix3, Point3, Vector3};
use otoatlas::config::Config;
use otoatlas::ear::read_landmarks;
use otoatlas::image;
use otoatlas::mesh::TriMesh;
use otoatlas::mesh::io::ply::read_ply;
use otoatlas::mesh::spatial::SignedSurface;
use otoatlas::mesh::topology::surface_topology;
use otoatlas::phantom::{PhantomCase, PhantomOptions, generate_case, write_case};
use otoatlas::register::Side;

/// Coarse voxels keep debug-mode tests quick.
const SPACING: f64 = 0.3;

fn options(side: Side) -> PhantomOptions {
    PhantomOptions {
        spacing_mm: Some(SPACING),
        side: Some(side),
        ..PhantomOptions::default()
    }
}

/// Every file under `dir`, by relative path, with its bytes.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.insert(rel, fs::read(&p).unwrap());
            }
        }
    }
    out
}

#[test]
fn a_case_reads_back_exactly_is_byte_identical_per_seed_and_agrees_with_pydicom() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cli");
    let (code, report) = common::otoatlas_json(&[
        "phantom",
        "--out",
        out.to_str().unwrap(),
        "--seed",
        "11",
        "--side",
        "left",
        "--spacing",
        "0.3",
    ]);
    assert_eq!(code, 0, "{report}");
    let case_dir = out.join("case-001");
    assert_eq!(report["cases"][0]["side"], "left");

    // the library with the same seed writes the same bytes
    let case = generate_case(11, &options(Side::Left)).unwrap();
    let again = write_case(&dir.path().join("lib").join("case-001"), &case).unwrap();
    let (a, b) = (tree(&case_dir), tree(&again));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(
            bytes == &b[name],
            "{name} differs between two runs of seed 11"
        );
    }
    for part in [
        "image.nii.gz",
        "landmarks.fcsv",
        "landmarks.mrk.json",
        "landmarks.json",
        "truth.json",
        "segmentation/labels.nii.gz",
        "segmentation/malleus.ply",
        "segmentation/incus.ply",
        "segmentation/stapes.ply",
        "segmentation/eardrum.ply",
    ] {
        assert!(a.contains_key(part), "{part} missing");
    }

    // our ingest: both images carry exactly the generated geometry and voxels
    let truth: serde_json::Value =
        serde_json::from_slice(&fs::read(case_dir.join("truth.json")).unwrap()).unwrap();
    let cfg = Config::default_config().unwrap().ingest;
    let expected = &case.image;
    let dicom = image::load(&case_dir.join("dicom"), None, &cfg).unwrap();
    let nifti = image::load(&case_dir.join("image.nii.gz"), None, &cfg).unwrap();
    for loaded in [&dicom, &nifti] {
        let v = &loaded.volume;
        assert_eq!(v.dims, expected.dims);
        assert_eq!(
            serde_json::json!(v.dims),
            truth["image"]["dims"],
            "{}",
            loaded.info.format
        );
        for c in 0..3 {
            assert!((v.spacing[c] - SPACING).abs() < 1e-6);
            assert!((v.origin[c] - expected.origin[c]).abs() < 1e-4);
        }
        assert!((v.direction - Matrix3::identity()).norm() < 1e-9);
        let worst = v
            .data
            .iter()
            .zip(&expected.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst <= 0.5 + 1e-3, "HU off by {worst} beyond quantisation");
    }
    assert_eq!(dicom.volume.data, nifti.volume.data);
    assert_eq!(dicom.info.laterality.as_deref(), Some("L"));
    assert!(dicom.info.files > 1 && dicom.info.files == expected.dims[2]);
    // the label map lies on the same grid
    let labels = image::load(&case_dir.join("segmentation/labels.nii.gz"), None, &cfg).unwrap();
    assert_eq!(labels.volume.dims, expected.dims);
    assert!((labels.volume.origin - expected.origin).norm() < 1e-4);
    for l in 1..=4 {
        assert!(labels.volume.data.contains(&(l as f32)), "label {l} absent");
    }

    // the landmark files hold the picked landmarks, within 0.3 mm of the exact ones
    for name in ["landmarks.fcsv", "landmarks.mrk.json", "landmarks.json"] {
        let file = read_landmarks(&case_dir.join(name)).unwrap();
        for (got, want) in file.landmarks.points().iter().zip(case.picked.points()) {
            assert!((got - want).norm() < 1e-3, "{name}");
        }
    }
    let exact = &case.truth.landmarks;
    for (picked, exact) in
        case.picked
            .points()
            .iter()
            .zip([exact.umbo, exact.incudomalleolar, exact.incudostapedial])
    {
        assert!((picked - Point3::from(exact)).norm() <= 0.3 + 1e-9);
    }

    common::python::run_python(
        "check_phantom.py",
        &[case_dir.to_str().unwrap()],
        &["pydicom", "nibabel", "numpy"],
    );
}

/// Signed distance from `p` to a closed truth surface.
fn distance(mesh: &TriMesh, p: [f64; 3]) -> f64 {
    SignedSurface::new(mesh, "truth")
        .unwrap()
        .signed_distance(&Point3::from(p))
}

fn surface<'a>(case: &'a PhantomCase, name: &str) -> &'a TriMesh {
    &case.surfaces.iter().find(|(n, _)| *n == name).unwrap().1
}

/// Signed volume of the landmark triangle and the incus centroid: its sign is the chain's
/// handedness, which no rotation changes and a mirror flips.
fn handedness(case: &PhantomCase) -> f64 {
    let l = &case.truth.landmarks;
    let incus = surface(case, "incus");
    let centroid = incus
        .vertices
        .iter()
        .map(|p| p.coords)
        .sum::<Vector3<f64>>()
        / incus.vertices.len() as f64;
    let (u, m, s) = (
        Vector3::from(l.umbo),
        Vector3::from(l.incudomalleolar),
        Vector3::from(l.incudostapedial),
    );
    (m - u).cross(&(s - u)).dot(&(centroid - u))
}

#[test]
fn truth_is_consistent_mirrored_for_left_ears_and_different_across_seeds() {
    let right = generate_case(21, &options(Side::Right)).unwrap();
    let left = generate_case(21, &options(Side::Left)).unwrap();
    let other = generate_case(22, &options(Side::Left)).unwrap();
    for case in [&right, &left, &other] {
        let t = &case.truth;
        // the deformation: at most 0.8 mm, orientation-preserving everywhere sampled
        assert!(t.deformation.displacement_bound_mm <= 0.8);
        assert!(t.deformation.max_displacement_mm <= t.deformation.displacement_bound_mm);
        assert!(t.deformation.gradient_bound < 1.0);
        assert!(t.deformation.min_jacobian_determinant > 0.0);
        assert!((0.9..=1.1).contains(&t.pose.scale));
        // truth surfaces: closed, outward, the landmarks on them
        for name in ["malleus", "incus", "stapes"] {
            let m = surface(case, name);
            assert!(surface_topology(m).is_closed_oriented_manifold(), "{name}");
            assert!(m.signed_volume() > 0.0, "{name} inward");
        }
        let l = &t.landmarks;
        let imj_m = distance(surface(case, "malleus"), l.incudomalleolar);
        let imj_i = distance(surface(case, "incus"), l.incudomalleolar);
        let isj_i = distance(surface(case, "incus"), l.incudostapedial);
        let isj_s = distance(surface(case, "stapes"), l.incudostapedial);
        let umbo = distance(surface(case, "malleus"), l.umbo);
        assert!(imj_m.abs() <= 0.3 && imj_i.abs() <= 0.3, "{imj_m} {imj_i}");
        // the ISJ is the centre of a 0.95 mm thick joint disc (atlas), between both bones
        assert!(
            isj_i.abs() <= 0.65 && isj_s.abs() <= 0.65,
            "{isj_i} {isj_s}"
        );
        assert!(
            (-0.3..0.0).contains(&umbo),
            "umbo {umbo} not just inside the malleus"
        );
        // the eardrum's apex is the umbo
        assert!((surface(case, "eardrum").vertices[0] - Point3::from(l.umbo)).norm() < 1e-9);
    }
    assert_eq!(right.truth.side, Side::Right);
    assert_eq!(left.truth.side, Side::Left);
    assert!(
        handedness(&right) * handedness(&left) < 0.0,
        "a left ear must be the mirror image: {} vs {}",
        handedness(&right),
        handedness(&left)
    );
    assert!(handedness(&left) * handedness(&other) > 0.0);
    // another seed: another patient (shape, pose and image)
    let lm = |c: &PhantomCase| {
        let l = &c.truth.landmarks;
        let (u, m) = (Vector3::from(l.umbo), Vector3::from(l.incudomalleolar));
        (u - m).norm()
    };
    assert!((lm(&left) - lm(&other)).abs() > 1e-3);
    let volume = |c: &PhantomCase| surface(c, "malleus").signed_volume();
    assert!((volume(&left) - volume(&other)).abs() > 1e-3);
    assert_ne!(left.truth.pose.rotation, other.truth.pose.rotation);
    // the generated PLY reads back as written
    let dir = tempfile::tempdir().unwrap();
    let path = write_case(&dir.path().join("case"), &other).unwrap();
    let (stapes, _) = read_ply(&path.join("segmentation/stapes.ply")).unwrap();
    assert_eq!(stapes.triangles, surface(&other, "stapes").triangles);
}

#[test]
fn bad_arguments_exit_with_code_2_and_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap().to_string();
    let blocker = dir.path().join("a-file");
    fs::write(&blocker, b"x").unwrap();
    let cases: [(&[&str], &str); 5] = [
        (&["--spacing", "0.5"], "outside 0.125..=0.3 mm"),
        (&["--spacing", "0.05"], "outside 0.125..=0.3 mm"),
        (&["--cases", "0"], "at least one case"),
        (&["--noise=-3"], "--noise -3"),
        (&["--side", "both"], "invalid value"),
    ];
    for (extra, message) in cases {
        let mut args = vec!["phantom", "--out", out.as_str()];
        args.extend_from_slice(extra);
        let o = common::otoatlas(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(message), "{extra:?}: {stderr}");
        assert!(!stderr.contains("panicked"));
    }
    // an --out that cannot be a folder
    let o = common::otoatlas(&["phantom", "--out", blocker.join("sub").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("cannot write there"), "{stderr}");
    // nothing was written for the refused runs
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// `phantom --out COHORT` where COHORT/case-002 is a patient's case (no truth.json) replaced
/// it with a phantom. Refused before any case is made, the patient's files kept.
#[test]
fn a_case_that_is_not_a_phantom_is_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let patient = dir.path().join("case-002");
    fs::create_dir_all(patient.join("dicom")).unwrap();
    fs::write(patient.join("dicom/slice-1.dcm"), b"a patient's slice").unwrap();
    fs::write(patient.join("landmarks.fcsv"), b"a patient's picks").unwrap();
    let o = common::otoatlas(&[
        "phantom",
        "--out",
        dir.path().to_str().unwrap(),
        "--cases",
        "2",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("case-002 exists and is not a phantom (no truth.json)"),
        "{stderr}"
    );
    assert_eq!(
        fs::read(patient.join("dicom/slice-1.dcm")).unwrap(),
        b"a patient's slice"
    );
    assert_eq!(
        fs::read(patient.join("landmarks.fcsv")).unwrap(),
        b"a patient's picks"
    );
    // case-001 was not made either: the check comes before any work
    assert!(!dir.path().join("case-001").exists());
}

#[test]
fn committed_sample_cases_are_what_the_generator_makes_and_read_back() {
    let root = common::root().join("sample_cases");
    let cfg = Config::default_config().unwrap().ingest;
    let mut sides = Vec::new();
    for k in 1..=3 {
        let dir = root.join(format!("case-{k:03}"));
        let case = otoatlas::pipeline::Case::open(&dir).unwrap();
        assert_eq!(case.image, dir.join("dicom"));
        assert_eq!(case.landmarks, Some(dir.join("landmarks.fcsv")));
        assert_eq!(case.segmentation, Some(dir.join("segmentation")));
        let truth: serde_json::Value =
            serde_json::from_slice(&fs::read(dir.join("truth.json")).unwrap()).unwrap();
        let loaded = image::load(&case.image, None, &cfg).unwrap();
        assert_eq!(
            serde_json::json!(loaded.volume.dims),
            truth["image"]["dims"]
        );
        let side = truth["side"].as_str().unwrap().to_string();
        let code = if side == "left" { "L" } else { "R" };
        assert_eq!(loaded.info.laterality.as_deref(), Some(code));
        sides.push(side);
    }
    assert!(sides.iter().any(|s| s == "left") && sides.iter().any(|s| s == "right"));
    // the cheapest one (0.298 mm) is regenerated: the committed files are up to date (after
    // a change to the generator, run scripts/make-sample-cases.sh). Compared by value, not
    // by bytes, so that another libm's last-bit differences cannot fail it.
    let seed = 2026 + 1;
    let case = generate_case(seed, &PhantomOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let fresh = write_case(&dir.path().join("case-002"), &case).unwrap();
    let committed = root.join("case-002");
    let stale = "sample_cases/ is stale: run scripts/make-sample-cases.sh";
    let (a, b) = (tree(&committed), tree(&fresh));
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "{stale}"
    );
    let json =
        |p: &Path| -> serde_json::Value { serde_json::from_slice(&fs::read(p).unwrap()).unwrap() };
    assert_json_close(
        &json(&committed.join("truth.json")),
        &json(&fresh.join("truth.json")),
        stale,
    );
    for part in ["dicom", "image.nii.gz", "segmentation/labels.nii.gz"] {
        let x = image::load(&committed.join(part), None, &cfg)
            .unwrap()
            .volume;
        let y = image::load(&fresh.join(part), None, &cfg).unwrap().volume;
        assert_eq!(x.dims, y.dims, "{part}: {stale}");
        let off = x
            .data
            .iter()
            .zip(&y.data)
            .filter(|(p, q)| (*p - *q).abs() > 1.0)
            .count();
        assert!(
            off * 1000 <= x.data.len(),
            "{part}: {off} voxels differ; {stale}"
        );
    }
    for name in ["malleus", "incus", "stapes", "eardrum"] {
        let rel = format!("segmentation/{name}.ply");
        let (x, _) = read_ply(&committed.join(&rel)).unwrap();
        let (y, _) = read_ply(&fresh.join(&rel)).unwrap();
        assert_eq!(x.triangles, y.triangles, "{rel}: {stale}");
        assert!(
            x.vertices
                .iter()
                .zip(&y.vertices)
                .all(|(p, q)| (p - q).norm() < 1e-6),
            "{rel}: {stale}"
        );
    }
}

/// Two JSON documents equal up to a relative 1e-9 on numbers.
fn assert_json_close(a: &serde_json::Value, b: &serde_json::Value, what: &str) {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                "{x} vs {y}: {what}"
            );
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{what}");
            x.iter()
                .zip(y)
                .for_each(|(p, q)| assert_json_close(p, q, what));
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{what}"
            );
            x.iter()
                .for_each(|(k, v)| assert_json_close(v, &y[k], what));
        }
        _ => assert_eq!(a, b, "{what}"),
    }
}

/// dciodvfy (dicom3tools, the reference checker of the standard's IODs) finds no error in a
/// phantom slice of either side: the Type 2 attributes are present, Laterality is not written
/// beside Image Laterality.
#[test]
fn dciodvfy_finds_no_error_in_phantom_slices() {
    for side in [Side::Left, Side::Right] {
        let dir = tempfile::tempdir().unwrap();
        let case = generate_case(7, &options(side)).unwrap();
        write_case(&dir.path().join("case"), &case).unwrap();
        let mut slices: Vec<_> = fs::read_dir(dir.path().join("case/dicom"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        slices.sort();
        let Some(dciodvfy) = common::program("dciodvfy", "dicom3tools") else {
            return;
        };
        let out = std::process::Command::new(dciodvfy)
            .arg(&slices[slices.len() / 2])
            .output()
            .expect("run dciodvfy");
        // dciodvfy writes its findings to stderr
        let report = String::from_utf8_lossy(&out.stderr).into_owned()
            + &String::from_utf8_lossy(&out.stdout);
        let errors: Vec<&str> = report.lines().filter(|l| l.starts_with("Error")).collect();
        assert!(errors.is_empty(), "{side:?}: {errors:#?}");
        assert!(
            report.contains("CTImage"),
            "dciodvfy did not check a CT image: {report}"
        );
    }
}
