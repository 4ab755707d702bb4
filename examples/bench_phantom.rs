//! Generating phantom cases: time to make one case in memory (variability, truth surfaces,
//! adaptive render, label map) and to write its folder, for five seeds at one spacing.
//!
//! `cargo run --release --example bench_phantom [SPACING_MM]` (default 0.2)

use std::time::Instant;

use otoatlas::phantom::{PhantomOptions, generate_case, write_case};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let spacing: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(0.2);
    let options = PhantomOptions {
        spacing_mm: Some(spacing),
        ..PhantomOptions::default()
    };
    let dir = std::env::temp_dir().join(format!("otoatlas-bench-phantom-{}", std::process::id()));
    let mut totals = Vec::new();
    for seed in 1..=5u64 {
        let start = Instant::now();
        let case = generate_case(seed, &options)?;
        let generated = start.elapsed().as_secs_f64();
        let start = Instant::now();
        write_case(&dir.join(format!("case-{seed}")), &case)?;
        let written = start.elapsed().as_secs_f64();
        let [nx, ny, nz] = case.truth.image.dims;
        println!(
            "seed {seed}: {} ear, {nx}x{ny}x{nz} = {} voxels at {spacing} mm: generate {generated:.2} s, write {written:.2} s, total {:.2} s",
            case.truth.side.as_str(),
            nx * ny * nz,
            generated + written
        );
        totals.push(generated + written);
    }
    totals.sort_by(f64::total_cmp);
    println!("median total per case: {:.2} s", totals[totals.len() / 2]);
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}
