//! Quasi-static equilibrium of corotational elasticity plus zero-rest-length springs and nodal
//! forces, by Newton-like iterations on the warped tangent (SOFA StaticSolver with the
//! TetrahedronFEMForceField tangent R K Rᵀ, no dR/dx term; docs/fem.md, "Corotation").
//!
//! Each iteration at positions x: residual r = f_el(x) + Σ k (p − x_node) + f_ext, tangent
//! A = K'(x) + Σ k I (spring nodes) + shift·I (optional), fixed DOFs projected out; assemble,
//! factorise numerically with the reused symbolic analysis, solve A Δx = r. Inversion guard:
//! the step x + αΔx starts at α = 1 and is halved while any tetrahedron would invert
//! (det F ≤ 0) or any membrane triangle collapse; no returned state holds such an element.
//! Convergence: a full step (α = 1) whose largest nodal update |Δx_v| (mm) is below
//! `tolerance_mm` and, when the solver has a residual tolerance
//! (`StaticSolver::with_residual_tolerance`), whose out-of-balance force is at most
//! that fraction of the load (Euclidean norms over the free DOFs; the load being the springs',
//! nodal and pressure forces at the iterate): a small update alone can hide a slow
//! modified-Newton iteration far from equilibrium. A halved step never counts as converged.
//!
//! Tangent reuse (`StaticOptions::reuse_tangent_below`, off by default): an iteration whose
//! residual has fallen to at most that fraction of the previous iteration's solves with the
//! last factorised tangent instead of assembling and factorising a new one (a chord step;
//! the numeric factorisation is most of an iteration's cost). The residual, the step and the
//! convergence test are the same, so the equilibrium is too; only the path changes. Under
//! reuse the last factorisation also carries over to the next solve when its tangent has the
//! same diagonal (shift and springs) and pressure terms: the next load increment starts
//! where the last one ended, at the same tangent. Once a step has met the update test and
//! only the residual test is left, every further step takes a fresh tangent: a chord step
//! there shrinks the update further, but with rigid bodies its stale tangent (the bodies'
//! arms where they were, across a joint stiffer than bone) raises the residual many times
//! over (BENCHMARKS.md, "The package check: a single-precision static tangent").
//!
//! Anderson acceleration (`StaticOptions::anderson_depth`, off by default; `fem::anderson`):
//! the steps taken with a reused tangent mix in the last few iterates, which speeds up the
//! chord iteration's linear convergence; the history is cleared at each factorisation.
//!
//! Rigid bodies (`StaticSolver::with_rigid_bodies`, `fem::rigid_statics`): the unknowns are
//! then the free DOFs of no body and a translation and an exact rotation per body; the
//! residual and the tangent are restricted to them, the same iteration runs on them, and the
//! largest nodal update counts a body's turn as well.
//!
//! Balance and stall (`StaticOptions::balanced_below`, `stalled_below`, off by default), for
//! solves that only need the loads met: the solve is converged, without a further step, once
//! the residual norm has fallen to that fraction of the first iteration's (the warped tangent
//! has no stress stiffness, so parts no load holds drift by whole steps at a negligible
//! residual and the update test alone never passes); and it ends, not converged, once an
//! iteration lowered the residual by less than the stall fraction (the inversion guard halving
//! every step).

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::{Point3, Vector3};

use super::anderson::Anderson;
use super::assembly::SparsePattern;
use super::cholesky::{FactorPrecision, SparseCholesky};
use super::error::{ElementId, FemError};
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::pressure::PressureLoad;
use super::rigid::RigidBodies;
use super::rigid_statics::RigidUnknowns;
use super::state::{CorotationalState, check_positions, first_failure};
use super::static_problem::{Spring, StaticLoads, StaticOptions, StaticReport};
use super::static_unknowns::Unknowns;

