//! Mesh convergence of the stapes velocity transfer function: an atlas (default: the embedded
//! one) against a finer one at the six octave points 250…8000 Hz: |H_V| of both, the largest
//! |ΔdB| (criterion ≤ 1 dB; docs/mechanics.md, "Convergence") and the RMS difference of |H_V|:
//! `cargo run --release --example convergence -- FINE_DIR [ATLAS_DIR]`
//! (the fine atlas: `otoatlas atlas build --fine --out FINE_DIR`; about 2 minutes and 12 GB).

use std::path::Path;

use otoatlas::atlas::{Atlas, default_atlas, read_atlas};
use otoatlas::mechanics::{MechanicalSystem, TfaOptions, transfer_function};

const OCTAVES_HZ: [f64; 6] = [250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0];

/// |H_V| at the octave points [µm/s/Pa].
fn magnitudes(atlas: &Atlas) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let system = MechanicalSystem::new(atlas, atlas.nodes())?;
    let options = TfaOptions {
        frequencies_hz: OCTAVES_HZ.to_vec(),
        ..TfaOptions::default()
    };
    let tf = transfer_function(&system, &options, &otoatlas::progress::Silent)?;
    Ok(tf.points.iter().map(|p| p.magnitude_um_s_per_pa).collect())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(fine_dir) = args.first() else {
        return Err("usage: convergence FINE_DIR [ATLAS_DIR]".into());
    };
    let atlas = match args.get(1) {
        Some(dir) => read_atlas(Path::new(dir))?,
        None => default_atlas()?,
    };
    let fine = read_atlas(Path::new(fine_dir))?;
    println!(
        "atlas {} tets against fine {} tets",
        atlas.mesh.tets.tets.len(),
        fine.mesh.tets.tets.len()
    );
    let coarse = magnitudes(&atlas)?;
    drop(atlas);
    let reference = magnitudes(&fine)?;
    println!("f (Hz)   atlas   fine   fine − atlas (dB)");
    let mut worst_db = 0.0_f64;
    let mut squares = 0.0;
    for ((f, a), b) in OCTAVES_HZ.iter().zip(&coarse).zip(&reference) {
        let db = 20.0 * (b / a).log10();
        worst_db = worst_db.max(db.abs());
        squares += (a - b).powi(2);
        println!("{f:6.0} {a:8.2} {b:8.2} {db:+8.2}");
    }
    let rms = (squares / OCTAVES_HZ.len() as f64).sqrt();
    let verdict = if worst_db <= 1.0 { "met" } else { "missed" };
    println!("max |ΔdB| {worst_db:.2} (≤ 1 dB: {verdict}); RMS difference {rms:.1} µm/s/Pa");
    Ok(())
}
