//! Steady-state harmonic response of the model linearised about its rest shape: the complex
//! frequency-domain system (docs/fem.md)
//!
//! [K (1 + iωβ) + iω (α M + C) − ω² M] û = F̂,
//!
//! with K the rest stiffness (elements plus node springs), M the lumped masses, C the node
//! blocks c n nᵀ of dashpots along a direction (g/s; `Dashpot`) and Rayleigh α, β as SOFA applies them (to the whole stiffness,
//! springs included). The matrix is complex symmetric, not Hermitian; its ordering and
//! symbolic analysis are done once per model and reused at every frequency
//! (`fem::complex_symmetric`). Fixed DOFs are removed from the system (û = 0 there).

use faer::c64;
use faer::sparse::SparseColMat;
use nalgebra::Vector3;

use super::assembly::SparsePattern;
use super::complex_symmetric::ComplexSymmetric;
use super::dashpot::{Dashpot, check_dashpots};
use super::dynamics::{Rayleigh, non_negative};
use super::error::FemError;
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::reduced_pattern::ReducedLower;
use super::rigid::{Reduction, RigidBodies};
use super::state::CorotationalState;

/// Complex amplitude of one node's displacement (mm), x, y, z.
pub type ComplexDisplacement = [c64; 3];

/// Harmonic solver for one model, one set of fixed DOFs and one set of node springs and
/// dashpots; immutable after construction, so frequencies can be solved in parallel. Its
/// unknowns are the free DOFs, or with rigid bodies (`HarmonicSolver::with_rigid_bodies`) the
/// free DOFs of no body and six per body.
#[derive(Debug)]
pub struct HarmonicSolver {
    pub(super) node_count: usize,
    /// The map from the unknowns to the DOFs.
    pub(super) reduction: Reduction,
    /// The full (both triangles) pattern of the unknowns with the real stiffness values.
    pub(super) stiffness: SparseColMat<usize, f64>,
    /// The mass matrix (g): diagonal, or with rigid bodies each body's 6 x 6 block.
    pub(super) mass: OnPattern,
    /// The dashpots' damping matrix (g/s).
    pub(super) dashpot: OnPattern,
    pub(super) rayleigh: Rayleigh,
    factoriser: ComplexSymmetric,
}

/// A symmetric matrix whose entries lie in the solver's pattern: (row, column, value) and each
/// entry's position in the pattern's values.
#[derive(Debug)]
pub(super) struct OnPattern {
    entries: Vec<(usize, usize, f64)>,
    positions: Vec<usize>,
}

impl OnPattern {
    /// y = A x over the unknowns.
    pub(super) fn times(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for &(row, col, a) in &self.entries {
            y[row] += a * x[col];
        }
        y
    }
}

/// Sums the duplicates of (row, column, value) entries.
fn merged(mut entries: Vec<(usize, usize, f64)>) -> Vec<(usize, usize, f64)> {
    entries.sort_by_key(|&(r, c, _)| (c, r));
    let mut out: Vec<(usize, usize, f64)> = Vec::with_capacity(entries.len());
    for (r, c, v) in entries {
        match out.last_mut() {
            Some(last) if (last.0, last.1) == (r, c) => last.2 += v,
            _ => out.push((r, c, v)),
        }
    }
    out
}

impl HarmonicSolver {
    /// The solver of `model` with `fixed` DOFs, isotropic node springs `node_stiffness`
    /// (µN/mm, one per node) and `dashpots` (each along its own direction).
    pub fn new(
        model: &FemModel,
        fixed: &FixedDofs,
        node_stiffness: &[f64],
        dashpots: &[Dashpot],
        rayleigh: Rayleigh,
    ) -> Result<Self, FemError> {
        let none = RigidBodies::new(model.rest_positions(), &vec![None; model.node_count()])?;
        Self::with_rigid_bodies(model, fixed, node_stiffness, dashpots, rayleigh, &none)
    }

