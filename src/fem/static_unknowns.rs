//! The static solver's unknowns, and the tangent's factorisation on them: every free DOF
//! (the tangent's own Cholesky), or with rigid bodies the free DOFs of no body and a
//! translation and an exact rotation per body (`fem::rigid_statics`). One type, so that the
//! Newton iteration of `fem::statics` is written once for both.

use nalgebra::{Point3, Vector3};

use super::assembly::SparsePattern;
use super::cholesky::{FactorPrecision, SparseCholesky};
use super::error::FemError;
use super::fixed::FixedDofs;
use super::rigid_statics::RigidUnknowns;

/// What the solver's unknowns are.
#[derive(Debug, Clone)]
pub(super) enum Unknowns {
    /// Every free DOF (fixed ones stay in the vectors, zeroed).
    Dofs(Box<SparseCholesky>),
    /// The free DOFs of no body and six per body (`StaticSolver::with_rigid_bodies`).
    Rigid(Box<RigidUnknowns>),
}

impl Unknowns {
    /// Length of the vectors over the unknowns, for a model of `node_count` nodes.
    pub(super) fn len(&self, node_count: usize) -> usize {
        match self {
            Unknowns::Dofs(_) => 3 * node_count,
            Unknowns::Rigid(rigid) => rigid.unknowns(),
        }
    }

    /// Puts the bodies' nodes of `x` on the poses fitted to them (nothing without bodies).
    pub(super) fn attach(&mut self, x: &mut [Point3<f64>]) {
        if let Unknowns::Rigid(rigid) = self {
            rigid.attach(x);
        }
    }

    /// The nodal forces `forces` on the unknowns, into `out`: zero on fixed DOFs, or each
    /// body's net force and moment.
    pub(super) fn restrict(&self, forces: &[Vector3<f64>], fixed: &FixedDofs, out: &mut [f64]) {
        match self {
            Unknowns::Rigid(rigid) => rigid.restrict(forces, out),
            Unknowns::Dofs(_) => {
                for (r, f) in out.chunks_exact_mut(3).zip(forces) {
                    r.copy_from_slice(f.as_slice());
                }
                fixed.zero_fixed(out);
            }
        }
    }

    /// Factorises in `precision` the tangent whose full lower `values` lie on `pattern`.
    pub(super) fn factorise(
        &mut self,
        pattern: &SparsePattern,
        values: &[f64],
        precision: FactorPrecision,
    ) -> Result<(), FemError> {
        match self {
            Unknowns::Rigid(rigid) => rigid.factorise(pattern, values, precision),
            Unknowns::Dofs(cholesky) => cholesky.factorise_in(pattern.matrix(values), precision),
        }
    }

    /// Solves the last factorised tangent in place.
    pub(super) fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), FemError> {
        match self {
            Unknowns::Rigid(rigid) => rigid.solve_in_place(rhs),
            Unknowns::Dofs(cholesky) => cholesky.solve_in_place(rhs),
        }
    }

    /// The iterate at `x` as one vector (for Anderson mixing), into `out`.
    pub(super) fn iterate(&self, x: &[Point3<f64>], out: &mut Vec<f64>) {
        match self {
            Unknowns::Rigid(rigid) => rigid.iterate(x, out),
            Unknowns::Dofs(_) => {
                out.clear();
                out.extend(x.iter().flat_map(|p| [p.x, p.y, p.z]));
            }
        }
    }

    /// Writes into `trial` the positions `x` moved by α times the step `step`.
    pub(super) fn trial_positions(
        &mut self,
        x: &[Point3<f64>],
        step: &[f64],
        alpha: f64,
        trial: &mut Vec<Point3<f64>>,
    ) {
        match self {
            Unknowns::Rigid(rigid) => rigid.trial_positions(x, step, alpha, trial),
            Unknowns::Dofs(_) => {
                trial.clear();
                trial.extend(
                    x.iter()
                        .zip(step.chunks_exact(3))
                        .map(|(p, d)| p + Vector3::new(d[0], d[1], d[2]) * alpha),
                );
            }
        }
    }

    /// The largest nodal update of the trial `trial` from `x` (α times the step `step`); a
    /// body's nodes move by its turn as well as its translation.
    pub(super) fn largest_update(
        &self,
        x: &[Point3<f64>],
        trial: &[Point3<f64>],
        step: &[f64],
        alpha: f64,
    ) -> f64 {
        match self {
            Unknowns::Rigid(_) => x
                .iter()
                .zip(trial)
                .map(|(a, b)| (b - a).norm())
                .fold(0.0, f64::max),
            Unknowns::Dofs(_) => step
                .chunks_exact(3)
                .map(|d| Vector3::new(d[0], d[1], d[2]).norm() * alpha)
                .fold(0.0, f64::max),
        }
    }

    /// Takes the last trial step (the bodies' poses; nothing else to keep).
    pub(super) fn accept(&mut self) {
        if let Unknowns::Rigid(rigid) = self {
            rigid.accept();
        }
    }

    /// The largest out-of-balance force (µN) at a free node, or of a body's net force: from
    /// the residual `rhs` over every DOF, or from the total nodal forces `forces` with bodies.
    pub(super) fn max_residual(&self, rhs: &[f64], forces: &[Vector3<f64>]) -> f64 {
        match self {
            Unknowns::Rigid(rigid) => rigid.max_residual(forces),
            Unknowns::Dofs(_) => rhs
                .chunks_exact(3)
                .map(|r| Vector3::new(r[0], r[1], r[2]).norm())
                .fold(0.0, f64::max),
        }
    }
}
