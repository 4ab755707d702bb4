#!/usr/bin/env bash
# Regenerates sample_cases/ (three synthetic CBCT cases with ground truth, committed): the
# same command always gives byte-identical files, so `git status` stays clean after a run.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
ensure_build_deps
rm -rf sample_cases
cargo run --release --locked --bin otoatlas -- phantom --out sample_cases --cases 3 --seed 2026
du -sh sample_cases
