//! `batch`: a cohort of cases through `run`, in parallel, each into `DIR/cases/ID/`.
//!
//! A failing case (an error or a panic) does not stop the others: its error is recorded in
//! its `status.json` and in the cohort report. Cases run on a pool of `jobs` threads and the
//! parallel loops inside a case (probing, assembly, distances) run on the same pool, so the
//! machine is never oversubscribed. `--resume` skips the cases whose package is already there,
//! verifies, and was made from the same inputs, configuration and atlas (by SHA-256).

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Case, RunOptions, Stage, run_case};
use crate::Error;
use crate::config::Config;
use crate::export::package::PACKAGE_DIR;
use crate::export::{atlas_sha256, verify_package};
use crate::io_util::write_json_file;
use crate::progress::Reporter;

/// What `batch` is asked to do besides the cases and the configuration.
#[derive(Debug, Clone)]
pub struct BatchOptions {
    pub out: PathBuf,
    /// Cases run at once (and threads in all).
    pub jobs: usize,
    pub resume: bool,
    /// An atlas folder instead of the embedded default.
    pub atlas: Option<PathBuf>,
    /// Keep the DICOM patient fields in the packages (`run --keep-phi`).
    pub keep_phi: bool,
}

/// How one case of the cohort ended, as `DIR/cases/ID/status.json` records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseStatus {
    pub id: String,
    pub outcome: Outcome,
    /// The error of a failed case.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Wall time of the run \[s\] (0 for a case skipped by `--resume`).
    pub seconds: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    Ok,
    Failed,
    /// Skipped by `--resume`: the case's outputs were already complete and current.
    Resumed,
}

/// The folder of case `id` in the batch output `out`.
pub fn case_dir(out: &Path, id: &str) -> PathBuf {
    out.join("cases").join(id)
}

/// The status file of case `id`.
pub fn status_path(out: &Path, id: &str) -> PathBuf {
    case_dir(out, id).join("status.json")
}

/// Runs `cases` (already the shard's slice) and returns each one's status, in cohort order.
pub fn run_batch(
    cases: &[Case],
    opts: &BatchOptions,
    config: &Config,
    progress: &dyn Reporter,
) -> Result<Vec<CaseStatus>, Error> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.jobs.max(1))
        .build()
        .map_err(|e| Error::Usage(format!("--jobs {}: {e}", opts.jobs)))?;
    progress.cohort_started(cases.len() as u64);
    let statuses = pool.install(|| {
        cases
            .par_iter()
            .map(|case| {
                let status = run_one(case, opts, config, progress);
                let outcome = match (&status.outcome, &status.error) {
                    (Outcome::Failed, Some(e)) => format!("FAILED: {e}"),
                    (Outcome::Resumed, _) => "complete already, skipped (--resume)".into(),
                    _ => format!("done in {:.1} s", status.seconds),
                };
                progress.case_finished(&case.id, &outcome);
                status
            })
            .collect::<Vec<_>>()
    });
    progress.cohort_finished();
    Ok(statuses)
}

fn run_one(
    case: &Case,
    opts: &BatchOptions,
    config: &Config,
    progress: &dyn Reporter,
) -> CaseStatus {
    let out = case_dir(&opts.out, &case.id);
    if opts.resume && is_complete(case, &out, opts, config) {
        // a package that verifies is the case's success, whatever an interrupted run left
        let previous = read_status(&opts.out, &case.id);
        if previous
            .as_ref()
            .is_none_or(|s| s.outcome == Outcome::Failed)
        {
            let recovered = CaseStatus {
                id: case.id.clone(),
                outcome: Outcome::Ok,
                error: None,
                seconds: 0.0,
            };
            if let Err(e) = write_status(&opts.out, &recovered) {
                progress.log(&format!("{}: cannot record its status: {e}", case.id));
            }
        }
        return CaseStatus {
            id: case.id.clone(),
            outcome: Outcome::Resumed,
            error: None,
            seconds: 0.0,
        };
    }
    progress.case_started(&case.id);
    let started = Instant::now();
    let run_opts = RunOptions {
        out: out.clone(),
        from: Stage::Ingest,
        landmarks: None,
        atlas: opts.atlas.clone(),
        side: None,
        keep_phi: opts.keep_phi,
    };
    // a panic in one case is that case's failure, never the cohort's
    let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
        run_case(case, &run_opts, config, progress)
    }));
    let error = match result {
        Ok(Ok(_)) => None,
        Ok(Err(e)) => Some(e.to_string()),
        Err(panic) => Some(format!(
            "internal error (please report): {}",
            panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("panic")
        )),
    };
    let status = CaseStatus {
        id: case.id.clone(),
        outcome: if error.is_some() {
            Outcome::Failed
        } else {
            Outcome::Ok
        },
        error,
        seconds: started.elapsed().as_secs_f64(),
    };
    if let Err(e) = write_status(&opts.out, &status) {
        progress.log(&format!("{}: cannot record its status: {e}", case.id));
    }
    status
}

fn write_status(out: &Path, status: &CaseStatus) -> Result<(), Error> {
    Ok(write_json_file(&status_path(out, &status.id), status)?)
}

/// Reads the status of case `id`, if it has one.
pub fn read_status(out: &Path, id: &str) -> Option<CaseStatus> {
    let text = std::fs::read_to_string(status_path(out, id)).ok()?;
    serde_json::from_str(&text).ok()
}

/// Whether the case's outputs in `out` are complete and current: its package verifies (every
/// file hashed, meshes and scene consistent) and its manifest names these inputs, this
/// configuration and this atlas (by SHA-256), and holds no patient identity unless asked to.
/// A package is written last and atomically, so one that verifies means the run finished.
fn is_complete(case: &Case, out: &Path, opts: &BatchOptions, config: &Config) -> bool {
    let Ok(report) = verify_package(&out.join(PACKAGE_DIR)) else {
        return false;
    };
    let Some(manifest) = report.manifest.as_ref().filter(|_| report.passed()) else {
        return false;
    };
    let same_inputs = case
        .inputs_sha256(None)
        .is_ok_and(|digest| digest == manifest.inputs_sha256);
    let same_atlas = || {
        crate::atlas::load_atlas(opts.atlas.as_deref(), Some(manifest.side))
            .ok()
            .and_then(|atlas| atlas_sha256(&atlas).ok())
            .is_some_and(|digest| digest == manifest.atlas.sha256)
    };
    same_inputs
        && manifest.config_sha256 == config.sha256()
        && (opts.keep_phi || manifest.patient.is_none())
        && same_atlas()
}
