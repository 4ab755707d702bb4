#!/usr/bin/env bash
# The main job on the embedded default, from a fresh clone (with Rust installed).
# Until registration lands this runs the furthest stage that exists: it writes a synthetic
# CT series with the project's own DICOM writer and ingests it with `otoatlas inspect`.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
ensure_build_deps
cargo build --release --locked --bin otoatlas --example synthetic_series
./target/release/examples/synthetic_series out/demo/dicom 256 256 120 0.2
./target/release/otoatlas inspect out/demo/dicom
