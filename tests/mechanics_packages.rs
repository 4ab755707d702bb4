//! The packages `run` makes from the sample cases keep the atlas's mechanics where the
//! registration alone decides them: the stiffness-controlled transfer function (250 and
//! 500 Hz within ±3 dB of the atlas's) and the frequency of its maximum (ratio in
//! [0.8, 1.25], the package gate of docs/mechanics.md, once the patient's size is taken
//! out: a similar ear s times larger has s times the stiffness and s³ the mass, so its
//! frequencies scale by 1/s, and the phantoms are up to ±14 % in size). A registration that
//! leaves the eardrum rough makes it slack (facets that move with little stretching): on the
//! earlier, bending-free atlas, before its offsets were smoothed, case-003's package answered
//! 250 Hz 11 dB above the atlas.
//! (Higher frequencies also follow the patient's size, which the ±10 % phantoms vary.)
//! `run` stores the package's validation in its manifest and report, unless switched off; its
//! transfer function, with rigid ossicles and from the reduced sweep, is that of the direct
//! solves (one complex LU per frequency) to 1e-5, and every gate of its verdict (transfer
//! function and static curve, rigid ossicles) passes or fails as the full model's (elastic
//! ossicles, direct solves, package and atlas alike).

use crate::common;
use otoatlas::atlas::{default_atlas, read_atlas};
use otoatlas::mechanics::udsp::GATE_PRESSURES_PA;
use otoatlas::mechanics::verdict::MAXIMUM_BAND_DB;
use otoatlas::mechanics::{
    MechanicalSystem, Ossicles, StaticCurve, TfaOptions, TransferFunction, UdspOptions, Verdict,
    relative_verdict, static_pressure_curve, transfer_function,
};

/// The transfer function of `atlas` at the 1/3 octaves 250-8000 Hz, one complex LU per
/// frequency (the direct solves, not the reduced sweep `run` uses), with the ossicles
/// `ossicles`.
fn direct_tf(atlas: &otoatlas::atlas::Atlas, ossicles: Ossicles) -> TransferFunction {
    let system = MechanicalSystem::new(atlas, atlas.nodes()).unwrap();
    let options = TfaOptions {
        reduced: None,
        ossicles,
        ..TfaOptions::default()
    };
    transfer_function(&system, &options, &otoatlas::progress::Silent).unwrap()
}

/// The full model's static curve of `atlas` at the gate pressures (elastic ossicles; the
/// gate's tolerance).
fn full_udsp(atlas: &otoatlas::atlas::Atlas) -> StaticCurve {
    let system = MechanicalSystem::new(atlas, atlas.nodes()).unwrap();
    let options = UdspOptions {
        pressures_pa: GATE_PRESSURES_PA.to_vec(),
        tolerance_mm: 1e-4,
        ..UdspOptions::default()
    };
    assert_eq!(options.ossicles, Ossicles::Elastic);
    static_pressure_curve(&system, &options, &otoatlas::progress::Silent).unwrap()
}

/// `run`'s verdict (rigid ossicles, the reduced sweep) against the verdict of the full model
/// (elastic ossicles, direct solves) of the package against the full model of the atlas:
/// the values within 0.25 dB, 2.5 degrees and 0.03 in the ratios (measured: BENCHMARKS.md,
/// "The package check with rigid ossicles"), and every gate passes or fails alike, but where
/// the full model's value lies within that tolerance of the band's edge, where the two models
/// may fall on either side (sample case-002 at 500 Hz: −2.99 dB full, −3.07 dB rigid, with the
/// cochlear load at Aibara et al.'s mean). Returns the largest differences (dB, degrees,
/// ratio).
fn same_verdict_as_full(case: &str, mechanics: &serde_json::Value, full: &Verdict) -> [f64; 3] {
    let gates = mechanics["verdict"]["gates"].as_array().unwrap();
    assert_eq!(gates.len(), full.gates.len(), "{case}");
    let mut worst = [0.0f64; 3];
    for gate in &full.gates {
        let run = gates
            .iter()
            .find(|g| g["name"] == gate.name.as_str())
            .unwrap_or_else(|| panic!("{case}: no gate {} in run's verdict", gate.name));
        let value = run["value"].as_f64().unwrap();
        let (kind, tolerance) = match gate.unit {
            "dB" => (0, 0.25),
            "deg" => (1, 2.5),
            _ => (2, 0.03),
        };
        let difference = (value - gate.value).abs();
        worst[kind] = worst[kind].max(difference);
        assert!(
            difference < tolerance,
            "{case} {}: full model {} vs {run}",
            gate.name,
            gate.value
        );
        let at_an_edge =
            (gate.value - gate.low).abs() < tolerance || (gate.value - gate.high).abs() < tolerance;
        if run["passed"].as_bool().unwrap() != gate.passed {
            assert!(
                at_an_edge,
                "{case} {}: full model {} vs {run}",
                gate.name, gate.value
            );
            println!(
                "{case} {}: full model {:.3}, rigid {value:.3}, on either side of the band's edge",
                gate.name, gate.value
            );
        }
    }
    worst
}

