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
use faer::sparse::{SparseColMat, Triplet};
use nalgebra::Vector3;

use super::assembly::SparsePattern;
use super::complex_symmetric::ComplexSymmetric;
use super::dashpot::{Dashpot, check_dashpots};
use super::dynamics::{Rayleigh, non_negative};
use super::error::FemError;
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::state::CorotationalState;

/// Complex amplitude of one node's displacement (mm), x, y, z.
pub type ComplexDisplacement = [c64; 3];

/// Harmonic solver for one model, one set of fixed DOFs and one set of node springs and
/// dashpots; immutable after construction, so frequencies can be solved in parallel.
#[derive(Debug)]
pub struct HarmonicSolver {
    pub(super) node_count: usize,
    /// Reduced index → DOF.
    pub(super) free: Vec<usize>,
    /// The full (both triangles) reduced pattern with the real stiffness values.
    pub(super) stiffness: SparseColMat<usize, f64>,
    /// Position of each reduced DOF's diagonal in the values.
    pub(super) diagonal: Vec<usize>,
    /// Lumped mass (g) of each reduced DOF.
    pub(super) mass: Vec<f64>,
    /// The dashpots' entries (g/s) between free DOFs, at their positions in the values.
    dashpot: Vec<(usize, f64)>,
    /// The same entries as (row, column, value) of the reduced system.
    pub(super) dashpot_entries: Vec<(usize, usize, f64)>,
    pub(super) rayleigh: Rayleigh,
    factoriser: ComplexSymmetric,
}

fn faer_error(stage: &str, e: impl std::fmt::Debug) -> FemError {
    FemError::Factorisation {
        message: format!("{stage}: {e:?}"),
    }
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
        let pattern = SparsePattern::new(model);
        let mut state = CorotationalState::new(model);
        state.update(model, model.rest_positions())?;
        let mut lower = pattern.zero_values();
        let none_fixed = FixedDofs::from_nodes(n, &[])?;
        pattern.assemble(
            model,
            &state,
            1.0,
            Some(node_stiffness),
            &none_fixed,
            &mut lower,
        )?;
        let free: Vec<usize> = (0..3 * n).filter(|&d| !fixed.is_fixed(d)).collect();
        let mut reduced = vec![usize::MAX; 3 * n];
        for (r, &d) in free.iter().enumerate() {
            reduced[d] = r;
        }
        let sym = pattern.symbolic();
        let mut triplets = Vec::with_capacity(2 * lower.len());
        for col in 0..3 * n {
            let rc = reduced[col];
            if rc == usize::MAX {
                continue;
            }
            for k in sym.col_ptr()[col]..sym.col_ptr()[col + 1] {
                let rr = reduced[sym.row_idx()[k]];
                if rr == usize::MAX {
                    continue;
                }
                triplets.push(Triplet::new(rr, rc, lower[k]));
                if rr != rc {
                    triplets.push(Triplet::new(rc, rr, lower[k]));
                }
            }
        }
        let m = free.len();
        let stiffness = SparseColMat::try_new_from_triplets(m, m, &triplets)
            .map_err(|e| faer_error("harmonic pattern", e))?;
        let s = stiffness.symbolic();
        let masses = model.lumped_masses();
        let mass = free.iter().map(|&d| masses[d / 3]).collect();
        let position = |row: usize, col: usize| {
            let rows = &s.row_idx()[s.col_ptr()[col]..s.col_ptr()[col + 1]];
            // a node's diagonal block is in the pattern
            s.col_ptr()[col] + rows.partition_point(|&r| r < row)
        };
        let diagonal = (0..m).map(|c| position(c, c)).collect();
        let mut dashpot = Vec::with_capacity(9 * dashpots.len());
        let mut dashpot_entries = Vec::with_capacity(9 * dashpots.len());
        for d in dashpots {
            let block = d.block();
            for i in 0..3 {
                for j in 0..3 {
                    let (row, col) = (
                        reduced[3 * d.node as usize + i],
                        reduced[3 * d.node as usize + j],
                    );
                    if row != usize::MAX && col != usize::MAX {
                        dashpot.push((position(row, col), block[(i, j)]));
                        dashpot_entries.push((row, col, block[(i, j)]));
                    }
                }
            }
        }
        let factoriser = ComplexSymmetric::analyse(s)?;
        Ok(HarmonicSolver {
            node_count: n,
            free,
            stiffness,
            diagonal,
            mass,
            dashpot,
            dashpot_entries,
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
        for (&p, &m) in self.diagonal.iter().zip(&self.mass) {
            values[p] += c64::new(-omega * omega * m, omega * self.rayleigh.mass * m);
        }
        for &(p, c) in &self.dashpot {
            values[p] += c64::new(0.0, omega * c);
        }
        self.factoriser.with_factor(&values, body)
    }

    /// Number of unknowns (free DOFs).
    pub fn unknowns(&self) -> usize {
        self.free.len()
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
            .free
            .iter()
            .map(|&d| c64::new(force[d / 3][d % 3], 0.0))
            .collect();
        self.with_factor(omega, |solve| {
            solve(&mut rhs);
            Ok(())
        })?;
        let mut out = vec![[c64::new(0.0, 0.0); 3]; self.node_count];
        for (&d, u) in self.free.iter().zip(&rhs) {
            if !(u.re.is_finite() && u.im.is_finite()) {
                return Err(FemError::NonFinite {
                    what: "harmonic displacement of DOF",
                    index: d,
                });
            }
            out[d / 3][d % 3] = *u;
        }
        Ok(out)
    }
}
