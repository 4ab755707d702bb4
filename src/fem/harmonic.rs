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
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use nalgebra::Vector3;

use super::assembly::SparsePattern;
use super::complex_symmetric::ComplexSymmetric;
use super::dashpot::{Dashpot, check_dashpots};
use super::dynamics::{Rayleigh, non_negative};
use super::error::FemError;
use super::fixed::FixedDofs;
use super::model::FemModel;
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

/// The m x m matrix of the (row, column, value) entries `entries` (all below m), duplicates
/// summed in their order: bucketed by column, then each column sorted by row. A counting sort
/// instead of faer's `try_new_from_triplets`, which took 0.03 s for the rigid package
/// check's half a million entries, timed alone (BENCHMARKS.md).
fn summed_columns(m: usize, entries: &[(usize, usize, f64)]) -> SparseColMat<usize, f64> {
    let mut start = vec![0usize; m + 1];
    for &(_, c, _) in entries {
        start[c + 1] += 1;
    }
    for c in 0..m {
        start[c + 1] += start[c];
    }
    let mut next = start.clone();
    let mut bucketed = vec![(0usize, 0.0f64); entries.len()];
    for &(r, c, v) in entries {
        bucketed[next[c]] = (r, v);
        next[c] += 1;
    }
    let mut col_ptr = Vec::with_capacity(m + 1);
    let (mut row_idx, mut values) = (Vec::new(), Vec::new());
    col_ptr.push(0);
    for c in 0..m {
        let column = &mut bucketed[start[c]..start[c + 1]];
        column.sort_by_key(|&(r, _)| r);
        for &(r, v) in column.iter() {
            match row_idx.last() {
                Some(&last) if last == r && values.len() > col_ptr[c] => {
                    if let Some(sum) = values.last_mut() {
                        *sum += v;
                    }
                }
                _ => {
                    row_idx.push(r);
                    values.push(v);
                }
            }
        }
        col_ptr.push(row_idx.len());
    }
    let symbolic = SymbolicSparseColMat::new_checked(m, m, col_ptr, None, row_idx);
    SparseColMat::new(symbolic, values)
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
        // Tᵀ K T from the lower triangle of K: each entry and its mirror
        let sym = pattern.symbolic();
        let mut triplets = Vec::with_capacity(2 * lower.len());
        reduction.lower_products(sym, |k, i, a, j, b, diagonal| {
            let v = a * lower[k] * b;
            triplets.push((i, j, v));
            if !diagonal {
                triplets.push((j, i, v));
            }
        });
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
        // the mass and dashpot entries belong to the pattern even where K has none
        triplets.extend(mass.iter().chain(&damping).map(|&(i, j, _)| (i, j, 0.0)));
        let stiffness = summed_columns(reduction.unknowns(), &triplets);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Duplicates are summed, also across the end of one column and the start of the next,
    /// rows come out sorted, and an empty column stays empty: the dense matrix of the entries.
    #[test]
    fn summed_columns_is_the_sum_of_the_entries() {
        let entries = [
            (2, 0, 1.0),
            (0, 0, 2.0),
            (2, 0, 0.5),
            (0, 2, 4.0),
            (1, 2, 3.0),
            (0, 2, -1.0),
            (2, 2, 7.0),
        ];
        let a = summed_columns(3, &entries);
        let mut dense = [[0.0; 3]; 3];
        for &(r, c, v) in &entries {
            dense[r][c] += v;
        }
        let s = a.symbolic();
        assert_eq!(s.col_ptr(), &[0, 2, 2, 5]);
        assert_eq!(s.row_idx(), &[0, 2, 0, 1, 2]);
        for (k, &row) in s.row_idx().iter().enumerate() {
            let col = s.col_ptr().partition_point(|&p| p <= k) - 1;
            assert_eq!(a.val()[k], dense[row][col]);
        }
    }
}
