//! Running the independent Python checkers of `tests/python/`: skip cleanly (say why, return
//! `None`) when python3 or a needed package is missing, unless `OTOATLAS_REQUIRE_PYTHON=1`
//! (CI), which makes that a failure. Only std, so the benchmarks can include it via `#[path]`.

use std::ffi::OsStr;
use std::path::Path;
use std::process::Command;

/// Runs `python3 tests/python/SCRIPT ARGS` when python3 imports every one of `packages`, and
/// returns its stdout; a failing script fails the caller. `None` when skipped (see above).
pub fn run_python<A: AsRef<OsStr>>(script: &str, args: &[A], packages: &[&str]) -> Option<String> {
    let probe = Command::new("python3")
        .args(["-c", &format!("import {}", packages.join(", "))])
        .output();
    let why = match probe {
        Ok(o) if o.status.success() => None,
        Ok(o) => Some(format!(
            "python3 lacks {}: {}",
            packages.join("/"),
            String::from_utf8_lossy(&o.stderr).trim()
        )),
        Err(e) => Some(format!("python3 cannot be run ({e})")),
    };
    if let Some(why) = why {
        if std::env::var("OTOATLAS_REQUIRE_PYTHON").as_deref() == Ok("1") {
            panic!(
                "OTOATLAS_REQUIRE_PYTHON=1 but {why} (pip install {})",
                packages.join(" ")
            );
        }
        eprintln!("skipped {script}: {why}");
        return None;
    }
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
