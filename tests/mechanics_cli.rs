//! `otoatlas simulate` end to end: the trajectory file, the JSON report, a pathology, bad
//! options.
//! `validate` (its numbers are exercised by the library tests): the progress it logs when
//! stderr is not a terminal, the evidence it lists source by source, its refusal of a bad
//! option and of an anatomy the atlas was not built from.

use crate::common::{otoatlas, otoatlas_json};

#[test]
fn simulate_writes_the_umbo_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("umbo.csv");
    let (code, json) = otoatlas_json(&[
        "simulate",
        "--steps",
        "4",
        "--pressure",
        "500",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{json}");
    assert!(json["frames_per_second"].as_f64().unwrap() > 0.0);
    let frame = |k: &str| json["frame_ms"][k].as_f64().unwrap();
    assert!(0.0 < frame("median") && frame("median") <= frame("p95"));
    assert!(frame("p95") <= frame("max"), "{json}");
    let csv = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "time_s,umbo_medial_mm,x_mm,y_mm,z_mm");
    assert_eq!(rows.len(), 1 + 5, "{csv}");
    let last: Vec<f64> = rows[5].split(',').map(|v| v.parse().unwrap()).collect();
    assert!((last[0] - 0.16).abs() < 1e-12);
    // canal pressure pushes the umbo medially, toward the 500 Pa static value (78.9 µm)
    assert!(last[1] > 0.0 && last[1] < 0.0790, "{}", last[1]);
    assert_eq!(json["final_umbo_medial_mm"].as_f64().unwrap(), last[1]);
}

/// `--condition stapes-fixation` steps the fixed ear: under 1 kPa its umbo settles on the
/// fixed ear's static value (51.55 µm, `otoatlas validate --condition stapes-fixation`), not
/// the normal ear's (86.5 µm); the JSON says which ear it stepped.
#[test]
fn simulate_steps_the_ear_of_the_condition() {
    let final_umbo = |condition: &str| {
        let (code, json) = otoatlas_json(&[
            "simulate",
            "--steps",
            "8",
            "--pressure",
            "1000",
            "--condition",
            condition,
        ]);
        assert_eq!(code, 0, "{json}");
        assert_eq!(json["condition"], condition, "{json}");
        json["final_umbo_medial_mm"].as_f64().unwrap()
    };
    let (normal, fixed) = (final_umbo("normal"), final_umbo("stapes-fixation"));
    println!("umbo after 8 steps at 1 kPa: normal {normal} mm, stapes fixation {fixed} mm");
    assert!((0.085..0.0900).contains(&normal), "{normal}");
    assert!((0.050..0.053).contains(&fixed), "{fixed}");
}

