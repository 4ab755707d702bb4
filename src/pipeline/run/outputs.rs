//! The run's output folder: what an earlier run left there, which a new run replaces, and
//! the check that a folder given as `--out` is a run's before anything in it is removed.

use std::path::{Path, PathBuf};

use crate::Error;
use crate::export::package::PACKAGE_DIR;
use crate::pipeline::stage::{Stage, artefact_path};

/// The outputs a run writes after its stages (registered/, metrics, report, timings,
/// mechanics, the package and its log), removed as soon as the image is read (and, resumed,
/// found to be the earlier run's): a re-run that fails half-way never leaves an earlier
/// run's package or report beside its own stages, and a resumed run refused for another side
/// or another image leaves them as they were. The stages' artefacts stay (`--from` reads
/// them).
pub(super) fn remove_previous_outputs(out: &Path) -> Result<(), Error> {
    for (path, metadata) in previous_outputs(out) {
        let removed = match metadata.is_dir() {
            true => std::fs::remove_dir_all(&path),
            false => std::fs::remove_file(&path),
        };
        removed.map_err(crate::io_util::io_err(&path))?;
    }
    Ok(())
}

/// The outputs of an earlier run present in `out` (`remove_previous_outputs`).
fn previous_outputs(out: &Path) -> Vec<(PathBuf, std::fs::Metadata)> {
    [
        PACKAGE_DIR,
        "package.log.json",
        "registered",
        "metrics.json",
        "report.html",
        "timings.json",
        "mechanics.json",
    ]
    .iter()
    .map(|name| out.join(name))
    .filter_map(|path| std::fs::symlink_metadata(&path).ok().map(|m| (path, m)))
    .collect()
}

/// Refuses an `out` that holds what a run would replace (`previous_outputs`) but is not an
/// earlier run's output folder (it has no `stages/ingest.json`, the first thing a run
/// writes): a report, a `registered/` folder or a package of the user's own, in a folder
/// given as `--out` by mistake, is never removed.
pub(super) fn check_out_is_a_run(out: &Path) -> Result<(), Error> {
    let found = previous_outputs(out);
    if found.is_empty() || artefact_path(out, Stage::Ingest).is_file() {
        return Ok(());
    }
    let names: Vec<String> = found
        .iter()
        .filter_map(|(path, _)| path.file_name())
        .map(|name| name.to_string_lossy().into_owned())
        .collect();
    Err(Error::Usage(format!(
        "--out {}: holds {} but no stages/ingest.json, so it is not an earlier run's output, and a run would replace them; expected a new or empty folder, or a previous run's",
        out.display(),
        names.join(", ")
    )))
}
