//! Running the independent Python checkers of `tests/python/`, when python3 imports the
//! packages a checker needs (`external::python`: otherwise the test fails under
//! `OTOATLAS_REQUIRE_PYTHON=1`, or is skipped, saying why). Only std, so the examples can
//! include it via `#[path]`; users declare the sibling module `external` next to this one.

use std::ffi::OsStr;
use std::path::Path;
use std::process::Command;

/// Runs `python3 tests/python/SCRIPT ARGS` when python3 imports every one of `packages`, and
/// returns its stdout; a failing script fails the caller. `None` when skipped (see above).
pub fn run_python<A: AsRef<OsStr>>(script: &str, args: &[A], packages: &[&str]) -> Option<String> {
    super::external::python(packages)?;
    let out = Command::new("python3")
        .arg(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/python")
                .join(script),
        )
        .args(args)
        .output()
        .expect("run python3");
    assert!(
        out.status.success(),
        "{script} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}
