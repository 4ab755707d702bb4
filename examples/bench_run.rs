//! `cargo run --release --example bench_run [-- REPEATS]`: `otoatlas run` on each sample case,
//! REPEATS times (default 5), printing the median seconds of every stage and of the whole run.
//! Like the `otoatlas` command, it runs on rayon's workers (`cli::main`).

use std::path::Path;

use otoatlas::config::Config;
use otoatlas::pipeline::{AutoLandmarks, Case, RunOptions, Stage, run_case};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    rayon::ThreadPoolBuilder::new()
        .build()?
        .install(|| bench().map_err(|e| e.to_string()))?;
    Ok(())
}

fn bench() -> Result<(), Box<dyn std::error::Error>> {
    let repeats: usize = std::env::args().nth(1).map_or(Ok(5), |s| s.parse())?;
    let config = Config::default_config()?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = tempfile::tempdir()?;
    println!(
        "case       spacing  dims          ingest landmarks rigid deform  score export validate report  total"
    );
    for k in 1..=3 {
        let case = Case::open(&root.join(format!("sample_cases/case-00{k}")))?;
        let opts = RunOptions {
            out: out.path().join(format!("case{k}")),
            from: Stage::Ingest,
            landmarks: None,
            atlas: None,
            side: None,
            keep_phi: false,
            auto_landmarks: AutoLandmarks::Never,
            condition: otoatlas::mechanics::Condition::Normal,
        };
        let names: Vec<&str> = Stage::ALL
            .iter()
            .map(|s| s.name())
            .chain(["validate", "report"])
            .collect();
        let mut per_stage: Vec<Vec<f64>> = vec![Vec::new(); names.len() + 1];
        let mut dims = String::new();
        let mut spacing = 0.0;
        for _ in 0..repeats {
            let t = std::time::Instant::now();
            let summary = run_case(&case, &opts, &config, &otoatlas::progress::Silent)?;
            per_stage[names.len()].push(t.elapsed().as_secs_f64());
            for (step, secs) in summary.timings {
                if let Some(k) = names.iter().position(|n| *n == step) {
                    per_stage[k].push(secs);
                }
            }
            let [nx, ny, nz] = summary.metrics.image.dims;
            dims = format!("[{nx},{ny},{nz}]");
            spacing = summary.metrics.image.spacing[0];
        }
        // a step that did not run (validation off) reads 0
        let m: Vec<f64> = per_stage
            .into_iter()
            .map(|v| if v.is_empty() { 0.0 } else { median(v) })
            .collect();
        println!(
            "{:<10} {:>5.3} mm {:<13} {:>6.3} {:>9.3} {:>5.3} {:>6.3} {:>6.3} {:>6.3} {:>8.3} {:>6.3} {:>6.3}",
            case.id, spacing, dims, m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
        );
    }
    Ok(())
}
