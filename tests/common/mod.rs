//! Helpers shared by the integration tests: the inputs from outside the repository and the one
//! rule when one is absent (`external`), running the `otoatlas` binary and the Python checkers
//! (`python`, `trimesh_io`), and structured meshes (`meshes`).
#![allow(dead_code)]

pub mod external;
pub mod meshes;
pub mod python;
pub mod trimesh_io;
#[allow(unused_imports)]
pub use external::{chromium, program, shared_anatomy, testdata};
#[allow(unused_imports)]
pub use meshes::*;

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

/// The crate root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Copies the folder `from` into `to` (made if absent), recursively.
pub fn copy_dir(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// The arguments of `otoatlas atlas import` for SOFA's chain (`anatomy` from
/// [`shared_anatomy`]) with the repository's region mapping and landmarks, into `out`.
pub fn sofa_import_args(anatomy: &std::path::Path, out: &std::path::Path) -> Vec<String> {
    let sofa = anatomy.join("sofa-ossicles");
    let fixtures = root().join("tests/atlas_cli");
    let path = |p: PathBuf| p.to_string_lossy().into_owned();
    vec![
        "atlas".into(),
        "import".into(),
        "--mesh".into(),
        path(sofa.join("Ossicles.vtu")),
        "--labels".into(),
        path(sofa.join("Ossicles_tet_labels.txt")),
        "--mapping".into(),
        path(fixtures.join("sofa-ossicles.mapping.toml")),
        "--landmarks".into(),
        path(fixtures.join("sofa-ossicles.landmarks.json")),
        "--name".into(),
        "sofa".into(),
        "--out".into(),
        path(out.to_path_buf()),
    ]
}

/// Writes the repository's `pipeline.toml` with `[validate] enabled = false` (no package
/// mechanics: faster runs for tests about other stages) as `dir/pipeline.toml`; returns it.
pub fn config_without_validation(dir: &std::path::Path) -> PathBuf {
    let default = std::fs::read_to_string(root().join("pipeline.toml")).expect("pipeline.toml");
    let at = default.find("\n[validate]").expect("a [validate] section");
    let (head, tail) = default.split_at(at);
    let off = format!(
        "{head}{}",
        tail.replacen("\nenabled = true", "\nenabled = false", 1)
    );
    assert_ne!(off, default, "[validate] enabled = true not found");
    let path = dir.join("pipeline.toml");
    std::fs::write(&path, off).expect("write the test configuration");
    path
}

/// Runs the otoatlas binary with `args`, writing `stdin` to its standard input.
pub fn otoatlas_with_stdin<S: AsRef<std::ffi::OsStr>>(args: &[S], stdin: &[u8]) -> Output {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_otoatlas"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("otoatlas starts");
    child
        .stdin
        .take()
        .expect("a stdin pipe")
        .write_all(stdin)
        .expect("write the answers");
    child.wait_with_output().expect("otoatlas runs")
}

/// Runs the otoatlas binary with `args`.
pub fn otoatlas(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_otoatlas"))
        .args(args)
        .output()
        .expect("run otoatlas")
}

/// Runs `otoatlas ARGS --json` and parses stdout.
pub fn otoatlas_json(args: &[&str]) -> (i32, serde_json::Value) {
    let mut all: Vec<&str> = args.to_vec();
    all.push("--json");
    all.push("--quiet");
    let out = otoatlas(&all);
    let code = out.status.code().unwrap_or(-1);
    let v = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}): {}\nstderr: {}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (code, v)
}

/// Asserts two float slices agree within `tol`.
pub fn assert_close(actual: &[f64], expected: &[f64], tol: f64, what: &str) {
    assert_eq!(actual.len(), expected.len(), "{what}: length");
    for (a, e) in actual.iter().zip(expected) {
        assert!((a - e).abs() <= tol, "{what}: {actual:?} vs {expected:?}");
    }
}
