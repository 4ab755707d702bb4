//! The terms of a static problem (`fem::statics`): its loads (zero-rest-length springs,
//! nodal forces; the follower pressure is `fem::pressure`), the solver's iteration controls,
//! and what a converged solve reports.

use nalgebra::{Point3, Vector3};

use super::cholesky::FactorPrecision;

/// A zero-rest-length spring pulling `node` towards `target` (mm) with `stiffness` (µN/mm):
/// force k (target − x_node).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    pub node: u32,
    pub target: Point3<f64>,
    pub stiffness: f64,
}

/// The loads of a static problem.
#[derive(Debug, Clone, Copy, Default)]
pub struct StaticLoads<'a> {
    /// Zero-rest-length springs.
    pub springs: &'a [Spring],
    /// Constant nodal forces (µN), one per node, if any.
    pub nodal_forces: Option<&'a [Vector3<f64>]>,
}

/// Iteration controls of the static solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticOptions {
    /// Converged when the largest nodal update of an iteration is below this (mm).
    pub tolerance_mm: f64,
    /// Iteration limit; exceeding it is `FemError::NotConverged`.
    pub max_iterations: usize,
    /// Step halvings allowed per iteration by the inversion guard.
    pub max_halvings: usize,
    /// Levenberg-style shift (µN/mm) added to the tangent diagonal of every free DOF, not to
    /// the residual: the equilibrium is unchanged, only the path (convergence slows as the
    /// shift grows; check `StaticReport::max_residual`). The warped tangent has no stress
    /// (geometric) stiffness, so flat membrane regions without springs are singular out of
    /// plane; a shift above the membrane tension σh there keeps the iteration definite and
    /// stable. (A membrane in compression has no flat equilibrium at all: it wrinkles.)
    pub tangent_shift: f64,
    /// Tangent reuse (module doc): an iteration whose residual norm is at most this fraction
    /// of the previous iteration's keeps the last factorisation; 0 (the default) assembles and
    /// factorises at every iteration.
    pub reuse_tangent_below: f64,
    /// Balance (module doc): converged, before any further step, once the residual norm is
    /// at most this fraction of the first iteration's; 0 (the default) judges on the update
    /// alone. For loads that are met long before the nodes stop moving: with no stress
    /// stiffness, parts no load holds (a membrane without springs, out of plane) drift by
    /// tenths of a millimetre per iteration at a residual 1e-5 of the first.
    pub balanced_below: f64,
    /// Stall (module doc): the solve ends, not converged, when an iteration's residual norm
    /// is above (1 − this) times the previous one's; 0 (the default) never. For loads the
    /// inversion guard keeps from being met: each step is halved and the residual creeps.
    pub stalled_below: f64,
    /// Anderson acceleration of the chord steps (`fem::anderson`): the number of past
    /// iterations mixed into each step taken with a reused tangent; the history is cleared
    /// at each factorisation. 0 (the default) takes the plain steps.
    pub anderson_depth: usize,
    /// The precision the tangent is factorised in (`FactorPrecision`; double by default).
    /// The residual, the steps and the convergence tests stay double, so a single-precision
    /// tangent changes the path to an equilibrium, not the equilibrium.
    pub tangent_precision: FactorPrecision,
}

impl Default for StaticOptions {
    fn default() -> Self {
        StaticOptions {
            tolerance_mm: 1e-6,
            max_iterations: 100,
            max_halvings: 30,
            tangent_shift: 0.0,
            reuse_tangent_below: 0.0,
            balanced_below: 0.0,
            stalled_below: 0.0,
            anderson_depth: 0,
            tangent_precision: FactorPrecision::Double,
        }
    }
}

/// What a converged static solve did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StaticReport {
    /// Newton-like iterations done (a residual and a solve each).
    pub iterations: usize,
    /// Tangents assembled and factorised (`iterations` unless the tangent was reused, the
    /// first iteration's possibly carried over from the previous solve).
    pub factorisations: usize,
    /// Largest nodal update of the last iteration (mm).
    pub max_update_mm: f64,
    /// Total step halvings forced by the inversion guard.
    pub halvings: usize,
    /// Largest nodal out-of-balance force over free DOFs at the returned state (µN).
    pub max_residual: f64,
    /// |out-of-balance force| / |load| over the free DOFs at the returned state.
    pub relative_residual: f64,
}
