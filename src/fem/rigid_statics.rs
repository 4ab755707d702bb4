//! The static solver's unknowns with rigid bodies (`StaticSolver::with_rigid_bodies`;
//! docs/fem.md, "Rigid bodies"): the free DOFs of no body, and per body a translation t and a
//! rotation R taken exactly, its node v at c + t + R (X_v − c) (c its centre, X the rest
//! positions), so a body never strains however far it turns.
//!
//! At positions x the out-of-balance force is restricted through T at the current arms
//! a_v = R (X_v − c): a body's rows are its net force and its net moment about c + t. The
//! tangent is Tᵀ K T at the same arms, without the moment's own change as the body turns (as
//! the warped tangent leaves out dR/dx: a Newton-like iteration whose equilibrium is exact).
//! A step moves a body by t ← t + αΔt, R ← exp([αΔθ]×) R. The tangent is assembled from the
//! elastic model's (the bodies' inner tetrahedra left out) through a plan built once
//! (`fem::reduced_pattern`): where each product of a full lower entry with two rows of T falls
//! in the reduced lower pattern.

use std::sync::Arc;

use faer::sparse::SparseColMatRef;
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

use super::assembly::SparsePattern;
use super::cholesky::{FactorPrecision, SparseCholesky, amd_ordering};
use super::error::FemError;
use super::fixed::FixedDofs;
use super::reduced_pattern::ReducedLower;
use super::rigid::{Reduction, RigidBodies};
use super::rotation::polar_rotation;

/// The unknowns, the bodies' poses and the reduced tangent's factorisation.
#[derive(Debug, Clone)]
pub(crate) struct RigidUnknowns {
    bodies: RigidBodies,
    /// T at the current arms.
    reduction: Reduction,
    /// Each body's nodes.
    members: Vec<Vec<usize>>,
    /// X_v − c of each node of a body (zero elsewhere).
    rest_arms: Vec<Vector3<f64>>,
    /// Each body's translation and rotation from rest; `trial` those of the last trial step.
    poses: Vec<(Vector3<f64>, Rotation3<f64>)>,
    trial: Vec<(Vector3<f64>, Rotation3<f64>)>,
    /// The DOF of each unknown of no body (the unknowns of the bodies follow them).
    free_dofs: Vec<usize>,
    /// The reduced tangent's lower pattern and the plan of its products (shared by clones).
    reduced: Arc<ReducedLower>,
    values: Vec<f64>,
    /// Where each unknown sits in the reduced tangent's order, and a vector in that order.
    position: Vec<usize>,
    ordered: Vec<f64>,
    cholesky: SparseCholesky,
}

impl RigidUnknowns {
    /// The unknowns of a model whose elastic part has the tangent pattern `full`, at rest
    /// positions `rest`, with `fixed` DOFs and `bodies`.
    pub(crate) fn new(
        full: &SparsePattern,
        rest: &[Point3<f64>],
        fixed: &FixedDofs,
        bodies: &RigidBodies,
    ) -> Result<Self, FemError> {
        let reduction = Reduction::new(rest, fixed, bodies)?;
        let mut members = vec![Vec::new(); bodies.count()];
        let mut rest_arms = vec![Vector3::zeros(); rest.len()];
        for (v, p) in rest.iter().enumerate() {
            if let Some(b) = bodies.body_of(v) {
                members[b].push(v);
                rest_arms[v] = p - bodies.centre(b);
            }
        }
        let free_dofs: Vec<usize> = (0..3 * rest.len())
            .filter(|&d| bodies.body_of(d / 3).is_none() && !reduction.row(d).is_empty())
            .collect();
        // the reduced tangent in its fill-reducing order once, so that no factorisation
        // permutes it again
        let natural = ReducedLower::new(&reduction, full.symbolic(), &[]);
        let (_, position) = amd_ordering(natural.pattern())?;
        let reduced = natural.permuted(&position);
        let cholesky = SparseCholesky::analyse_in_order(reduced.pattern())?;
        let identity = (Vector3::zeros(), Rotation3::identity());
        Ok(RigidUnknowns {
            reduction,
            members,
            rest_arms,
            poses: vec![identity; bodies.count()],
            trial: vec![identity; bodies.count()],
            bodies: bodies.clone(),
            free_dofs,
            values: vec![0.0; reduced.len()],
            reduced: Arc::new(reduced),
            ordered: vec![0.0; position.len()],
            position,
            cholesky,
        })
    }

    /// Number of unknowns.
    pub(crate) fn unknowns(&self) -> usize {
        self.reduction.unknowns()
    }

