//! `otoatlas validate [PACKAGE | --atlas DIR]`: the mechanical checks (UDSP, TFA) of an atlas
//! against the literature bands, or of a patient package (or a registered atlas) against the
//! atlas it came from; exit code 1 when a gate fails.

use std::fmt::Write;
use std::path::PathBuf;

use clap::Args;

use super::Report;
use super::package_arg::{open_package, source_atlas};
use crate::Error;
use crate::atlas::{Anatomy, load_atlas};
use crate::mechanics::verdict::MAXIMUM_BAND_DB;
use crate::mechanics::{
    Condition, ConditionChange, Drive, DrumConvergence, DrumStudy, Ossicles, ValidationOptions,
    validate_atlas, validate_package,
};
use crate::progress::Reporter;
use crate::report::mechanics_plots::validation_plots;

/// Validate the mechanics of an atlas or a patient package: umbo displacement under static
/// pressure (UDSP) and the stapes velocity transfer function (TFA), with verdicts.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  otoatlas validate                                  # the embedded atlas, literature gates
  otoatlas validate out/case-001/package --plots out/case-001/plots
  otoatlas validate --atlas my-atlas                 # another atlas, literature gates
  otoatlas validate out/p/package --reference my-atlas   # a package of my-atlas
  otoatlas validate --drive umbo --json
  otoatlas validate --condition stapes-fixation      # otosclerosis: fails the normal bands
  otoatlas validate --convergence --json             # and the eardrum mesh's convergence