/// Static solver for one model and one set of fixed DOFs: the pattern and the symbolic
/// factorisation are built once here and reused by every solve.
#[derive(Debug, Clone)]
pub struct StaticSolver<'m> {
    /// The model, or with rigid bodies its elastic part (`FemModel::without_rigid_tets`).
    model: Cow<'m, FemModel>,
    /// The unknowns and the tangent's factorisation on them.
    unknowns: Unknowns,
    fixed: FixedDofs,
    /// The tangent's pattern (shared by clones).
    pattern: Arc<SparsePattern>,
    values: Vec<f64>,
    state: CorotationalState,
    forces: Vec<Vector3<f64>>,
    rhs: Vec<f64>,
    trial: Vec<Point3<f64>>,
    /// The iterate, flattened, for the Anderson history.
    fixed_point: Vec<f64>,
    tangent_diagonal: Vec<f64>,
    /// `tangent_diagonal` of the previous solve, to tell whether its tangent carries over.
    previous_diagonal: Vec<f64>,
    /// Whether `unknowns` holds a factorised tangent, and if so whether with the pressure's
    /// stress stiffness.
    factorised_pressure: Option<bool>,
    /// Converged only when |residual| ≤ this × |load| (the module doc); `None` judges on the
    /// update alone.
    residual_tolerance: Option<f64>,
}

impl<'m> StaticSolver<'m> {
    /// A solver with the given fixed DOFs (see `FixedDofs::from_nodes`).
    pub fn new(model: &'m FemModel, fixed: FixedDofs) -> Result<Self, FemError> {
        Self::check_fixed(model, &fixed)?;
        let pattern = SparsePattern::new(model);
        let cholesky = SparseCholesky::analyse(&pattern)?;
        Ok(Self::build(
            Cow::Borrowed(model),
            fixed,
            pattern,
            Unknowns::Dofs(Box::new(cholesky)),
        ))
    }

    /// A solver with `bodies` moving rigidly (`fem::rigid_statics`): its unknowns are the free
    /// DOFs of no body and a translation and an exact rotation per body; the tetrahedra inside
    /// a body are left out. No node of a body may have a fixed DOF.
    pub fn with_rigid_bodies(
        model: &'m FemModel,
        fixed: FixedDofs,
        bodies: &RigidBodies,
    ) -> Result<Self, FemError> {
        Self::check_fixed(model, &fixed)?;
        let elastic = model.without_rigid_tets(bodies)?;
        let pattern = SparsePattern::new(&elastic);
        let rigid = RigidUnknowns::new(&pattern, model.rest_positions(), &fixed, bodies)?;
        Ok(Self::build(
            Cow::Owned(elastic),
            fixed,
            pattern,
            Unknowns::Rigid(Box::new(rigid)),
        ))
    }

    fn check_fixed(model: &FemModel, fixed: &FixedDofs) -> Result<(), FemError> {
        if fixed.len() != model.dof_count() {
            return Err(FemError::LengthMismatch {
                what: "fixed DOF mask",
                expected: model.dof_count(),
                found: fixed.len(),
            });
        }
        Ok(())
    }

    fn build(
        model: Cow<'m, FemModel>,
        fixed: FixedDofs,
        pattern: SparsePattern,
        unknowns: Unknowns,
    ) -> Self {
        let n = model.node_count();
        let rhs = unknowns.len(n);
        StaticSolver {
            state: CorotationalState::new(&model),
            model,
            unknowns,
            fixed,
            values: pattern.zero_values(),
            pattern: Arc::new(pattern),
            forces: vec![Vector3::zeros(); n],
            rhs: vec![0.0; rhs],
            trial: Vec::with_capacity(n),
            fixed_point: Vec::with_capacity(3 * n),
            tangent_diagonal: vec![0.0; n],
            previous_diagonal: vec![0.0; n],
            factorised_pressure: None,
            residual_tolerance: None,
        }
    }

    /// The same solver judging equilibrium on the out-of-balance force too: a solve converges
    /// only when it is at most `fraction` of the load (the module doc).
    pub fn with_residual_tolerance(mut self, fraction: f64) -> Result<Self, FemError> {
        if !(fraction > 0.0 && fraction.is_finite()) {
            return Err(FemError::InvalidParameter {
                what: "residual tolerance (fraction of the load)",
                value: fraction,
                expected: "finite and > 0",
            });
        }
        self.residual_tolerance = Some(fraction);
        Ok(self)
    }