#[test]
fn simulate_rejects_a_bad_time_step() {
    let out = otoatlas(&["simulate", "--steps", "2", "--dt", "0", "--quiet"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("time step"));
}

#[test]
fn validate_rejects_a_bad_eardrum_bending_thickness() {
    let out = otoatlas(&["validate", "--eardrum-bending=-0.05", "--quiet"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    // exit 1 is kept for a failed gate
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("bending thickness"), "{stderr}");
}

/// `validate --convergence` rebuilds the atlas from the anatomy it was built from, which the
/// atlas's provenance names by its digest: another anatomy (here the embedded one with a
/// blend radius changed) is refused before any solve, as bad input. A comment added to the
/// same anatomy does not change the digest (the spec, not the file's bytes, is hashed).
#[test]
fn validate_convergence_refuses_an_anatomy_the_atlas_was_not_built_from() {
    use otoatlas::atlas::build::anatomy_digest;
    use otoatlas::atlas::{Anatomy, DEFAULT_TOML};
    let dir = tempfile::tempdir().unwrap();
    let commented = dir.path().join("commented.toml");
    std::fs::write(&commented, format!("# a note\n{DEFAULT_TOML}")).unwrap();
    assert_eq!(
        anatomy_digest(&Anatomy::load(&commented).unwrap()),
        anatomy_digest(&Anatomy::default_right().unwrap())
    );
    let other = dir.path().join("other.toml");
    assert!(DEFAULT_TOML.contains("blend_mm = 0.3\n"));
    std::fs::write(
        &other,
        DEFAULT_TOML.replacen("blend_mm = 0.3\n", "blend_mm = 0.35\n", 1),
    )
    .unwrap();
    let out = otoatlas(&[
        "validate",
        "--convergence",
        "--anatomy",
        other.to_str().unwrap(),
        "--quiet",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("the anatomy the atlas was built from")
            && stderr.contains("anatomy_sha256"),
        "{stderr}"
    );
    // refused before the atlas's own checks ran: nothing on stdout
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

#[test]
#[ignore = "heavy: the atlas's whole validation, 6 s in debug; scripts/test.sh runs it"]
fn validate_logs_its_progress_when_stderr_is_not_a_terminal() {
    // stderr is a pipe here, as in CI or a batch log: plain log lines instead of bars
    let out = otoatlas(&["validate"]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    // exit 1: the default atlas fails two gates, the 250-500 Hz slope (9.24 dB/octave, band
    // 3-9) and the drop to 4 kHz (7.88 dB, band 8-25; docs/mechanics.md, "Parameters")
    let failed: Vec<&str> = stdout.lines().filter(|l| l.contains("FAIL ")).collect();
    assert_eq!(failed.len(), 2, "{stdout}");
    assert!(failed[0].contains("FAIL slope 250-500 Hz"), "{stdout}");
    assert!(
        failed[1].contains("FAIL drop from max to 4 kHz"),
        "{stdout}"
    );
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    // as many frequencies and pressures as the report lists ("... deg" rows; "... um" rows but
    // the 0 Pa one)
    let frequencies = stdout
        .lines()
        .filter(|l| l.trim_end().ends_with(" deg"))
        .count();
    let pressures = stdout
        .lines()
        .filter(|l| l.trim_end().ends_with(" um") && !l.trim_start().starts_with("0 Pa"))
        .count();
    assert!(frequencies > 10 && pressures > 2, "{stdout}");
    // the flat top's band, whose centre a package's consistency gate compares: the atlas's
    // maximum (707 Hz) lies within it
    let band = stdout
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("within 1 dB of it: "))
        .unwrap_or_else(|| panic!("no band line in {stdout}"));
    let (low, rest) = band.split_once('-').unwrap();
    let high = rest.split_once(" Hz").unwrap().0;
    let (low, high): (f64, f64) = (low.parse().unwrap(), high.parse().unwrap());
    assert!(low < 707.0 && 707.0 < high, "{band}");
    // the evidence, one line per source, the fitted one marked as such
    let evidence: Vec<&str> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("evidence ("))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .collect();
    assert_eq!(evidence.len(), 6, "{stdout}");
    assert!(
        evidence[0].starts_with("  Goode et al. 1994") && evidence[0].contains("over 7 point(s)"),
        "{stdout}"
    );
    // a source the atlas meets says so, and one it misses (the live ears' phase at 300 Hz)
    assert!(
        evidence[2].starts_with("  Kringlebotn & Gundersen 1985")
            && evidence[2].contains("within ±10 dB: yes"),
        "{stdout}"
    );
    assert!(
        evidence[3].starts_with("  Chien et al. 2009")
            && evidence[3].contains("within ±15 deg: no"),
        "{stdout}"
    );
    // the static-pressure source: three pressures, each held to its own 2 SD
    assert!(
        evidence[4].starts_with("  Gyo & Goode 1987")
            && evidence[4].contains("over 3 point(s)")
            && evidence[4].contains("within ±2.0-3.6 dB: yes"),
        "{stdout}"
    );
    assert!(
        evidence[5].contains("(fitted: ") && !evidence[..5].iter().any(|e| e.contains("fitted")),
        "{stdout}"
    );
    let tfa_done = format!("TFA: {frequencies} frequencies solved");
    let udsp_done = format!("UDSP: {pressures} static pressures solved");
    let lines: Vec<&str> = stderr.lines().collect();
    // the summary line, with what the TFA's reduced model took in parentheses
    let at = |line: &str| {
        lines
            .iter()
            .position(|l| *l == line || l.starts_with(&format!("{line} (")))
    };
    let (Some(tfa), Some(udsp)) = (at(&tfa_done), at(&udsp_done)) else {
        panic!("no {tfa_done:?} or {udsp_done:?} in stderr:\n{stderr}");
    };
    assert!(tfa < udsp, "{stderr}");
    // the way there, in tenths, before the UDSP summary
    let tenths = |label: &str, end: usize| {
        lines[..end]
            .iter()
            .filter(|l| l.starts_with(&format!("{label}: ")) && l.contains("% ("))
            .count()
    };
    // the TFA's frequencies are solved together, from one reduced model, in under a second:
    // its summary says how, no tenths before it
    assert!(
        lines[tfa].contains("a reduced model of") && lines[tfa].contains("factorisations"),
        "{stderr}"
    );
    assert!(tenths("UDSP", udsp) >= 2, "{stderr}");
}
