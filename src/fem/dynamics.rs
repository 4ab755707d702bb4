//! One linearised backward-Euler step of corotational elasticity with lumped mass and Rayleigh
//! damping C = α M + β K' (SOFA EulerImplicitSolver, rayleighMass = α, rayleighStiffness = β;
//! Müller & Gross 2004 form; docs/fem.md):
//!
//! (M + h C + h² K') v' = M v − h (K' x − f0' − f_ext) = M v + h (f_el(x) + f_ext),
//! x' = x + h v'.
//!
//! One factorisation per step, no Newton loop; fixed DOFs get v' = 0. The pattern and the
//! symbolic factorisation are built once and reused every step.

use nalgebra::{Point3, Vector3};

use super::assembly::SparsePattern;
use super::cholesky::SparseCholesky;
use super::error::{ElementId, FemError};
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::state::CorotationalState;

/// Rayleigh damping coefficients: C = mass·M + stiffness·K'.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Rayleigh {
    /// α (1/s).
    pub mass: f64,
    /// β (s).
    pub stiffness: f64,
}

impl Rayleigh {
    /// Both coefficients finite and non-negative.
    pub fn validate(&self) -> Result<(), FemError> {
        non_negative("rayleigh mass", self.mass)?;
        non_negative("rayleigh stiffness", self.stiffness)
    }
}

/// `Err(InvalidParameter)` unless `value` is finite and ≥ 0.
pub(crate) fn non_negative(what: &'static str, value: f64) -> Result<(), FemError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(FemError::InvalidParameter {
            what,
            value,
            expected: "finite and >= 0",
        })
    }
}

/// What one implicit step produced.
#[derive(Debug, Clone, PartialEq)]
pub struct StepReport {
    /// Tetrahedra inverted and membrane triangles collapsed in the new state.
    pub failed_elements: Vec<ElementId>,
}

/// Linearised implicit Euler integrator for one model and one set of fixed DOFs.
#[derive(Debug)]
pub struct ImplicitEuler<'m> {
    model: &'m FemModel,
    fixed: FixedDofs,
    damping: Rayleigh,
    pattern: SparsePattern,
    values: Vec<f64>,
    cholesky: SparseCholesky,
    state: CorotationalState,
    forces: Vec<Vector3<f64>>,
    rhs: Vec<f64>,
    mass_diagonal: Vec<f64>,
}

impl<'m> ImplicitEuler<'m> {
    /// An integrator with fixed DOFs and Rayleigh damping (α, β ≥ 0).
    pub fn new(model: &'m FemModel, fixed: FixedDofs, damping: Rayleigh) -> Result<Self, FemError> {
        if fixed.len() != model.dof_count() {
            return Err(FemError::LengthMismatch {
                what: "fixed DOF mask",
                expected: model.dof_count(),
                found: fixed.len(),
            });
        }
        damping.validate()?;
        let pattern = SparsePattern::new(model);
        let cholesky = SparseCholesky::analyse(&pattern)?;
        Ok(ImplicitEuler {
            model,
            fixed,
            damping,
            values: pattern.zero_values(),
            pattern,
            cholesky,
            state: CorotationalState::new(model),
            forces: vec![Vector3::zeros(); model.node_count()],
            rhs: vec![0.0; model.dof_count()],
            mass_diagonal: vec![0.0; model.node_count()],
        })
    }

    /// Advances positions `x` (mm) and velocities `v` (mm/s) by `dt` (s) under constant nodal
    /// forces `external` (µN, one per node, if any).
    pub fn step(
        &mut self,
        x: &mut [Point3<f64>],
        v: &mut [Vector3<f64>],
        dt: f64,
        external: Option<&[Vector3<f64>]>,
    ) -> Result<StepReport, FemError> {
        let n = self.model.node_count();
        if !(dt.is_finite() && dt > 0.0) {
            return Err(FemError::InvalidParameter {
                what: "time step (s)",
                value: dt,
                expected: "finite and > 0",
            });
        }
        for (what, len) in [
            ("velocities", v.len()),
            ("external forces", external.map_or(n, <[_]>::len)),
        ] {
            if len != n {
                return Err(FemError::LengthMismatch {
                    what,
                    expected: n,
                    found: len,
                });
            }
        }
        self.state.update(self.model, x)?;
        let masses = self.model.lumped_masses();
        let Rayleigh {
            mass: alpha,
            stiffness: beta,
        } = self.damping;
        for (d, m) in self.mass_diagonal.iter_mut().zip(masses) {
            *d = (1.0 + dt * alpha) * m;
        }
        self.pattern.assemble(
            self.model,
            &self.state,
            dt * (dt + beta),
            Some(&self.mass_diagonal),
            &self.fixed,
            &mut self.values,
        )?;
        self.forces.fill(Vector3::zeros());
        self.state
            .add_elastic_forces(self.model, &mut self.forces)?;
        if let Some(f) = external {
            self.forces.iter_mut().zip(f).for_each(|(a, b)| *a += b);
        }
        for (((r, f), vel), m) in self
            .rhs
            .chunks_exact_mut(3)
            .zip(&self.forces)
            .zip(v.iter())
            .zip(masses)
        {
            let b = vel * *m + f * dt;
            r.copy_from_slice(b.as_slice());
        }
        self.fixed.zero_fixed(&mut self.rhs);
        self.cholesky.factorise(self.pattern.matrix(&self.values))?;
        self.cholesky.solve_in_place(&mut self.rhs)?;
        if let Some(i) = self.rhs.iter().position(|r| !r.is_finite()) {
            return Err(FemError::NonFinite {
                what: "new velocity of DOF",
                index: i,
            });
        }
        for ((p, vel), r) in x.iter_mut().zip(v.iter_mut()).zip(self.rhs.chunks_exact(3)) {
            *vel = Vector3::new(r[0], r[1], r[2]);
            *p += *vel * dt;
        }
        self.state.update(self.model, x)?;
        Ok(StepReport {
            failed_elements: self.state.failed_elements().to_vec(),
        })
    }
}