    /// Equilibrium under springs only; see `solve`.
    pub fn solve_with_springs(
        &mut self,
        x: &mut [Point3<f64>],
        springs: &[Spring],
        options: &StaticOptions,
    ) -> Result<StaticReport, FemError> {
        let loads = StaticLoads {
            springs,
            nodal_forces: None,
        };
        self.solve(x, &loads, options)
    }

    /// Moves the free DOFs of `x` (mm; fixed DOFs keep their given values) to the equilibrium
    /// of elasticity and `loads`. `x` must hold no inverted element. On `NotConverged` or
    /// `StepRejected`, `x` holds the last admissible iterate.
    pub fn solve(
        &mut self,
        x: &mut [Point3<f64>],
        loads: &StaticLoads<'_>,
        options: &StaticOptions,
    ) -> Result<StaticReport, FemError> {
        self.solve_impl(x, loads, None, options)
    }

    /// As [`StaticSolver::solve`], plus a follower `pressure` re-evaluated at every iterate.
    /// The tangent adds the membranes' tensile stress stiffness (a pressurised membrane's
    /// out-of-plane stiffness; `SparsePattern::add_membrane_stress_stiffness`). The load's own
    /// stiffness (non-symmetric, of order p·L; docs/fem.md, "Follower pressure") is left out
    /// of the tangent, so the iteration is a modified Newton that converges linearly at the
    /// rate (load stiffness)/(structural stiffness); the equilibrium it reaches is exact.
    pub fn solve_with_pressure(
        &mut self,
        x: &mut [Point3<f64>],
        loads: &StaticLoads<'_>,
        pressure: &PressureLoad<'_>,
        options: &StaticOptions,
    ) -> Result<StaticReport, FemError> {
        pressure.check(self.model.node_count())?;
        self.solve_impl(x, loads, Some(pressure), options)
    }

    fn solve_impl(
        &mut self,
        x: &mut [Point3<f64>],
        loads: &StaticLoads<'_>,
        pressure: Option<&PressureLoad<'_>>,
        options: &StaticOptions,
    ) -> Result<StaticReport, FemError> {
        self.check(loads, options)?;
        self.previous_diagonal
            .copy_from_slice(&self.tangent_diagonal);
        self.set_tangent_diagonal(loads, options);
        let carried = options.reuse_tangent_below > 0.0
            && self.factorised_pressure == Some(pressure.is_some())
            && self.previous_diagonal == self.tangent_diagonal;
        self.start_at(x)?;
        let mut halvings = 0;
        let mut factorisations = 0;
        let mut previous_residual = f64::INFINITY;
        let mut max_update = f64::INFINITY;
        let mut relative_residual = f64::INFINITY;
        // a full step has met the update test and only the residual test is left: fresh
        // tangents from then on (module doc)
        let mut only_residual_left = false;
        let mut first_residual = None;
        let mut anderson = Anderson::new(options.anderson_depth);
        for iteration in 1..=options.max_iterations {
            let load = self.residual(x, loads, pressure)?;
            let residual = self.rhs.iter().map(|r| r * r).sum::<f64>().sqrt();
            let first = *first_residual.get_or_insert(residual);
            if iteration > 1
                && options.balanced_below > 0.0
                && residual <= options.balanced_below * first
            {
                return Ok(self.report(
                    iteration - 1,
                    factorisations,
                    max_update,
                    halvings,
                    residual / load.max(f64::MIN_POSITIVE),
                ));
            }
            if iteration > 1
                && options.stalled_below > 0.0
                && residual > (1.0 - options.stalled_below) * previous_residual
            {
                return Err(FemError::NotConverged {
                    iterations: iteration - 1,
                    max_update,
                    tolerance: options.tolerance_mm,
                    relative_residual,
                    residual_tolerance: self.residual_tolerance.unwrap_or(f64::INFINITY),
                });
            }
            let reuse = (factorisations > 0 || carried)
                && !only_residual_left
                && options.reuse_tangent_below > 0.0
                && residual <= options.reuse_tangent_below * previous_residual;
            previous_residual = residual;
            if !reuse {
                self.factorise_tangent(x, pressure.is_some(), options.tangent_precision)?;
                factorisations += 1;
                anderson.clear();
            }
            self.unknowns.solve_in_place(&mut self.rhs)?;
            if options.anderson_depth > 0 {
                self.unknowns.iterate(x, &mut self.fixed_point);
                anderson.accelerate(&self.fixed_point, &mut self.rhs);
            }
            let (step, h) = self.guarded_step(x, iteration, options.max_halvings)?;
            halvings += h;
            max_update = step;
            if h > 0 || max_update >= options.tolerance_mm {
                continue;
            }
            let load = self.residual(x, loads, pressure)?;
            let residual = self.rhs.iter().map(|r| r * r).sum::<f64>().sqrt();
            relative_residual = residual / load.max(f64::MIN_POSITIVE);
            only_residual_left = true;
            if self
                .residual_tolerance
                .is_none_or(|t| relative_residual <= t)
            {
                return Ok(self.report(
                    iteration,
                    factorisations,
                    max_update,
                    halvings,
                    relative_residual,
                ));
            }
        }
        Err(FemError::NotConverged {
            iterations: options.max_iterations,
            max_update,
            tolerance: options.tolerance_mm,
            relative_residual,
            residual_tolerance: self.residual_tolerance.unwrap_or(f64::INFINITY),
        })
    }

