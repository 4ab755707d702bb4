//! The cohort's results merged from its case folders: `DIR/cohort.json` (every case's outcome,
//! error and time), the cohort report `DIR/cohort.html` and every metric in `DIR/cohort.csv`.
//! `batch` writes them at the end of an unsharded run; `cohort-report DIR` writes them after
//! the shards of a job array have all finished.

use std::path::Path;

use serde_json::{Value, json};

use super::batch::{Outcome, case_dir, read_status};
use super::cohort::Skipped;
use crate::Error;
use crate::io_util::{write_atomic, write_json_file};
use crate::report::metrics::CaseMetrics;
use crate::report::{CohortEntry, cohort_report};

/// The list of the cohort's case ids that `batch` leaves in its output folder, so that the
/// merge knows which cases are missing.
const CASE_LIST: &str = "cohort-cases.json";

/// Records the cohort's case ids in `out` (the same file from every shard).
pub fn write_case_list(out: &Path, ids: &[String], skipped: &[Skipped]) -> Result<(), Error> {
    let list = json!({ "cases": ids, "skipped": skipped });
    Ok(write_json_file(&out.join(CASE_LIST), &list)?)
}

fn read_case_list(out: &Path) -> Result<(Vec<String>, Vec<Skipped>), Error> {
    let path = out.join(CASE_LIST);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Error::Usage(format!(
            "{}: cannot read the cohort's case list ({e}); is {} the --out of a batch?",
            path.display(),
            out.display()
        ))
    })?;
    let value: Value = serde_json::from_str(&text)
        .map_err(|e| Error::Usage(format!("{}: not a case list: {e}", path.display())))?;
    let ids = value["cases"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    let skipped = serde_json::from_value(value["skipped"].clone()).unwrap_or_default();
    Ok((ids, skipped))
}

/// A case's `metrics.json`: `None` when absent, an error naming the file when it is not one
/// `run` writes.
fn read_metrics(path: &Path) -> Result<Option<CaseMetrics>, String> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Ok(None);
    };
    serde_json::from_str(&text).map(Some).map_err(|e| {
        format!(
            "{}: not a metrics.json that run writes: {e}",
            path.display()
        )
    })
}

/// Merges the case folders of the batch output `out` into `out/cohort.json` (returned),
/// `out/cohort.html` and `out/cohort.csv`.
/// `"passed"` is false when a case failed or has not run.
pub fn merge_cohort(out: &Path) -> Result<Value, Error> {
    let (ids, skipped) = read_case_list(out)?;
    let mut cases = Vec::new();
    let mut entries = Vec::new();
    let (mut ok, mut failed, mut missing) = (0usize, 0usize, 0usize);
    for id in &ids {
        let dir = case_dir(out, id);
        let status = read_status(out, id);
        let metrics_path = dir.join("metrics.json");
        let (metrics, unreadable) = match status.as_ref().map(|s| s.outcome) {
            Some(Outcome::Ok | Outcome::Resumed) => match read_metrics(&metrics_path) {
                Ok(metrics) => (metrics, None),
                Err(why) => (None, Some(why)),
            },
            _ => (None, None),
        };
        entries.push(CohortEntry {
            case: id.clone(),
            metrics,
            report_link: format!("cases/{id}/report.html"),
            error: match &status {
                Some(s) => s.error.clone().or(unreadable),
                None => Some("not run: no shard has reached this case".into()),
            },
        });
        let entry = match status {
            Some(s) => {
                match s.outcome {
                    Outcome::Failed => failed += 1,
                    Outcome::Ok | Outcome::Resumed => ok += 1,
                }
                let relative = |name: &str| format!("cases/{id}/{name}");
                json!({
                    "id": id,
                    "outcome": s.outcome,
                    "error": s.error,
                    "seconds": s.seconds,
                    "report": dir.join("report.html").is_file().then(|| relative("report.html")),
                    "metrics": metrics_path.is_file().then(|| relative("metrics.json")),
                })
            }
            None => {
                missing += 1;
                json!({ "id": id, "outcome": "missing" })
            }
        };
        cases.push(entry);
    }
    let summary = json!({
        "format": "otoatlas-cohort",
        "version": 1,
        "counts": { "cases": ids.len(), "ok": ok, "failed": failed, "missing": missing },
        "passed": failed == 0 && missing == 0,
        "cases": cases,
        "skipped": skipped,
    });
    let report_path = out.join("cohort.html");
    let report = cohort_report(&entries).map_err(|source| Error::Report {
        path: report_path.clone(),
        source,
    })?;
    write_atomic(&report_path, report.html.as_bytes())?;
    write_atomic(&out.join("cohort.csv"), report.csv.as_bytes())?;
    write_json_file(&out.join("cohort.json"), &summary)?;
    Ok(summary)
}
