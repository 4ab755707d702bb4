//! `cargo run --release --example bench_batch [-- CASES]`: a cohort of CASES phantom cases
//! (default 20) at 0.2 mm through `batch` with 1 and with 2 jobs, printing the wall time of
//! each, the parallel speed-up and the per-case time distribution. The phantoms are made
//! (seed 7000 on) before the clock starts.

use otoatlas::config::Config;
use otoatlas::phantom::{PhantomOptions, generate_case, write_case};
use otoatlas::pipeline::batch::{BatchOptions, Outcome, run_batch};
use otoatlas::pipeline::cohort::read_cohort;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cases: u64 = std::env::args().nth(1).map_or(Ok(20), |s| s.parse())?;
    let config = Config::default_config()?;
    let dir = tempfile::tempdir()?;
    let options = PhantomOptions {
        spacing_mm: Some(0.2),
        ..PhantomOptions::default()
    };
    for k in 0..cases {
        let case = generate_case(7000 + k, &options)?;
        write_case(&dir.path().join(format!("case-{k:03}")), &case)?;
    }
    let cohort = read_cohort(dir.path())?.cases;
    println!("{cases} phantom cases at 0.2 mm");
    let mut wall = Vec::new();
    for jobs in [1, 2] {
        let opts = BatchOptions {
            out: dir.path().join(format!("out-{jobs}")),
            jobs,
            resume: false,
            atlas: None,
            keep_phi: false,
            condition: otoatlas::mechanics::Condition::Normal,
            child: None,
        };
        let t = std::time::Instant::now();
        let statuses = run_batch(&cohort, &opts, &config, &otoatlas::progress::Silent)?;
        let seconds = t.elapsed().as_secs_f64();
        wall.push(seconds);
        let failed = statuses
            .iter()
            .filter(|s| s.outcome == Outcome::Failed)
            .count();
        let mut per_case: Vec<f64> = statuses.iter().map(|s| s.seconds).collect();
        per_case.sort_by(f64::total_cmp);
        println!(
            "jobs {jobs}: {seconds:.1} s wall, {failed} failed; per case min {:.2} median {:.2} \
             p90 {:.2} max {:.2} s",
            per_case[0],
            percentile(&per_case, 0.5),
            percentile(&per_case, 0.9),
            per_case[per_case.len() - 1]
        );
    }
    println!("speed-up 1 -> 2 jobs: {:.2}x", wall[0] / wall[1]);
    Ok(())
}