    /// Fits each body's pose to its nodes in `x` (their centroid and the polar rotation of
    /// their spread against rest's) and puts them on it exactly: `x` may come from anywhere
    /// (rest, an earlier solve, a caller's copy).
    pub(crate) fn attach(&mut self, x: &mut [Point3<f64>]) {
        for (b, nodes) in self.members.iter().enumerate() {
            let centroid = nodes.iter().map(|&v| x[v].coords).sum::<Vector3<f64>>()
                / nodes.len().max(1) as f64;
            let spread: Matrix3<f64> = nodes
                .iter()
                .map(|&v| (x[v].coords - centroid) * self.rest_arms[v].transpose())
                .sum();
            let rotation = Rotation3::from_matrix_unchecked(polar_rotation(&spread));
            let t = centroid - self.bodies.centre(b).coords;
            self.poses[b] = (t, rotation);
        }
        self.place(x, false);
    }

    /// Puts the bodies' nodes of `x` where the poses (`trial` ones if asked) put them.
    fn place(&self, x: &mut [Point3<f64>], trial: bool) {
        let poses = if trial { &self.trial } else { &self.poses };
        for (b, nodes) in self.members.iter().enumerate() {
            let (t, r) = poses[b];
            let origin = self.bodies.centre(b) + t;
            for &v in nodes {
                x[v] = origin + r * self.rest_arms[v];
            }
        }
    }

    /// Tᵀ f of nodal forces `f` (fixed DOFs have no unknowns and drop out) into `out`.
    pub(crate) fn restrict(&self, f: &[Vector3<f64>], out: &mut [f64]) {
        self.reduction.restrict_into(|d| f[d / 3][d % 3], out);
    }

    /// The iterate as one vector (for Anderson mixing): the free coordinates of `x`, then
    /// each body's translation and rotation vector.
    pub(crate) fn iterate(&self, x: &[Point3<f64>], out: &mut Vec<f64>) {
        out.clear();
        out.extend(self.free_dofs.iter().map(|&d| x[d / 3][d % 3]));
        for (t, r) in &self.poses {
            out.extend(t.iter().chain(r.scaled_axis().iter()));
        }
    }

    /// Writes into `trial` the positions `x` moved by α times the step `dq` (module doc).
    pub(crate) fn trial_positions(
        &mut self,
        x: &[Point3<f64>],
        dq: &[f64],
        alpha: f64,
        trial: &mut Vec<Point3<f64>>,
    ) {
        trial.clear();
        trial.extend_from_slice(x);
        for (i, &d) in self.free_dofs.iter().enumerate() {
            trial[d / 3][d % 3] += alpha * dq[i];
        }
        let first = self.free_dofs.len();
        for (b, (t, r)) in self.poses.iter().enumerate() {
            let s = &dq[first + 6 * b..first + 6 * b + 6];
            let turn = Rotation3::from_scaled_axis(Vector3::new(s[3], s[4], s[5]) * alpha);
            self.trial[b] = (t + Vector3::new(s[0], s[1], s[2]) * alpha, turn * r);
        }
        self.place(trial, true);
    }

    /// Takes the last trial step's poses, and T at their arms.
    pub(crate) fn accept(&mut self) {
        self.poses.copy_from_slice(&self.trial);
        let (poses, arms) = (&self.poses, &self.rest_arms);
        self.reduction
            .set_arms(&self.bodies, |v, b| poses[b].1 * arms[v]);
    }

    /// Factorises in `precision` Tᵀ A T of the full lower tangent `values` on `full`.
    pub(crate) fn factorise(
        &mut self,
        full: &SparsePattern,
        values: &[f64],
        precision: FactorPrecision,
    ) -> Result<(), FemError> {
        self.reduced
            .reduce(&self.reduction, full.symbolic(), values, &mut self.values);
        self.cholesky.factorise_in(
            SparseColMatRef::new(self.reduced.pattern(), &self.values),
            precision,
        )
    }

    /// Solves the last factorised tangent in place.
    pub(crate) fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), FemError> {
        if rhs.len() != self.position.len() {
            return Err(FemError::LengthMismatch {
                what: "right-hand side",
                expected: self.position.len(),
                found: rhs.len(),
            });
        }
        for (&i, r) in self.position.iter().zip(rhs.iter()) {
            self.ordered[i] = *r;
        }
        self.cholesky.solve_in_place(&mut self.ordered)?;
        for (&i, r) in self.position.iter().zip(rhs.iter_mut()) {
            *r = self.ordered[i];
        }
        Ok(())
    }

    /// The largest out-of-balance force (µN) of the total nodal forces `f`: at a free node of
    /// no body, and each body's net force.
    pub(crate) fn max_residual(&self, f: &[Vector3<f64>]) -> f64 {
        let mut free = vec![Vector3::zeros(); f.len()];
        for &d in &self.free_dofs {
            free[d / 3][d % 3] = f[d / 3][d % 3];
        }
        let nodes = free.iter().map(|r| r.norm());
        let bodies = self
            .members
            .iter()
            .map(|m| m.iter().map(|&v| f[v]).sum::<Vector3<f64>>().norm());
        nodes.chain(bodies).fold(0.0, f64::max)
    }
}