/// The three sample packages keep the atlas's transfer function within the consistency gate's
/// 3 dB at 250 and 500 Hz and the centre of its maximum's band (within 1 dB of it; scaled by the
/// ear's size) within 0.8-1.25 of the atlas's.
/// Case-002, the smallest ear (landmark scale 0.920), whose smaller size moves the
/// suspension's resonance near 315 Hz up, lies on that resonance's flank: −2.99 dB at 500 Hz
/// with the cochlear load at Aibara et al.'s mean (−2.8 dB at 1e10, −3.1 dB while the bones
/// weighed what the lattice held of them, −2.2 dB while the malleus weighed 38.3 mg) and
/// −8.75 dB at 397 Hz in the package check (rigid bones), not checked here. docs/mechanics.md, "Packages
/// today", "The malleus's mass" and "Masses that do not depend on the mesh".
#[test]
#[ignore = "heavy: runs the three sample cases and their transfer functions, 40 s in debug; scripts/test.sh runs it"]
fn sample_case_packages_keep_the_atlas_low_frequency_mechanics() {
    let atlas = default_atlas().unwrap();
    let reference = direct_tf(&atlas, Ossicles::Elastic);
    let reference_udsp = full_udsp(&atlas);
    let reference_centre = reference.maximum_band_centre(MAXIMUM_BAND_DB).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut faults = Vec::new();
    for case in ["case-001", "case-002", "case-003"] {
        let out = dir.path().join(case);
        let case_dir = common::root().join("sample_cases").join(case);
        let o = common::otoatlas(&[
            "--quiet",
            "run",
            &case_dir.to_string_lossy(),
            "--out",
            &out.to_string_lossy(),
        ]);
        assert!(o.status.success(), "{case}: {o:?}");
        let package = read_atlas(&out.join("package")).unwrap();
        let rigid = direct_tf(&package, Ossicles::Rigid);
        let tf = direct_tf(&package, Ossicles::Elastic);
        // run validated the package: the manifest holds its transfer function with rigid
        // ossicles (from the reduced sweep: within 1e-5 of the direct solves), the report its
        // verdict and charts
        let manifest: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("package/manifest.json")).unwrap())
                .unwrap();
        let stored = manifest["mechanics"]["transfer_function"]
            .as_array()
            .unwrap();
        assert_eq!(stored.len(), 16, "{case}: 1/3 octaves 250-8000 Hz");
        for p in &rigid.points {
            let row = stored
                .iter()
                .find(|r| (r[0].as_f64().unwrap() - p.frequency_hz).abs() < 1e-6)
                .unwrap();
            let m = row[1].as_f64().unwrap();
            assert!(
                (m / p.magnitude_um_s_per_pa - 1.0).abs() < 1e-5,
                "{case}: {row} vs {}",
                p.magnitude_um_s_per_pa
            );
        }
        let mechanics: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("mechanics.json")).unwrap()).unwrap();
        let full = relative_verdict(&tf, &full_udsp(&package), &reference, &reference_udsp);
        let [db, degrees, ratio] = same_verdict_as_full(case, &mechanics, &full);
        println!(
            "{case}: the full model's gates within {db:.3} dB, {degrees:.2} degrees, {ratio:.4} in the ratios"
        );
        if case == "case-001" {
            package_commands(&out.join("package"), &manifest);
        }
        let html = std::fs::read_to_string(out.join("report.html")).unwrap();
        assert!(html.contains("Mechanics: consistency with the atlas"));
        // the page and the manifest say which model of the ossicles the check used
        assert!(html.contains("each ossicle as one rigid body"));
        assert_eq!(manifest["mechanics"]["ossicles"], "rigid");
        assert!(html.contains("Goode et al. 1994 band"));
        assert!(out.join("mechanics.json").is_file());
        for f in [250.0, 500.0] {
            let (a, b) = (reference.at(f).unwrap(), tf.at(f).unwrap());
            let db = b.db() - a.db();
            println!("{case} {f} Hz: {:+.2} dB", db);
            if db.abs() > 3.0 {
                faults.push(format!("{case}: {db:+.1} dB at {f} Hz"));
            }
        }
        let manifest: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("package/manifest.json")).unwrap())
                .unwrap();
        let scale = manifest["registration"]["scale"].as_f64().unwrap();
        let ratio = tf.maximum_band_centre(MAXIMUM_BAND_DB).unwrap() / reference_centre * scale;
        println!("{case} maximum's band centre ratio x scale {scale:.3}: {ratio:.3}");
        if !(0.8..=1.25).contains(&ratio) {
            faults.push(format!(
                "{case}: maximum's band centre ratio x scale {ratio:.2}"
            ));
        }
    }
    assert!(faults.is_empty(), "{faults:?}");
}

