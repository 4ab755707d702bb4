# Shared set-up steps for scripts/demo.sh and scripts/test.sh (sourced, not run).
# Installs what a fresh machine lacks: Debian packages and Python packages.

set -euo pipefail

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
        echo "need root to run: $*" >&2; return 1; fi
}

apt_updated=0
# ensure_apt COMMAND PACKAGE: installs PACKAGE with apt-get when COMMAND is missing.
ensure_apt() {
    local cmd=$1 pkg=$2
    command -v "$cmd" >/dev/null 2>&1 && return 0
    if [ "$apt_updated" -eq 0 ]; then as_root apt-get update -qq; apt_updated=1; fi
    echo "installing $pkg (for $cmd)" >&2
    DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -qq "$pkg" >/dev/null
}

# Build dependencies of the product: cmake builds CharLS (JPEG-LS decoding).
ensure_build_deps() {
    command -v cargo >/dev/null || { echo "Rust (cargo) is required: https://rustup.rs" >&2; exit 2; }
    ensure_apt cmake cmake
    ensure_apt g++ g++
}
