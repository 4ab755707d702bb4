//! Ingest benchmark: reads a DICOM series (default: a 512 x 512 x 400 int16 series written by
//! `examples/synthetic_series.rs`) several times and reports seconds and MB/s of pixel data.
//!
//! `cargo run --release --example bench_ingest -- SERIES_DIR [REPEATS]`

use std::path::PathBuf;
use std::time::Instant;

use otoatlas::config::Config;
use otoatlas::image;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(
        args.first()
            .ok_or("usage: bench_ingest SERIES_DIR [REPEATS]")?,
    );
    let repeats: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(5);
    let cfg = Config::default_config()?;
    let mut times = Vec::new();
    let mut megabytes = 0.0;
    for _ in 0..repeats {
        let start = Instant::now();
        let img = image::load(&dir, None, &cfg.ingest)?;
        times.push(start.elapsed().as_secs_f64());
        megabytes = (img.volume.len() * 2) as f64 / 1e6;
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    println!(
        "ingest {} : {megabytes:.1} MB of int16 pixels, median {median:.3} s over {repeats} runs (best {:.3} s), {:.0} MB/s, threads {}",
        dir.display(),
        times[0],
        megabytes / median,
        rayon::current_num_threads()
    );
    Ok(())
}