/// `validate PACKAGE` and `simulate PACKAGE` on a run's package: the validation finds the
/// source atlas from the manifest's SHA-256 and computes the transfer function `run` stored;
/// a package that is not whole, or a reference that is not its atlas, is refused.
fn package_commands(package: &std::path::Path, manifest: &serde_json::Value) {
    let p = package.to_string_lossy();
    let (code, json) = common::otoatlas_json(&["--quiet", "validate", &p]);
    assert_eq!(code, 0, "{json}");
    assert_eq!(
        json["verdict"]["kind"], "consistency with the atlas",
        "{json}"
    );
    assert!(json["reference"]["transfer_function"].is_object(), "{json}");
    // a package is checked as `run` checked it: with rigid ossicles, the atlas likewise
    for of in [&json["mechanics"], &json["reference"]] {
        assert_eq!(of["transfer_function"]["ossicles"], "rigid", "{json}");
    }
    let stored = manifest["mechanics"]["transfer_function"]
        .as_array()
        .unwrap();
    let computed = json["mechanics"]["transfer_function"]["points"]
        .as_array()
        .unwrap();
    assert_eq!(computed.len(), stored.len());
    for (c, s) in computed.iter().zip(stored) {
        let (m, reference) = (
            c["magnitude_um_s_per_pa"].as_f64().unwrap(),
            s[1].as_f64().unwrap(),
        );
        // two reduced sweeps, of the package in memory and as read back: each within 1e-6 of
        // the direct solves
        assert!((m / reference - 1.0).abs() < 1e-5, "{c} vs {s}");
    }

    let (code, json) = common::otoatlas_json(&["--quiet", "simulate", &p, "--steps", "3"]);
    assert_eq!(code, 0, "{json}");
    let umbo = json["final_umbo_medial_mm"].as_f64().unwrap();
    assert!(umbo > 0.0 && umbo < 0.2, "{json}");

    // the package's own atlas.json is an atlas, but not the one it was registered from
    let o = common::otoatlas(&["--quiet", "validate", &p, "--reference", &p]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("registered from atlas 'default'"),
        "{stderr}"
    );

    let tampered = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(package).unwrap().flatten() {
        if entry.path().is_file() {
            std::fs::copy(entry.path(), tampered.path().join(entry.file_name())).unwrap();
        }
    }
    let o = common::otoatlas(&["--quiet", "simulate", &tampered.path().to_string_lossy()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("not a whole patient package"), "{stderr}");
}

#[test]
fn validation_can_be_switched_off() {
    let dir = tempfile::tempdir().unwrap();
    let config = common::config_without_validation(dir.path());
    let out = dir.path().join("out");
    // a previous run's verdict must not survive a run without validation (a previous run's
    // folder: its first stage's artefact beside the verdict)
    std::fs::create_dir_all(out.join("stages")).unwrap();
    std::fs::write(out.join("stages/ingest.json"), "{}").unwrap();
    std::fs::write(out.join("mechanics.json"), "{}").unwrap();
    let case = common::root().join("sample_cases/case-001");
    let o = common::otoatlas(&[
        "--quiet",
        "--config",
        &config.to_string_lossy(),
        "run",
        &case.to_string_lossy(),
        "--out",
        &out.to_string_lossy(),
    ]);
    assert!(o.status.success(), "{o:?}");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("package/manifest.json")).unwrap()).unwrap();
    assert!(manifest.get("mechanics").is_none());
    assert!(!out.join("mechanics.json").exists());
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("Not validated"));
    let timings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("timings.json")).unwrap()).unwrap();
    assert!(timings.get("validate").is_none() && timings.get("report").is_some());
}

