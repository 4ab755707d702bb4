//! The `--out` arguments, checked before any work: `run` and `batch` write into a folder (new,
//! or an earlier run's), `landmarks` writes a file. A path of the wrong kind, or where nothing
//! can be written, is bad usage (exit 2) found at once, not a failure after minutes of work.

use std::path::Path;

use crate::Error;

/// `--out DIR`: a folder that exists or can be made, and can be written in.
pub fn check_out_dir(out: &Path) -> Result<(), Error> {
    if out.exists() && !out.is_dir() {
        return Err(Error::Usage(format!(
            "--out {}: this is a file; expected an output folder (new, or a previous run's)",
            out.display()
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| unwritable(out, "a folder", e))?;
    probe(out, out, "a folder")
}

/// `--out FILE`: not a folder, in a folder that exists and can be written in.
pub fn check_out_file(out: &Path) -> Result<(), Error> {
    if out.is_dir() {
        return Err(Error::Usage(format!(
            "--out {}: this is a folder; expected a file to write",
            out.display()
        )));
    }
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(Error::Usage(format!(
            "--out {}: {} is not a folder; expected a file in an existing folder",
            out.display(),
            parent.display()
        )));
    }
    probe(out, parent, "a file in a folder")
}

/// Writes and removes an empty file in `folder`.
fn probe(out: &Path, folder: &Path, expected: &str) -> Result<(), Error> {
    let probe = folder.join(format!(".otoatlas-write-test.{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| unwritable(out, expected, e))?;
    std::fs::remove_file(&probe).map_err(|e| unwritable(out, expected, e))
}

fn unwritable(out: &Path, expected: &str, e: std::io::Error) -> Error {
    Error::Usage(format!(
        "--out {}: cannot write there ({e}); expected {expected} you can write in",
        out.display()
    ))
}
