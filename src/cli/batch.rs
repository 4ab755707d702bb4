//! `otoatlas batch` (a cohort in parallel, with resume, shards and Slurm job arrays) and
//! `otoatlas cohort-report` (the shards' results merged).

use std::fmt::Write;
use std::path::{Path, PathBuf};

use clap::Args;

use super::Report;
use super::out_arg::check_out_dir;
use crate::Error;
use crate::config::Config;
use crate::mechanics::Condition;
use crate::pipeline::batch::{BatchOptions, Outcome, run_batch};
use crate::pipeline::case_process::{CaseProcess, serve};
use crate::pipeline::cohort::{Shard, read_cohort};
use crate::pipeline::cohort_summary::{merge_cohort, write_case_list};
use crate::pipeline::sbatch::{SbatchSpec, sbatch_script};
use crate::progress::Reporter;

/// Register a cohort: every case through `run`, in parallel, each into OUT/cases/ID/, with a
/// cohort report.
#[derive(Debug, Args)]
#[command(
    after_help = "COHORT is a folder of case folders or a manifest (.toml with [[case]] \
tables, or .csv with the columns id,image,landmarks[,segmentation][,series]; paths relative \
to the manifest; series, as run --series takes it, picks one of several series in an image \
folder).

Outputs under OUT: cases/ID/ (what `run` writes, plus status.json), cohort.json, the cohort \
report cohort.html and cohort.csv. Exit code 1 when any case failed.