    /// As [`HarmonicSolver::new`], with `bodies` moving rigidly (`fem::rigid`): the system
    /// Tᵀ A T of the map T from the free DOFs of no body and six per body, without the
    /// tetrahedra inside a body. No node of a body may have a fixed DOF.
    pub fn with_rigid_bodies(
        model: &FemModel,
        fixed: &FixedDofs,
        node_stiffness: &[f64],
        dashpots: &[Dashpot],
        rayleigh: Rayleigh,
        bodies: &RigidBodies,
    ) -> Result<Self, FemError> {
        let n = model.node_count();
        for (what, expected, found) in [
            ("fixed DOF mask", 3 * n, fixed.len()),
            ("node stiffness", n, node_stiffness.len()),
        ] {
            if expected != found {
                return Err(FemError::LengthMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        for v in node_stiffness {
            non_negative("node stiffness (µN/mm)", *v)?;
        }
        check_dashpots(dashpots, n)?;
        rayleigh.validate()?;
        let reduction = Reduction::new(model.rest_positions(), fixed, bodies)?;
        let elastic = model.without_rigid_tets(bodies)?;
        let pattern = SparsePattern::new(&elastic);
        let mut state = CorotationalState::new(&elastic);
        state.update(&elastic, elastic.rest_positions())?;
        let mut lower = pattern.zero_values();
        let none_fixed = FixedDofs::from_nodes(n, &[])?;
        pattern.assemble(
            &elastic,
            &state,
            1.0,
            Some(node_stiffness),
            &none_fixed,
            &mut lower,
        )?;
        let masses = model.lumped_masses();
        let mut mass = Vec::with_capacity(3 * n);
        for d in 0..3 * n {
            let row = reduction.row(d);
            for &(i, a) in row {
                for &(j, b) in row {
                    mass.push((i, j, a * b * masses[d / 3]));
                }
            }
        }
        let mut damping = Vec::with_capacity(9 * dashpots.len());
        for dp in dashpots {
            let block = dp.block();
            for p in 0..3 {
                for q in 0..3 {
                    let (dp_row, dp_col) = (3 * dp.node as usize + p, 3 * dp.node as usize + q);
                    for &(i, a) in reduction.row(dp_row) {
                        for &(j, b) in reduction.row(dp_col) {
                            damping.push((i, j, a * block[(p, q)] * b));
                        }
                    }
                }
            }
        }
        let (mass, damping) = (merged(mass), merged(damping));
        // Tᵀ K T on a pattern that holds the mass and dashpot entries too, even where K has none
        let extra: Vec<(usize, usize)> = mass
            .iter()
            .chain(&damping)
            .map(|&(i, j, _)| (i, j))
            .collect();
        let sym = pattern.symbolic();
        let reduced = ReducedLower::new(&reduction, sym, &extra);
        let mut reduced_lower = vec![0.0; reduced.len()];
        reduced.reduce(&reduction, sym, &lower, &mut reduced_lower);
        let stiffness = reduced.to_full(&reduced_lower);
        let s = stiffness.symbolic();
        let position = |row: usize, col: usize| {
            let rows = &s.row_idx()[s.col_ptr()[col]..s.col_ptr()[col + 1]];
            s.col_ptr()[col] + rows.partition_point(|&r| r < row)
        };
        let on_pattern = |entries: Vec<(usize, usize, f64)>| OnPattern {
            positions: entries.iter().map(|&(i, j, _)| position(i, j)).collect(),
            entries,
        };
        let (mass, dashpot) = (on_pattern(mass), on_pattern(damping));
        let factoriser = ComplexSymmetric::analyse(s)?;
        Ok(HarmonicSolver {
            node_count: n,
            reduction,
            stiffness,
            mass,
            dashpot,
            rayleigh,
            factoriser,
        })
    }

    /// Factorises the system at angular frequency `omega` (rad/s) and gives `body` the solve
    /// with it (in place, over the free DOFs).
    pub(super) fn with_factor<R>(
        &self,
        omega: f64,
        body: impl FnOnce(&mut dyn FnMut(&mut [c64])) -> Result<R, FemError>,
    ) -> Result<R, FemError> {
        let beta = self.rayleigh.stiffness;
        let mut values: Vec<c64> = self
            .stiffness
            .val()
            .iter()
            .map(|&k| c64::new(k, omega * beta * k))
            .collect();
        for (&p, &(_, _, m)) in self.mass.positions.iter().zip(&self.mass.entries) {
            values[p] += c64::new(-omega * omega * m, omega * self.rayleigh.mass * m);
        }
        for (&p, &(_, _, c)) in self.dashpot.positions.iter().zip(&self.dashpot.entries) {
            values[p] += c64::new(0.0, omega * c);
        }
        self.factoriser.with_factor(&values, body)
    }

    /// Number of unknowns (free DOFs, or with rigid bodies those of no body and six per
    /// body).
    pub fn unknowns(&self) -> usize {
        self.reduction.unknowns()
    }

    /// Displacement amplitudes (mm, per node; zero on fixed DOFs) at angular frequency
    /// `omega` (rad/s) under real nodal force amplitudes `force` (µN, one per node).
    pub fn solve(
        &self,
        omega: f64,
        force: &[Vector3<f64>],
    ) -> Result<Vec<ComplexDisplacement>, FemError> {
        if force.len() != self.node_count {
            return Err(FemError::LengthMismatch {
                what: "harmonic force",
                expected: self.node_count,
                found: force.len(),
            });
        }
        if !(omega.is_finite() && omega >= 0.0) {
            return Err(FemError::InvalidParameter {
                what: "angular frequency (rad/s)",
                value: omega,
                expected: "finite and >= 0",
            });
        }
        let mut rhs: Vec<c64> = self
            .reduction
            .restrict(|d| force[d / 3][d % 3])
            .into_iter()
            .map(|f| c64::new(f, 0.0))
            .collect();
        self.with_factor(omega, |solve| {
            solve(&mut rhs);
            Ok(())
        })?;
        if let Some(i) = rhs
            .iter()
            .position(|u| !(u.re.is_finite() && u.im.is_finite()))
        {
            return Err(FemError::NonFinite {
                what: "harmonic displacement of unknown",
                index: i,
            });
        }
        let out = self.expand(&rhs);
        Ok(out)
    }

    /// The nodes' displacement amplitudes T q of the unknowns `q` (zero on fixed DOFs).
    pub(super) fn expand(&self, q: &[c64]) -> Vec<ComplexDisplacement> {
        (0..self.node_count)
            .map(|v| std::array::from_fn(|a| self.reduction.expand_at(q, 3 * v + a)))
            .collect()
    }
}