    /// Factorises now the tangent that a solve from `x` with `loads` (and a pressure, if
    /// `pressure`) under `options` would factorise first; the next such solve starts from it,
    /// as from a tangent carried over from a previous solve (when `options` reuse tangents).
    /// A caller can factorise beside other work, or once for several clones of the solver:
    /// `mechanics::udsp` does both for the two branches of its curve, which start at rest.
    pub fn factorise_ahead(
        &mut self,
        x: &mut [Point3<f64>],
        loads: &StaticLoads<'_>,
        pressure: bool,
        options: &StaticOptions,
    ) -> Result<(), FemError> {
        self.check(loads, options)?;
        self.set_tangent_diagonal(loads, options);
        self.start_at(x)?;
        self.factorise_tangent(x, pressure, options.tangent_precision)
    }

    /// The tangent's diagonal terms: the shift, and the springs' stiffness.
    fn set_tangent_diagonal(&mut self, loads: &StaticLoads<'_>, options: &StaticOptions) {
        self.tangent_diagonal.fill(options.tangent_shift);
        for s in loads.springs {
            self.tangent_diagonal[s.node as usize] += s.stiffness;
        }
    }

    /// Puts the bodies on `x` and the state at it; refuses an inverted start.
    fn start_at(&mut self, x: &mut [Point3<f64>]) -> Result<(), FemError> {
        self.unknowns.attach(x);
        self.state.update(&self.model, x)?;
        if let Some(&first) = self.state.failed_elements().first() {
            return Err(FemError::InvertedState {
                count: self.state.failed_elements().len(),
                first,
            });
        }
        Ok(())
    }

    /// The report of a converged solve; `self.rhs` holds the residual at the returned state.
    fn report(
        &self,
        iterations: usize,
        factorisations: usize,
        max_update_mm: f64,
        halvings: usize,
        relative_residual: f64,
    ) -> StaticReport {
        let max_residual = self.unknowns.max_residual(&self.rhs, &self.forces);
        StaticReport {
            iterations,
            factorisations,
            max_update_mm,
            halvings,
            max_residual,
            relative_residual,
        }
    }

    /// Assembles the tangent at `x` (state already updated to `x`), with the membranes'
    /// stress stiffness under a pressure load, and factorises it in `precision`.
    fn factorise_tangent(
        &mut self,
        x: &[Point3<f64>],
        pressure: bool,
        precision: FactorPrecision,
    ) -> Result<(), FemError> {
        self.pattern.assemble(
            &self.model,
            &self.state,
            1.0,
            Some(&self.tangent_diagonal),
            &self.fixed,
            &mut self.values,
        )?;
        if pressure {
            self.pattern.add_membrane_stress_stiffness(
                &self.model,
                x,
                &self.state,
                1.0,
                &self.fixed,
                &mut self.values,
            )?;
        }
        self.factorised_pressure = None;
        self.unknowns
            .factorise(&self.pattern, &self.values, precision)?;
        self.factorised_pressure = Some(pressure);
        Ok(())
    }

