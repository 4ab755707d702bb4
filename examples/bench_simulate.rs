//! Frames per second of `otoatlas simulate` on an atlas (default: the embedded one):
//! `cargo run --release --example bench_simulate [-- STEPS [ATLAS_DIR]]`. Runs one thread
//! (faer and rayon pinned to 1) and then the default pool, each under 1 kPa from rest.

use std::time::Instant;

use otoatlas::atlas::{default_atlas, read_atlas};
use otoatlas::mechanics::MechanicalSystem;
use otoatlas::mechanics::simulate::{SimulationOptions, simulate};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let steps: usize = args.next().map_or(Ok(500), |s| s.parse())?;
    let atlas = match args.next() {
        Some(dir) => read_atlas(std::path::Path::new(&dir))?,
        None => default_atlas()?,
    };
    let system = MechanicalSystem::new(&atlas, atlas.nodes())?;
    println!(
        "atlas: {} tets, {} membrane triangles, {} DOF; {steps} steps of 0.04 s under 1 kPa",
        system.model.tet_count(),
        system.model.membrane_count(),
        system.model.dof_count()
    );
    let options = SimulationOptions {
        steps,
        ..SimulationOptions::default()
    };
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    for (label, threads) in [("1 thread", Some(&one)), ("default pool", None)] {
        let t = Instant::now();
        let sim = match threads {
            Some(pool) => pool.install(|| simulate(&system, &options))?,
            None => simulate(&system, &options)?,
        };
        println!(
            "{label}: {:.0} frames/s ({:.2} ms/step; frame median {:.2} ms = {:.0} fps, 95th \
             percentile {:.2} ms, worst {:.1} ms; {:.1} CG iterations/step, {} factorisations, \
             setup {:.3} s, total {:.2} s); umbo {:.3} um",
            sim.frames_per_second,
            1e3 / sim.frames_per_second,
            sim.frame_ms.median,
            1e3 / sim.frame_ms.median,
            sim.frame_ms.p95,
            sim.frame_ms.max,
            sim.mean_cg_iterations,
            sim.factorisations,
            sim.setup_seconds,
            t.elapsed().as_secs_f64(),
            sim.frames.last().map_or(0.0, |f| f.umbo_medial_mm * 1e3)
        );
    }
    Ok(())
}
