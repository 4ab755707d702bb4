//! `otoatlas simulate [PACKAGE]`: step a patient package or an atlas in time (backward Euler,
//! one solve per step) under a static ear-canal pressure or an umbo force, print the frame
//! rate and write the umbo trajectory.

use std::fmt::Write;
use std::path::PathBuf;

use clap::Args;

use super::Report;
use super::package_arg::open_package;
use crate::Error;
use crate::atlas::load_atlas;
use crate::mechanics::simulate::{SimulationOptions, simulate};
use crate::mechanics::{Condition, MechanicalSystem};

/// Step a patient package or an atlas in time and write the umbo trajectory.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  otoatlas simulate --steps 500 --pressure 2000 --out umbo.csv
  otoatlas simulate out/case-001/package --steps 300 --out umbo.csv
  otoatlas simulate --condition stapes-fixation --out umbo.csv
  otoatlas simulate --atlas patient-atlas --dt 0.01 --umbo-force 500 --out umbo.json")]
pub struct SimulateArgs {
    /// A patient package (OUT/package of a run), verified before it is stepped.
    #[arg(value_name = "PACKAGE", conflicts_with = "atlas")]
    pub package: Option<PathBuf>,
    /// An atlas folder; default (no PACKAGE either): the embedded atlas.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// The ear's condition: a pathology made from the atlas or package (docs/mechanics.md,
    /// "Pathologies").
    #[arg(long, value_enum, default_value_t = Condition::Normal)]
    pub condition: Condition,
    /// Number of time steps.
    #[arg(long, default_value_t = 250)]
    pub steps: usize,
    /// Time step [s] (the source study: 0.04).
    #[arg(long, default_value_t = 0.04)]
    pub dt: f64,
    /// Ear-canal pressure [Pa], + pushes the eardrum medially.
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub pressure: f64,
    /// A force on the umbo along the medial axis [µN].
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub umbo_force: f64,
    /// Refresh the CG preconditioner (a Cholesky factor of the step matrix) every N steps;
    /// it is also refreshed whenever CG needs more than 2 iterations.
    #[arg(long, value_name = "N", default_value_t = 1000)]
    pub refactor_every: usize,
    /// Trajectory file: .csv (time_s, umbo_medial_mm, x, y, z) or .json.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &SimulateArgs) -> Result<Report, Error> {
    if args.steps == 0 || args.steps > 10_000_000 {
        return Err(Error::Usage(format!(
            "--steps {}: expected 1 to 10,000,000",
            args.steps
        )));
    }
    let atlas = match &args.package {
        Some(dir) => open_package(dir)?.atlas,
        None => load_atlas(args.atlas.as_deref(), None)?,
    };
    let system = MechanicalSystem::new(&args.condition.apply(&atlas)?, atlas.nodes())?;
    let options = SimulationOptions {
        steps: args.steps,
        dt: args.dt,
        pressure_pa: args.pressure,
        umbo_force_un: args.umbo_force,
        refactor_every: args.refactor_every,
    };
    let sim = simulate(&system, &options)?;
    if let Some(path) = &args.out {
        let is_json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let bytes = if is_json {
            serde_json::to_vec_pretty(&sim.frames).unwrap_or_default()
        } else {
            let mut csv = String::from("time_s,umbo_medial_mm,x_mm,y_mm,z_mm\n");
            for f in &sim.frames {
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{}",
                    f.time_s, f.umbo_medial_mm, f.umbo[0], f.umbo[1], f.umbo[2]
                );
            }
            csv.into_bytes()
        };
        crate::io_util::write_atomic(path, &bytes)?;
    }
    let last = sim.frames.last().map_or(0.0, |f| f.umbo_medial_mm);
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} steps of {} s: {:.0} frames per second (setup {:.3} s, stepping {:.3} s, {:.1} CG \
         iterations per step, {} factorisations)",
        args.steps,
        args.dt,
        sim.frames_per_second,
        sim.setup_seconds,
        sim.step_seconds,
        sim.mean_cg_iterations,
        sim.factorisations
    );
    let _ = writeln!(
        text,
        "frame time: median {:.2} ms ({:.0} frames per second), 95th percentile {:.2} ms, worst \
         {:.2} ms (the steps that refresh the preconditioner as the load sets in)",
        sim.frame_ms.median,
        1e3 / sim.frame_ms.median.max(1e-9),
        sim.frame_ms.p95,
        sim.frame_ms.max
    );
    let _ = writeln!(
        text,
        "umbo displacement at t = {:.3} s: {:.3} um (+ = medial)",
        args.steps as f64 * args.dt,
        last * 1e3
    );
    if sim.failed_elements > 0 {
        let _ = writeln!(
            text,
            "warning: {} elements inverted or collapsed at the last step",
            sim.failed_elements
        );
    }
    if let Some(p) = &args.out {
        let _ = writeln!(text, "wrote {}", p.display());
    }
    let json = serde_json::json!({
        "condition": args.condition,
        "steps": args.steps,
        "dt_s": args.dt,
        "frames_per_second": sim.frames_per_second,
        "frame_ms": sim.frame_ms,
        "setup_seconds": sim.setup_seconds,
        "step_seconds": sim.step_seconds,
        "failed_elements": sim.failed_elements,
        "mean_cg_iterations": sim.mean_cg_iterations,
        "factorisations": sim.factorisations,
        "final_umbo_medial_mm": last,
        "out": args.out,
    });
    Ok(Report { text, json })
}