Exit codes: 0 every gate passed, 1 a gate failed (the report says which), 2 bad input.")]
pub struct ValidateArgs {
    /// A patient package (OUT/package of a run): verified, then gated against the atlas it
    /// was registered from (the embedded one, or --reference), identified by the SHA-256 in
    /// its manifest.
    #[arg(value_name = "PACKAGE", conflicts_with = "atlas")]
    pub package: Option<PathBuf>,
    /// An atlas folder to validate against the literature bands; default: the embedded atlas.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// The atlas the package (or --atlas, a registered atlas with the same mesh) came from;
    /// "default" = the embedded one. Gates relative to it instead of the literature bands.
    #[arg(long, value_name = "DIR")]
    pub reference: Option<PathBuf>,
    /// The ear's condition: a pathology made from the atlas (docs/mechanics.md,
    /// "Pathologies"); the literature gates are those of a normal ear, which it should fail.
    #[arg(long, value_enum, default_value_t = Condition::Normal)]
    pub condition: Condition,
    /// Where the sound drives the ear.
    #[arg(long, value_enum, default_value_t = Drive::Eardrum)]
    pub drive: Drive,
    /// What-if: bend the whole eardrum at this flexural thickness (mm) instead of the atlas's
    /// own (its regions' bending_thickness_mm: pars tensa 0.074, pars flaccida 0.1 in the
    /// default atlas; docs/mechanics.md, "The eardrum: a curved shell").
    #[arg(long, value_name = "MM", value_parser = positive_mm)]
    pub eardrum_bending: Option<f64>,
    /// Also study the eardrum mesh's convergence: the atlas rebuilt from its anatomy with
    /// drum triangles √2 and 2 times smaller, each one's transfer function and static curve
    /// against the finest (converged: within 1 dB and 5 %); about 10 s more on the default
    /// atlas.
    #[arg(long, conflicts_with_all = ["package", "reference"])]
    pub convergence: bool,
    /// With --convergence: the anatomy (TOML) the atlas was built from; default: the
    /// embedded assets/anatomy.toml.
    #[arg(long, value_name = "FILE", requires = "convergence")]
    pub anatomy: Option<PathBuf>,
    /// The ossicles in the transfer function's solves: elastic bone (the full model), or each
    /// ossicle one rigid body (half the unknowns; what `run` checks a package with). Default:
    /// rigid for a package (or --reference), elastic for an atlas against the literature.
    #[arg(long, value_enum, value_name = "MODEL")]
    pub ossicles: Option<Ossicles>,
    /// Write tf_magnitude.svg, tf_phase.svg and udsp.svg into this folder.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &ValidateArgs, progress: &dyn Reporter) -> Result<Report, Error> {
    let mut options = ValidationOptions::default();
    options.tfa.drive = args.drive;
    options.eardrum_bending_mm = args.eardrum_bending;
    options.condition = args.condition;
    let against_reference = args.package.is_some() || args.reference.is_some();
    let ossicles = args.ossicles.unwrap_or(if against_reference {
        Ossicles::Rigid
    } else {
        Ossicles::Elastic
    });
    options.tfa.ossicles = ossicles;
    if let Some(udsp) = &mut options.udsp {
        udsp.ossicles = ossicles;
    }
    let reference_dir = args
        .reference
        .as_deref()
        .filter(|r| r.as_os_str() != "default");
    // the atlas to check, and the one it came from for the consistency gates
    let (atlas, reference) = match &args.package {
        Some(dir) => {
            let package = open_package(dir)?;
            let reference = source_atlas(&package, reference_dir)?;
            (package.atlas, Some(reference))
        }
        None => (
            load_atlas(args.atlas.as_deref(), None)?,
            args.reference
                .as_ref()
                .map(|_| load_atlas(reference_dir, None))
                .transpose()?,
        ),
    };
    let anatomy = match (&args.anatomy, args.convergence) {
        (Some(p), _) => Some(Anatomy::load(p)?),
        (None, true) => Some(Anatomy::default_right()?),
        (None, false) => None,
    };
    // refused before any solve when the atlas was not built from the anatomy
    let study = anatomy
        .as_ref()
        .map(|anatomy| DrumStudy::new(&atlas, anatomy))
        .transpose()?;
    let mut convergence = None;
    let validation = match reference {
        None => {
            let validation = validate_atlas(&atlas, &options, progress)?;
            if let Some(study) = &study {
                convergence = Some(study.run(&validation.mechanics, &options, progress)?);
            }
            validation
        }
        Some(reference) => {
            let same = reference.mesh.tets.tets == atlas.mesh.tets.tets
                && reference.mesh.triangles == atlas.mesh.triangles;
            if !same {
                return Err(Error::Usage(
                    "the atlas and its reference must share one mesh (a package is its atlas \
                     with moved nodes)"
                        .into(),
                ));
            }
            validate_package(&reference, atlas.nodes(), &options, progress)?
        }
    };
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).map_err(|source| Error::Io {
            path: dir.clone(),
            source,
        })?;
        for (name, svg) in validation_plots(&validation) {
            let path = dir.join(name);
            crate::io_util::write_atomic(&path, svg.as_bytes())?;
        }
    }
    let m = &validation.mechanics;
    let mut text = String::new();
    if validation.condition != Condition::Normal {
        let _ = writeln!(
            text,
            "condition: {:?} (the literature gates are a normal ear's)",
            validation.condition
        );
    }
    let _ = writeln!(
        text,
        "transfer function (stapes piston velocity / {:?} drive of {} Pa):",
        m.transfer_function.drive, m.transfer_function.drive_pa
    );
    for p in &m.transfer_function.points {
        let _ = writeln!(
            text,
            "  {:7.0} Hz  {:9.2} um/s/Pa  {:7.1} deg",
            p.frequency_hz, p.magnitude_um_s_per_pa, p.phase_deg
        );
    }
    if let Some((f, h)) = m.transfer_function.peak() {
        let _ = writeln!(text, "  maximum {h:.2} um/s/Pa at {f:.0} Hz");
    }
    let tf = &m.transfer_function;
    if let (Some((low, high)), Some(centre)) = (
        tf.maximum_band(MAXIMUM_BAND_DB),
        tf.maximum_band_centre(MAXIMUM_BAND_DB),
    ) {
        let _ = writeln!(
            text,
            "  within {MAXIMUM_BAND_DB} dB of it: {low:.0}-{high:.0} Hz, centre {centre:.0} Hz \
             (what a package's consistency gate compares)"
        );
    }
    let _ = writeln!(
        text,
        "umbo displacement under static pressure (p = ear canal - middle ear; + = medial):"
    );
    for p in &m.udsp.points {
        let _ = writeln!(
            text,
            "  {:6.0} Pa  {:9.2} um",
            p.pressure_pa,
            p.umbo_mm * 1e3
        );
    }
    if let Some(a) = m.udsp.asymmetry() {
        let _ = writeln!(text, "  asymmetry |u(-4 kPa)|/|u(+4 kPa)| = {a:.3}");
    }
    if let Some(why) = &m.udsp.failure {
        let _ = writeln!(text, "  stopped short: {why}");
    }
    let _ = writeln!(
        text,
        "timing: TFA {:.2} s, UDSP {:.2} s",
        m.tfa_seconds, m.udsp_seconds
    );
    let v = &validation.verdict;
    let _ = writeln!(text, "verdict, {} ({} gates):", v.kind, v.gates.len());
    for g in &v.gates {
        let _ = writeln!(
            text,
            "  {} {:45} {:10.3} {} in [{}, {}]",
            if g.passed { "PASS" } else { "FAIL" },
            g.name,
            g.value,
            g.unit,
            g.low,
            g.high
        );
    }
    if !validation.evidence.is_empty() {
        let _ = writeln!(
            text,
            "evidence (the model against measurements, residual = model - measured):"
        );
    }
    for e in &validation.evidence {
        let spread = match e.spread_range() {
            (lo, hi) if lo < hi => format!("{lo:.1}-{hi:.1}"),
            (lo, _) => format!("{lo}"),
        };
        let _ = writeln!(
            text,
            "  {}: RMS {:.1} {u} over {} point(s), worst {:+.1} {u}; within ±{spread} {u}: {}{}",
            e.source,
            e.rms_residual,
            e.points.len(),
            e.worst_residual,
            if e.within_spread { "yes" } else { "no" },
            e.fitted
                .map(|why| format!(" (fitted: {why})"))
                .unwrap_or_default(),
            u = e.residual_unit,
        );
    }
    changes_text(&mut text, &validation.changes);
    if let Some(c) = &convergence {
        convergence_text(&mut text, c);
    }
    let passed = v.passed && convergence.as_ref().is_none_or(|c| c.converged);
    let _ = writeln!(text, "{}", if passed { "PASSED" } else { "FAILED" });
    let json = serde_json::json!({
        "passed": passed,
        "condition": validation.condition,
        "verdict": v,
        "evidence": validation.evidence,
        "changes": validation.changes,
        "mechanics": m,
        "reference": validation.reference,
        "convergence": convergence,
    });
    Ok(Report { text, json })
}

