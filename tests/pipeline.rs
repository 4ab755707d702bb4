//! Integration tests of the pipeline on files, mostly through the `otoatlas` binary: ingest
//! (test corpora and synthetic series), landmark files and checks, phantoms, registration
//! accuracy, packages and their mechanics, batch runs, the atlas commands and the report in a
//! browser.
//!
//! The integration tests are two binaries, ripgrep's layout (`autotests = false` in
//! Cargo.toml): this one and `tests/model.rs` (the model and its numerics, in-process), each a
//! list of modules, one file beside it per module. A new test file is a module added to one of
//! the two lists. Tests that take long are `#[ignore = "heavy: ..."]`: a plain
//! `cargo test` leaves them out (and lists them as ignored), `bash scripts/test.sh` (CI) runs
//! them with `--include-ignored`.

mod common;

mod atlas_cli;
mod auto_landmarks;
mod batch;
mod ingest_corpus;
mod ingest_synthetic;
mod landmark_checks;
mod landmark_files;
mod mechanics_cli;
mod mechanics_packages;
mod memory_limit;
mod package;
mod phantom_cases;
mod registration_accuracy;
mod registration_real_anatomy;
mod report_browser;
mod robustness;
