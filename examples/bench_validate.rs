//! Times `otoatlas validate` on an atlas (default: the embedded one) and prints the figures:
//! `cargo run --release --example bench_validate [-- ATLAS_DIR [--tf-only] [--octaves]]`
//! (`--octaves`: the TF at the six gate frequencies 250…8000 Hz only, for the fine atlas).

use std::time::Instant;

use otoatlas::atlas::{default_atlas, read_atlas};
use otoatlas::mechanics::{
    MechanicalSystem, TfaOptions, UdspOptions, static_pressure_curve, transfer_function,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let atlas = match std::env::args().nth(1).filter(|a| !a.starts_with("--")) {
        Some(dir) => read_atlas(std::path::Path::new(&dir))?,
        None => default_atlas()?,
    };
    let t0 = Instant::now();
    let system = MechanicalSystem::new(&atlas, atlas.nodes())?;
    println!(
        "atlas: {} tets, {} membrane triangles, {} nodes; system built in {:.3} s",
        system.model.tet_count(),
        system.model.membrane_count(),
        system.model.node_count(),
        t0.elapsed().as_secs_f64()
    );
    println!(
        "eardrum area {:.2} mm2, footplate area {:.2} mm2, medial {:?}, footplate normal {:?}",
        system.eardrum_area_mm2,
        system.footplate_area_mm2,
        system.medial.as_slice(),
        system.footplate_normal.as_slice()
    );
    let t1 = Instant::now();
    let mut options = TfaOptions::default();
    if std::env::args().any(|a| a == "--octaves") {
        options.frequencies_hz = vec![250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0];
    }
    let tf = transfer_function(&system, &options, &otoatlas::progress::Silent)?;
    let t_tf = t1.elapsed().as_secs_f64();
    for p in &tf.points {
        println!(
            "TF {:7.0} Hz  {:9.3} um/s/Pa  {:7.1} deg  (umbo {:9.3} um/s/Pa)",
            p.frequency_hz, p.magnitude_um_s_per_pa, p.phase_deg, p.umbo_um_s_per_pa
        );
    }
    println!(
        "TF peak {:?}; {} frequencies in {t_tf:.3} s",
        tf.peak(),
        tf.points.len()
    );
    if std::env::args().any(|a| a == "--tf-only") {
        return Ok(());
    }
    let t2 = Instant::now();
    let curve = static_pressure_curve(
        &system,
        &UdspOptions::default(),
        &otoatlas::progress::Silent,
    )?;
    let t_s = t2.elapsed().as_secs_f64();
    for p in &curve.points {
        println!(
            "UDSP {:6.0} Pa  umbo {:9.5} mm  ({} iterations)",
            p.pressure_pa, p.umbo_mm, p.iterations
        );
    }
    println!(
        "UDSP asymmetry {:?}, monotonic {}; {} pressures in {t_s:.3} s",
        curve.asymmetry(),
        curve.monotonic(),
        curve.points.len()
    );
    println!("total {:.3} s", t0.elapsed().as_secs_f64());
    Ok(())
}