/// What a condition changes against the normal ear, each source's lines under it.
fn changes_text(text: &mut String, changes: &[ConditionChange]) {
    if changes.is_empty() {
        return;
    }
    let _ = writeln!(
        text,
        "changes against the normal ear (velocity over ear-canal pressure, dB), beside \
         temporal bones:"
    );
    let mut source = "";
    for c in changes {
        if c.source != source {
            source = c.source;
            let _ = writeln!(text, "  {source}:");
        }
        let range = match (c.low_db, c.high_db) {
            (Some(low), Some(high)) => format!("{low:.1} to {high:.1}"),
            (Some(low), None) => format!("above {low:.1}"),
            (None, Some(high)) => format!("below {high:.1}"),
            (None, None) => "any".into(),
        };
        let _ = writeln!(
            text,
            "    {:6} {:5.0} Hz {:+7.1} dB; expected {range} dB: {}",
            c.velocity.name(),
            c.frequency_hz,
            c.model_db,
            if c.within { "yes" } else { "no" },
        );
    }
}

/// The convergence study's table: each drum against the finest.
fn convergence_text(text: &mut String, c: &DrumConvergence) {
    let _ = writeln!(
        text,
        "eardrum convergence (each drum against the finest; bounds {} dB, {} %):",
        c.bound_db,
        100.0 * c.bound_static_fraction
    );
    for l in &c.levels {
        let _ = writeln!(
            text,
            "  drum edge {:.3} mm, {:5} triangles: worst {:.2} dB, {:.1} deg, static {:.2} %, \
             asymmetry {}; {}",
            l.membrane_edge_mm,
            l.membrane_triangles,
            l.worst_db,
            l.worst_phase_deg,
            100.0 * l.worst_static_fraction,
            l.asymmetry.map_or("-".into(), |a| format!("{a:.3}")),
            l.manubrium_attachment
        );
    }
    let _ = writeln!(
        text,
        "  {}",
        if c.converged {
            "converged: the atlas's own drum is within both bounds of the finest"
        } else {
            "NOT converged: the atlas's own drum is outside a bound of the finest"
        }
    );
}

/// A thickness (mm): finite and > 0, refused at the command line otherwise.
fn positive_mm(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!(
            "bending thickness {text:?}: expected a number of mm > 0"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mechanics::Velocity;

    #[test]
    fn a_condition_s_changes_are_listed_under_their_sources_with_open_ranges_said_so() {
        let change = |velocity, f, model_db, low_db, high_db, within, source| ConditionChange {
            velocity,
            frequency_hz: f,
            model_db,
            low_db,
            high_db,
            within,
            source,
        };
        let mut text = String::new();
        changes_text(
            &mut text,
            &[
                change(Velocity::Stapes, 250.0, -77.1, None, Some(-40.0), true, "A"),
                change(
                    Velocity::Stapes,
                    500.0,
                    -30.0,
                    None,
                    Some(-40.0),
                    false,
                    "A",
                ),
                change(Velocity::Umbo, 250.0, 2.5, Some(0.0), None, true, "B"),
            ],
        );
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 6, "{text}");
        assert_eq!(lines[1], "  A:");
        assert_eq!(
            lines[2],
            "    stapes   250 Hz   -77.1 dB; expected below -40.0 dB: yes"
        );
        assert!(
            lines[3].ends_with("-30.0 dB; expected below -40.0 dB: no"),
            "{text}"
        );
        assert_eq!(lines[4], "  B:");
        assert!(
            lines[5].ends_with("+2.5 dB; expected above 0.0 dB: yes"),
            "{text}"
        );
        let mut none = String::new();
        changes_text(&mut none, &[]);
        assert!(none.is_empty());
    }
}
