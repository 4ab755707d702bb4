#!/usr/bin/env bash
# The whole test suite on a fresh machine (with Rust installed): installs what the tests need
# (Debian and Python packages, public test corpora), checks formatting, lints and rustdoc, runs
# every test, then the Slurm test (scripts/slurm-test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
# each step's start, in seconds since this script began (where CI time goes)
step() { echo "== $1 (${SECONDS} s)"; }
step "system and Python packages"
ensure_build_deps
ensure_apt python3 python3
ensure_apt dcmdjpeg dcmtk
ensure_apt dciodvfy dicom3tools
ensure_apt chromium chromium
ensure_apt slurmctld slurm-wlm
ensure_apt munged munge
python3 -m pip --version >/dev/null 2>&1 || ensure_apt pip python3-pip
python3 -m pip install --quiet --disable-pip-version-check -r scripts/requirements-test.txt
step "test corpora"
bash scripts/fetch-testdata.sh
step "format, lints, rustdoc"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked
step "tests"
# every test, the heavy ones (#[ignore = "heavy: ..."], which a plain `cargo test` leaves out) too;
# an absent input (the test anatomy, .testdata, python packages, chromium) is a failure, not a
# skip; the test anatomy is read from $OTOATLAS_SHARED_DIR, by default the shared folder beside
# the checkout
export OTOATLAS_SHARED_DIR="${OTOATLAS_SHARED_DIR:-$(cd .. && pwd)/shared}"
OTOATLAS_REQUIRE_SHARED=1 OTOATLAS_REQUIRE_TESTDATA=1 OTOATLAS_REQUIRE_PYTHON=1 OTOATLAS_REQUIRE_BROWSER=1 cargo test --workspace --locked -- --include-ignored
step "Slurm"
# the Slurm job array on a one-node cluster started here (needs root for the daemons)
as_root bash scripts/slurm-test.sh "$PWD/target/debug/otoatlas"
step "done"
