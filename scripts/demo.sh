#!/usr/bin/env bash
# The main job on the embedded default, from a fresh clone (with Rust installed): the embedded
# atlas registered onto the first sample case (a synthetic CBCT with its manual segmentation),
# writing the patient model, package, report, metrics and timings to out/demo/case-001, then
# verifying the package.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
ensure_build_deps
cargo build --release --locked --bin otoatlas
./target/release/otoatlas run sample_cases/case-001 --out out/demo/case-001
./target/release/otoatlas verify out/demo/case-001/package
echo "open out/demo/case-001/report.html in a browser"
