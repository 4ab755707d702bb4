//! Which variant of faer's sparse factorisations (Cholesky, LBLᵀ and LU) the FEM uses: supernodal,
//! or simplicial when the process has an address-space limit.
//!
//! faer's supernodal factorisations multiply dense blocks through `private-gemm-x86`, which
//! reserves on every thread that calls it a packing buffer of twice the L3 size it computes
//! for the machine (the per-CPU share of the L3 times the physical cores: 960 MiB per thread
//! where that comes to 480 MiB), as address space and whatever the problem's size. Under an
//! address-space limit (`ulimit -v`, common on shared clusters) that reservation fails and
//! aborts the process, although a case's resident memory is a few hundred MB. The simplicial
//! factorisations are sparse code only and never call it, but are several times slower, so
//! they are used only when the limit is there (`RLIMIT_AS` at the first factorisation). The
//! two variants agree to rounding, not to the last bit.

use std::sync::LazyLock;

use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::CholeskySymbolicParams;
use faer::sparse::linalg::lu::LuSymbolicParams;

/// The supernodal threshold for this process: simplicial under an address-space limit, faer's
/// automatic choice otherwise.
static THRESHOLD: LazyLock<SupernodalThreshold> = LazyLock::new(|| {
    if address_space_limited() {
        SupernodalThreshold::FORCE_SIMPLICIAL
    } else {
        SupernodalThreshold::AUTO
    }
});

#[cfg(target_os = "linux")]
fn address_space_limited() -> bool {
    use rustix::process::{Resource, getrlimit};
    getrlimit(Resource::As).current.is_some()
}

#[cfg(not(target_os = "linux"))]
fn address_space_limited() -> bool {
    false
}

/// Symbolic settings of a sparse Cholesky factorisation.
pub(crate) fn cholesky_params() -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: *THRESHOLD,
        ..Default::default()
    }
}

/// Whether supernodal factorisations may run in this process (no address-space limit).
pub(crate) fn supernodal_allowed() -> bool {
    *THRESHOLD != SupernodalThreshold::FORCE_SIMPLICIAL
}

/// Symbolic settings of a sparse Cholesky-structured factorisation that must be supernodal
/// (the pivoting LBLᵀ of `fem::complex_symmetric`), whatever its size; only where
/// [`supernodal_allowed`].
pub(crate) fn supernodal_cholesky_params() -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    }
}

/// Symbolic settings of the simplicial sparse LU used where supernodal factorisations are not
/// allowed.
pub(crate) fn lu_params() -> LuSymbolicParams<'static> {
    LuSymbolicParams {
        supernodal_flop_ratio_threshold: *THRESHOLD,
        ..Default::default()
    }
}