    fn check(&self, loads: &StaticLoads<'_>, options: &StaticOptions) -> Result<(), FemError> {
        let n = self.model.node_count();
        for s in loads.springs {
            if s.node as usize >= n {
                return Err(FemError::BadNodeReference {
                    what: "spring",
                    node: s.node,
                    n_nodes: n,
                });
            }
            let finite = s.target.coords.iter().all(|c| c.is_finite());
            if !(finite && s.stiffness.is_finite() && s.stiffness >= 0.0) {
                return Err(FemError::InvalidParameter {
                    what: "spring stiffness (µN/mm) or target (mm)",
                    value: s.stiffness,
                    expected: "finite target and stiffness >= 0",
                });
            }
        }
        if let Some(f) = loads.nodal_forces
            && f.len() != n
        {
            return Err(FemError::LengthMismatch {
                what: "nodal forces",
                expected: n,
                found: f.len(),
            });
        }
        if !(options.tangent_shift >= 0.0 && options.tangent_shift.is_finite()) {
            return Err(FemError::InvalidParameter {
                what: "tangent_shift (µN/mm)",
                value: options.tangent_shift,
                expected: "finite and >= 0",
            });
        }
        if !(0.0..1.0).contains(&options.reuse_tangent_below) {
            return Err(FemError::InvalidParameter {
                what: "reuse_tangent_below (residual ratio)",
                value: options.reuse_tangent_below,
                expected: "in [0, 1)",
            });
        }
        if !(options.tolerance_mm > 0.0 && options.tolerance_mm.is_finite()) {
            return Err(FemError::InvalidParameter {
                what: "tolerance_mm",
                value: options.tolerance_mm,
                expected: "a finite tolerance > 0 mm",
            });
        }
        Ok(())
    }

    /// Writes the out-of-balance force at `x` (state already updated to `x`) into `rhs`,
    /// zero on fixed DOFs; returns the Euclidean norm of the load (springs, nodal forces,
    /// pressure) over the free DOFs.
    fn residual(
        &mut self,
        x: &[Point3<f64>],
        loads: &StaticLoads<'_>,
        pressure: Option<&PressureLoad<'_>>,
    ) -> Result<f64, FemError> {
        self.forces.fill(Vector3::zeros());
        for s in loads.springs {
            let v = s.node as usize;
            self.forces[v] += (s.target - x[v]) * s.stiffness;
        }
        if let Some(f) = loads.nodal_forces {
            self.forces.iter_mut().zip(f).for_each(|(a, b)| *a += b);
        }
        if let Some(p) = pressure {
            p.add_forces(x, &mut self.forces);
        }
        // the load on the unknowns (zero on fixed DOFs, or each body's net force and moment)
        self.unknowns
            .restrict(&self.forces, &self.fixed, &mut self.rhs);
        let load = self.rhs.iter().map(|f| f * f).sum::<f64>().sqrt();
        self.state
            .add_elastic_forces(&self.model, &mut self.forces)?;
        self.unknowns
            .restrict(&self.forces, &self.fixed, &mut self.rhs);
        Ok(load)
    }

    /// Applies x += αΔx (Δx in `rhs`) with the largest α = 2⁻ᵏ that keeps every element
    /// admissible; leaves `state` at the new x. Returns (largest nodal update, halvings).
    fn guarded_step(
        &mut self,
        x: &mut [Point3<f64>],
        iteration: usize,
        max_halvings: usize,
    ) -> Result<(f64, usize), FemError> {
        let mut alpha = 1.0;
        let mut culprit = ElementId::Tet(0);
        for halvings in 0..=max_halvings {
            self.unknowns
                .trial_positions(x, &self.rhs, alpha, &mut self.trial);
            // a rejected trial costs a determinant per element, not a state update
            check_positions(&self.model, &self.trial)?;
            if let Some(failed) = first_failure(&self.model, &self.trial) {
                culprit = failed;
                alpha *= 0.5;
                continue;
            }
            self.state.update(&self.model, &self.trial)?;
            let largest = self
                .unknowns
                .largest_update(x, &self.trial, &self.rhs, alpha);
            x.copy_from_slice(&self.trial);
            self.unknowns.accept();
            return Ok((largest, halvings));
        }
        Err(FemError::StepRejected {
            iteration,
            halvings: max_halvings,
            element: culprit,
        })
    }
}
