//! Integration tests of the model and the numerics under it, in-process: the parametric
//! anatomy and the default atlas, FEM, mechanics, surface distances and the deformable stage.
//!
//! The integration tests are two binaries, ripgrep's layout (`autotests = false` in
//! Cargo.toml): this one and `tests/pipeline.rs` (the `otoatlas` binary on files), each a list
//! of modules, one file beside it per module. A new test file is a module added to one of
//! the two lists. Tests that take long are `#[ignore = "heavy: ..."]`: a plain
//! `cargo test` leaves them out (and lists them as ignored), `bash scripts/test.sh` (CI) runs
//! them with `--include-ignored`.

mod common;

mod architecture;
mod atlas_anatomy;
mod atlas_joints;
mod deform_synthetic;
mod fem_analytic;
mod fem_assembly;
mod fem_membrane;
mod fem_solvers;
mod mechanics_analytic;
mod mechanics_atlas;
mod meshdev_analytic;
mod meshdev_trimesh;

/// With `autotests = false` a file in tests/ that neither binary names would never be compiled
/// or run: every `tests/*.rs` is one of the two binaries or a module of exactly one.
#[test]
fn every_test_file_is_a_module_of_one_binary() {
    let tests = common::root().join("tests");
    let roots = ["model", "pipeline"];
    let declared: Vec<Vec<String>> = roots
        .iter()
        .map(|root| {
            std::fs::read_to_string(tests.join(format!("{root}.rs")))
                .unwrap()
                .lines()
                .filter_map(|l| l.strip_prefix("mod ")?.strip_suffix(';'))
                .map(String::from)
                .collect()
        })
        .collect();
    let mut files: Vec<String> = std::fs::read_dir(&tests)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .filter(|stem| !roots.contains(&stem.as_str()))
        .collect();
    files.sort();
    assert!(files.len() >= 20, "{files:?}");
    for file in &files {
        let holders = declared.iter().filter(|mods| mods.contains(file)).count();
        assert_eq!(
            holders, 1,
            "tests/{file}.rs is a module of {holders} test binaries"
        );
    }
}
