//! Mesh convergence of the stapes velocity transfer function: an atlas (default: the embedded
//! one) against a finer one at the 16 one-third octaves 250…8000 Hz that `validate` uses:
//! |H_V| of both and their difference in dB, the largest |ΔdB| over the octave points and over
//! every one-third octave (criterion ≤ 1 dB; docs/mechanics.md, "Convergence"), and the RMS
//! difference of |H_V| at the octaves:
//! `cargo run --release --example convergence -- FINE_DIR [ATLAS_DIR]`
//! (the fine atlas: `otoatlas atlas build --fine --out FINE_DIR`, about 15 s; the comparison
//! about 40 s and 4 GB on two cores).
//! The octaves alone miss the suspension's resonance between them (near 300 Hz), where the
//! 250-500 Hz slope gate and Chien's phase are read.

use std::path::Path;

use otoatlas::atlas::{Atlas, default_atlas, read_atlas};
use otoatlas::mechanics::{MechanicalSystem, TfaOptions, transfer_function};

/// (frequency Hz, |H_V| µm/s/Pa) at the default one-third octaves.
fn magnitudes(atlas: &Atlas) -> Result<Vec<(f64, f64)>, Box<dyn std::error::Error>> {
    let system = MechanicalSystem::new(atlas, atlas.nodes())?;
    let tf = transfer_function(&system, &TfaOptions::default(), &otoatlas::progress::Silent)?;
    Ok(tf
        .points
        .iter()
        .map(|p| (p.frequency_hz, p.magnitude_um_s_per_pa))
        .collect())
}

/// An octave point of 250 Hz (250, 500, …, 8000), to within the one-third octaves' rounding.
fn is_octave(f: f64) -> bool {
    let octaves = (f / 250.0).log2();
    (octaves - octaves.round()).abs() < 0.01
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
    let (mut worst_octave_db, mut worst_db) = (0.0_f64, 0.0_f64);
    let (mut squares, mut octaves) = (0.0, 0);
    for ((f, a), (_, b)) in coarse.iter().zip(&reference) {
        let db = 20.0 * (b / a).log10();
        worst_db = worst_db.max(db.abs());
        let mark = if is_octave(*f) {
            worst_octave_db = worst_octave_db.max(db.abs());
            squares += (a - b).powi(2);
            octaves += 1;
            "  (octave)"
        } else {
            ""
        };
        println!("{f:6.0} {a:8.2} {b:8.2} {db:+8.2}{mark}");
    }
    let rms = (squares / f64::from(octaves.max(1))).sqrt();
    let verdict = |db: f64| if db <= 1.0 { "met" } else { "missed" };
    println!(
        "max |ΔdB| at the octaves {worst_octave_db:.2} (≤ 1 dB: {}), at every one-third octave \
         {worst_db:.2} (≤ 1 dB: {}); RMS difference at the octaves {rms:.1} µm/s/Pa",
        verdict(worst_octave_db),
        verdict(worst_db)
    );
    Ok(())
}