#[test]
fn the_shipped_reference_is_the_default_atlas_mechanics() {
    use otoatlas::pipeline::mechanics::{compute_embedded_reference, embedded_reference};
    let shipped = embedded_reference().expect("assets/reference_mechanics.json parses");
    let fresh = compute_embedded_reference().unwrap();
    let stale = "stale: rerun `cargo run --release --example write_reference_mechanics`";
    assert_eq!(shipped.atlas_sha256, fresh.atlas_sha256, "{stale}");
    let (a, b) = (&shipped.transfer_function, &fresh.transfer_function);
    assert_eq!(a.points.len(), b.points.len(), "{stale}");
    assert_eq!((a.drive, a.drive_pa), (b.drive, b.drive_pa), "{stale}");
    for (p, q) in a.points.iter().zip(&b.points) {
        assert_eq!(p.frequency_hz, q.frequency_hz, "{stale}");
        // the solves may differ in the last bits between CPUs (SIMD paths)
        let rel = (p.magnitude_um_s_per_pa / q.magnitude_um_s_per_pa - 1.0).abs();
        assert!(rel < 1e-6, "{stale}: {} Hz off by {rel:e}", p.frequency_hz);
        assert!((p.phase_deg - q.phase_deg).abs() < 1e-4, "{stale}");
    }
    let (a, b) = (&shipped.static_pressure, &fresh.static_pressure);
    assert_eq!(a.points.len(), b.points.len(), "{stale}");
    assert!(a.failure.is_none() && b.failure.is_none());
    for (p, q) in a.points.iter().zip(&b.points) {
        assert_eq!(p.pressure_pa, q.pressure_pa, "{stale}");
        // the gate curve's Newton iterations stop at updates under 1e-4 mm; CPUs rounding
        // differently may stop one iteration apart (a stale atlas is off by far more)
        assert!(
            (p.umbo_mm - q.umbo_mm).abs() < 5e-4,
            "{stale}: {} Pa",
            p.pressure_pa
        );
    }
}

/// `run --condition stapes-fixation` writes the package of an otosclerotic ear: the same
/// registration, the atlas's materials under the condition (the annular ligament 1000 times
/// stiffer in `atlas.json` and the scene), recorded in the manifest and the metrics; its
/// mechanics are checked against the fixed atlas, whose stapes velocity at 250 Hz is more
/// than 40 dB below the normal atlas's (measured: about 40-50 dB, Nakajima et al. 2005), and
/// `verify` finds the source atlas under the condition to compare the elements with.
#[test]
#[ignore = "heavy: a run of sample case-001 with the fixed atlas's mechanics computed, 15 s in debug; scripts/test.sh runs it"]
fn a_package_of_a_fixed_stapes_holds_the_fixed_atlas() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("fixed");
    let case = common::root().join("sample_cases/case-001");
    let (code, metrics) = common::otoatlas_json(&[
        "run",
        case.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--condition",
        "stapes-fixation",
    ]);
    assert_eq!(code, 0, "{metrics}");
    assert_eq!(metrics["condition"], "stapes-fixation");
    let read = |path: std::path::PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    };
    let manifest = read(out.join("package/manifest.json"));
    assert_eq!(manifest["condition"], "stapes-fixation");
    let annular = |atlas: &serde_json::Value| {
        atlas["supports"]["annular_ligament_stiffness_n_per_m"]
            .as_f64()
            .unwrap()
    };
    let normal = default_atlas()
        .unwrap()
        .supports
        .annular_ligament_stiffness_n_per_m;
    let fixed = annular(&read(out.join("package/atlas.json")));
    assert!(
        (fixed / normal - otoatlas::mechanics::FIXATION_FACTOR).abs() < 1e-9,
        "{fixed} against {normal}"
    );

    let at_250 = |points: &serde_json::Value| {
        points
            .as_array()
            .unwrap()
            .iter()
            .find(|p| (p["frequency_hz"].as_f64().unwrap() - 250.0).abs() < 1.0)
            .unwrap()["magnitude_um_s_per_pa"]
            .as_f64()
            .unwrap()
    };
    let shipped: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(common::root().join("assets/reference_mechanics.json")).unwrap(),
    )
    .unwrap();
    let normal_250 = at_250(&shipped["transfer_function"]["points"]);
    let mechanics = read(out.join("mechanics.json"));
    assert_eq!(mechanics["condition"], "stapes-fixation");
    for (what, value) in [
        (
            "the fixed atlas",
            at_250(&mechanics["reference"]["transfer_function"]["points"]),
        ),
        (
            "the package",
            at_250(&mechanics["mechanics"]["transfer_function"]["points"]),
        ),
    ] {
        let db = 20.0 * (value / normal_250).log10();
        assert!(
            db < -40.0,
            "{what}: {db:.1} dB against the normal atlas at 250 Hz"
        );
    }

    let (code, verdict) = common::otoatlas_json(&["verify", out.join("package").to_str().unwrap()]);
    assert_eq!(code, 0, "{verdict}");
    assert!(
        verdict["elements"]["min_volume_ratio"].as_f64().is_some(),
        "the source atlas under the condition was found: {verdict}"
    );
}
