//! `batch`: a cohort of cases through `run`, in parallel, each into `DIR/cases/ID/`.
//!
//! A failing case does not stop the others: its error is recorded in its `status.json` and in
//! the cohort report. With [`BatchOptions::child`] (as the command line runs it) each case runs
//! in a child process (`case_process`), so that even an abort, a segmentation fault or an
//! out-of-memory kill is only that case's failure, named by its signal; `jobs` children run at
//! once and share the `jobs` threads. In-process, cases run on a pool of `jobs` threads shared
//! with the parallel loops inside a case (probing, assembly, distances), and a panic is the
//! case's failure. Either way the machine is never oversubscribed. `--resume` skips the cases
//! whose package is already there, verifies, and was made from the same inputs, configuration
//! and atlas (by SHA-256).

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::case_process::{CaseProcess, run_here, run_in_child};
pub use super::case_process::{CaseStatus, Outcome};
use super::{AutoLandmarks, Case, RunOptions, Stage};
use crate::Error;
use crate::config::Config;
use crate::export::package::PACKAGE_DIR;
use crate::export::{atlas_sha256, verify_package};
use crate::image::dicom::series_selects;
use crate::io_util::write_json_file;
use crate::mechanics::Condition;
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
    /// The ear's condition every package models (`run --condition`).
    pub condition: Condition,
    /// Run each case in a child process started so; none: in this process.
    pub child: Option<CaseProcess>,
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
    // children share the threads: as many at once as there are cases or threads, each with
    // its share of the threads
    let jobs = opts.jobs.max(1);
    let at_once = jobs.min(cases.len().max(1));
    let child_threads = (jobs / at_once).max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(if opts.child.is_some() { at_once } else { jobs })
        .build()
        .map_err(|e| Error::Usage(format!("--jobs {}: {e}", opts.jobs)))?;
    progress.cohort_started(cases.len() as u64);
    let statuses = pool.install(|| {
        cases
            .par_iter()
            .map(|case| {
                let status = run_one(case, opts, config, child_threads, progress);
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
    child_threads: usize,
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
    let run_opts = RunOptions {
        out,
        from: Stage::Ingest,
        landmarks: None,
        atlas: opts.atlas.clone(),
        side: None,
        keep_phi: opts.keep_phi,
        // a case without a landmark file has them proposed from its image
        auto_landmarks: AutoLandmarks::WhenMissing,
        condition: opts.condition,
    };
    let status = match &opts.child {
        Some(process) => run_in_child(process, case, &run_opts, config, child_threads, progress),
        None => run_here(case, &run_opts, config, progress),
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
/// file hashed, meshes and scene consistent) and its manifest names these inputs (the series
/// asked for, where the case names one), this configuration and this atlas under this
/// condition (by SHA-256), and holds no patient identity unless asked to.
/// A package is written last and atomically, so one that verifies means the run finished.
fn is_complete(case: &Case, out: &Path, opts: &BatchOptions, config: &Config) -> bool {
    let Ok(report) = verify_package(&out.join(PACKAGE_DIR)) else {
        return false;
    };
    let Some(manifest) = report.manifest.as_ref().filter(|_| report.passed()) else {
        return false;
    };
    let same_inputs = case
        .image_digests()
        .and_then(|image| case.inputs_sha256(&image, None))
        .is_ok_and(|digest| digest == manifest.inputs_sha256);
    let same_atlas = || {
        crate::atlas::load_atlas(opts.atlas.as_deref(), Some(manifest.side))
            .ok()
            .and_then(|atlas| opts.condition.apply(&atlas).ok())
            .and_then(|atlas| atlas_sha256(&atlas).ok())
            .is_some_and(|digest| digest == manifest.atlas.sha256)
    };
    // the inputs' digest covers the image folder's files, whichever series was read
    let same_series = case.series.as_deref().is_none_or(|wanted| {
        manifest
            .series_uid_sha256
            .as_deref()
            .is_some_and(|read| series_selects(wanted, read))
    });
    same_inputs
        && same_series
        && manifest.config_sha256 == config.sha256()
        && (opts.keep_phi || manifest.patient.is_none())
        && same_atlas()
}