Examples:
  otoatlas batch sample_cases --out out/cohort
  otoatlas batch cohort.toml --out out/cohort --jobs 2 --resume
  otoatlas batch cohort.csv --out /scratch/cohort --emit-sbatch cohort.sbatch --shards 8
  otoatlas cohort-report /scratch/cohort"
)]
pub struct BatchArgs {
    /// A folder of case folders, or a cohort manifest (.toml or .csv).
    pub cohort: PathBuf,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Cases at once (and threads in all); default: every core.
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Skip the cases whose outputs are complete and current (same inputs, configuration and
    /// atlas).
    #[arg(long)]
    pub resume: bool,
    /// Run only the K-th of N deterministic slices of the cohort (K from 0); default: from
    /// SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT when set, else the whole cohort.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Atlas folder instead of the embedded default.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// Write a Slurm job-array script for the cohort to FILE instead of running it.
    #[arg(long, value_name = "FILE")]
    pub emit_sbatch: Option<PathBuf>,
    /// Array tasks of the emitted script; default: one per case.
    #[arg(long, value_name = "N", requires = "emit_sbatch")]
    pub shards: Option<usize>,
    /// Keep the DICOM patient fields (name, ID, birth date, institution, accession) in the
    /// packages' manifests; without it no output holds them.
    #[arg(long)]
    pub keep_phi: bool,
    /// Address space each case's process may use, in MiB (RLIMIT_AS, as `ulimit -v`): a case
    /// that needs more fails alone, named in the cohort report. A case needs about 1 GiB plus
    /// 3 times its volume; default: no limit of its own.
    #[arg(long, value_name = "MIB", value_parser = clap::value_parser!(u64).range(1..))]
    pub case_memory_limit: Option<u64>,
    /// The ear's condition every package models (`run --condition`): the same registration,
    /// the materials of a pathology.
    #[arg(long, value_enum, default_value = "normal")]
    pub condition: Condition,
    /// Print machine-readable JSON (cohort.json) on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs one case of a batch in this process, as `batch` starts it: the job on stdin, its
/// events and status on stdout (`pipeline::case_process`). Not for users.
#[derive(Debug, Args)]
pub struct CaseArgs {}

/// The name of the hidden command a batch's case processes run.
pub const CASE_COMMAND: &str = "__case";

/// Merge the results of a batch's shards into OUT/cohort.json and the cohort report.
#[derive(Debug, Args)]
pub struct CohortReportArgs {
    /// The --out folder of the batch.
    pub out: PathBuf,
    /// Print machine-readable JSON (cohort.json) on stdout.
    #[arg(long)]
    pub json: bool,
}

fn absolute(path: &Path) -> Result<PathBuf, Error> {
    std::path::absolute(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

pub fn run(
    args: &BatchArgs,
    config_path: Option<&Path>,
    progress: &dyn Reporter,
) -> Result<Report, Error> {
    let config = Config::load(config_path)?;
    check_out_dir(&args.out)?;
    let cohort = read_cohort(&args.cohort)?;
    for skip in &cohort.skipped {
        progress.log(&format!(
            "not a case: {}/{}: {}",
            args.cohort.display(),
            skip.name,
            skip.reason
        ));
    }
    let cases = cohort.cases;
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if let Some(script_path) = &args.emit_sbatch {
        let out = absolute(&args.out)?;
        let logs = out.join("slurm");
        std::fs::create_dir_all(&logs).map_err(|source| Error::Io {
            path: logs.clone(),
            source,
        })?;
        let exe = std::env::current_exe().map_err(|source| Error::Io {
            path: "otoatlas".into(),
            source,
        })?;
        let tasks = args.shards.unwrap_or(cases.len()).clamp(1, cases.len());
        let config_abs = config_path.map(absolute).transpose()?;
        let atlas_abs = args.atlas.as_deref().map(absolute).transpose()?;
        let script = sbatch_script(&SbatchSpec {
            exe: &exe,
            cohort: &absolute(&args.cohort)?,
            out: &out,
            tasks,
            jobs,
            config: config_abs.as_deref(),
            atlas: atlas_abs.as_deref(),
            keep_phi: args.keep_phi,
            case_memory_limit_mib: args.case_memory_limit,
            condition: args.condition,
        });
        crate::io_util::write_atomic(script_path, script.as_bytes())?;
        return Ok(Report {
            text: format!(
                "wrote {} ({tasks} array tasks over {} cases); submit it with sbatch, then run \
                 `otoatlas cohort-report {}`\n",
                script_path.display(),
                cases.len(),
                out.display()
            ),
            json: serde_json::json!({ "script": script_path.display().to_string(), "tasks": tasks, "cases": cases.len() }),
        });
    }
    let shard = match &args.shard {
        Some(text) => Some(Shard::parse(text)?),
        None => Shard::from_slurm(),
    };
    let ids: Vec<String> = cases.iter().map(|c| c.id.clone()).collect();
    write_case_list(&args.out, &ids, &cohort.skipped)?;
    let selected = match shard {
        Some(s) => s.select(cases),
        None => cases,
    };
    // every case in a child process of this executable: whatever ends it ends only that case
    let program = std::env::current_exe().map_err(|source| Error::Io {
        path: "otoatlas".into(),
        source,
    })?;
    let opts = BatchOptions {
        out: args.out.clone(),
        jobs,
        resume: args.resume,
        atlas: args.atlas.clone(),
        keep_phi: args.keep_phi,
        condition: args.condition,
        child: Some(CaseProcess {
            program,
            args: vec![CASE_COMMAND.into()],
            memory_limit_mib: args.case_memory_limit,
        }),
    };
    let statuses = run_batch(&selected, &opts, &config, progress)?;
    let failed: Vec<_> = statuses
        .iter()
        .filter(|s| s.outcome == Outcome::Failed)
        .collect();
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{} cases: {} ran, {} resumed, {} failed",
        statuses.len(),
        statuses.iter().filter(|s| s.outcome == Outcome::Ok).count(),
        statuses
            .iter()
            .filter(|s| s.outcome == Outcome::Resumed)
            .count(),
        failed.len()
    );
    for s in &failed {
        let _ = writeln!(text, "  {}: {}", s.id, s.error.as_deref().unwrap_or("?"));
    }
    if !cohort.skipped.is_empty() {
        let _ = writeln!(
            text,
            "{} entries of {} are not cases:",
            cohort.skipped.len(),
            args.cohort.display()
        );
        for skip in &cohort.skipped {
            let _ = writeln!(text, "  {}: {}", skip.name, skip.reason);
        }
    }
    let json = match shard {
        // a shard reports its own cases; `cohort-report` merges them all
        Some(s) => {
            let _ = writeln!(
                text,
                "shard {}/{} done; merge with `otoatlas cohort-report {}` when every shard is",
                s.index,
                s.count,
                args.out.display()
            );
            serde_json::json!({ "shard": [s.index, s.count], "cases": statuses, "passed": failed.is_empty() })
        }
        None => {
            let summary = merge_cohort(&args.out)?;
            let _ = writeln!(
                text,
                "wrote {}/cohort.{{json,html,csv}}",
                args.out.display()
            );
            summary
        }
    };
    Ok(Report { text, json })
}

/// The hidden command: serves one job; exit 0 when it reported the case's status (whatever
/// the case's outcome), 1 otherwise.
pub fn case(_args: &CaseArgs) -> std::process::ExitCode {
    if serve(std::io::stdin().lock(), std::io::stdout()) {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::from(super::exit::ExitStatus::CaseFailed as u8)
    }
}

pub fn cohort_report(args: &CohortReportArgs) -> Result<Report, Error> {
    let summary = merge_cohort(&args.out)?;
    let counts = &summary["counts"];
    let text = format!(
        "{} cases: {} ok, {} failed, {} missing; wrote {}/cohort.{{json,html,csv}}\n",
        counts["cases"],
        counts["ok"],
        counts["failed"],
        counts["missing"],
        args.out.display()
    );
    Ok(Report {
        text,
        json: summary,
    })
}
