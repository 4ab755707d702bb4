//! A frequency sweep of the harmonic system from one reduced model, each frequency checked on
//! the full system (docs/fem.md, "Reduced-order sweep").
//!
//! A sweep solves [K(1 + iωβ) + iω(αM + C) − ω²M] û = F̂ at many ω. Factorising the complex
//! matrix at each ω costs one sparse factorisation per frequency; instead, the sweep projects
//! the system on a small real subspace V (Galerkin, Vᵀ A(ω) V q = Vᵀ F̂, û = V q) built from
//! the response's Taylor coefficients about a few shift frequencies ω_s (one factorisation of
//! A(ω_s) each, the solver's symbolic analysis reused; `HarmonicSolver::moments`), their real
//! and imaginary parts orthonormalised. Every reduced solution is then checked on the full
//! system by its relative residual ‖F̂ − A(ω)û‖ / ‖F̂‖; the first two shifts sit at a quarter
//! and three quarters of the logarithmic range, and while a frequency exceeds the tolerance a
//! new shift is placed at the worst one. A frequency still above the tolerance after the last
//! shift is solved directly by [`HarmonicSolver::solve`]. So every returned response satisfies
//! the full system to the tolerance (or is the direct solution), whatever the subspace.

use faer::c64;
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

use super::error::FemError;
use super::harmonic::{ComplexDisplacement, HarmonicSolver};

/// How far the reduced model is trusted and how it grows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepOptions {
    /// Largest relative residual ‖F̂ − A(ω)û‖ / ‖F̂‖ accepted at a frequency.
    pub residual_tolerance: f64,
    /// Taylor coefficients of the response taken at each shift (two real vectors each).
    pub moments_per_shift: usize,
    /// Most shifts; frequencies still above the tolerance after them are solved directly.
    pub max_shifts: usize,
}

impl Default for SweepOptions {
    /// A relative residual of 1e-3 keeps the stapes velocity of the default atlas and of the
    /// sample packages within 1e-5 dB of the direct solves (docs/fem.md); ten coefficients
    /// per shift make the first two shifts, factorised in parallel, enough for them, with
    /// elastic or rigid ossicles (eight left case-003's rigid package a third shift).
    fn default() -> Self {
        SweepOptions {
            residual_tolerance: 1e-3,
            moments_per_shift: 10,
            max_shifts: 8,
        }
    }
}

/// What the sweep did.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepReport {
    /// Dimension of the reduced model.
    pub basis_size: usize,
    /// The shifts (Hz), in the order they were placed.
    pub shifts_hz: Vec<f64>,
    /// Frequencies solved directly (one factorisation each) because the reduced model missed the
    /// tolerance there.
    pub direct_solves: usize,
    /// Largest relative residual of the returned responses (0 where solved directly).
    pub max_relative_residual: f64,
}

/// The responses of a sweep, one per angular frequency, and its report.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// Displacement amplitudes (mm, per node; zero on fixed DOFs), one vector per frequency.
    pub responses: Vec<Vec<ComplexDisplacement>>,
    pub report: SweepReport,
}

/// An orthonormal basis V (columns over the unknowns) with K V, M V and C V and the projections
/// Vᵀ K V, Vᵀ M V, Vᵀ C V and Vᵀ F̂, grown one column at a time.
struct Basis {
    v: Vec<Vec<f64>>,
    kv: Vec<Vec<f64>>,
    mv: Vec<Vec<f64>>,
    cv: Vec<Vec<f64>>,
    /// Row-major r x r projections (symmetric).
    kr: Vec<Vec<f64>>,
    mr: Vec<Vec<f64>>,
    cr: Vec<Vec<f64>>,
    fr: Vec<f64>,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Basis {
    fn new() -> Self {
        Basis {
            v: Vec::new(),
            kv: Vec::new(),
            mv: Vec::new(),
            cv: Vec::new(),
            kr: Vec::new(),
            mr: Vec::new(),
            cr: Vec::new(),
            fr: Vec::new(),
        }
    }

    fn len(&self) -> usize {
        self.v.len()
    }

    /// Orthogonalises each of `candidates` in turn against the basis (modified Gram-Schmidt,
    /// twice) and adds it, skipping those that lie in the basis to rounding; then forms the
    /// new columns' products with K, M and C and their projections, the columns side by side.
    fn extend(&mut self, solver: &HarmonicSolver, force: &[f64], candidates: Vec<Vec<f64>>) {
        let first = self.v.len();
        for mut w in candidates {
            let before = dot(&w, &w).sqrt();
            if !(before.is_finite() && before > 0.0) {
                continue;
            }
            for _ in 0..2 {
                for v in &self.v {
                    let c = dot(v, &w);
                    w.iter_mut().zip(v).for_each(|(x, y)| *x -= c * y);
                }
            }
            let after = dot(&w, &w).sqrt();
            if after <= 1e-10 * before {
                continue;
            }
            w.iter_mut().for_each(|x| *x /= after);
            self.v.push(w);
        }
        let products: Vec<[Vec<f64>; 3]> = self.v[first..]
            .par_iter()
            .map(|w| {
                [
                    solver.stiffness_times(w),
                    solver.mass.times(w),
                    solver.dashpot.times(w),
                ]
            })
            .collect();
        // column j of the projections: its entries against every column up to j
        let columns: Vec<[Vec<f64>; 3]> = (first..self.v.len())
            .into_par_iter()
            .zip(&products)
            .map(|(j, [kw, mw, cw])| {
                let against =
                    |pw: &[f64]| -> Vec<f64> { self.v[..=j].iter().map(|v| dot(v, pw)).collect() };
                [against(kw), against(mw), against(cw)]
            })
            .collect();
        for (j, ([k, m, c], [kw, mw, cw])) in (first..).zip(columns.into_iter().zip(products)) {
            for (of, column) in [(&mut self.kr, &k), (&mut self.mr, &m), (&mut self.cr, &c)] {
                for (row, &x) in of.iter_mut().zip(column) {
                    row.push(x);
                }
                of.push(column.clone());
            }
            self.fr.push(dot(&self.v[j], force));
            self.kv.push(kw);
            self.mv.push(mw);
            self.cv.push(cw);
        }
    }

    /// The reduced solution at `omega`, its relative residual on the full system and the
    /// full-space displacement (free DOFs).
    fn solve(
        &self,
        solver: &HarmonicSolver,
        force: &[f64],
        force_norm: f64,
        omega: f64,
    ) -> Option<(f64, Vec<c64>)> {
        let r = self.len();
        let (alpha, beta) = (solver.rayleigh.mass, solver.rayleigh.stiffness);
        let stiffness = c64::new(1.0, omega * beta);
        let mass = c64::new(-omega * omega, omega * alpha);
        let damping = c64::new(0.0, omega);
        // a few dozen unknowns: nalgebra's LU, not faer's, whose blocked products reserve a
        // packing buffer of twice the L3 per thread (`fem::variant`), which a process under
        // an address-space limit cannot have
        let a = DMatrix::<c64>::from_fn(r, r, |i, j| {
            stiffness * self.kr[i][j] + mass * self.mr[i][j] + damping * self.cr[i][j]
        });
        let b = DVector::<c64>::from_fn(r, |i, _| c64::new(self.fr[i], 0.0));
        let q = a.lu().solve(&b)?;
        let n = force.len();
        let mut u = vec![c64::new(0.0, 0.0); n];
        let mut au = vec![c64::new(0.0, 0.0); n];
        for j in 0..r {
            let qj = q[j];
            if !(qj.re.is_finite() && qj.im.is_finite()) {
                return None;
            }
            let (ks, ms, cs) = (stiffness * qj, mass * qj, damping * qj);
            for d in 0..n {
                let v = self.v[j][d];
                u[d] += qj * v;
                au[d] += ks * self.kv[j][d] + ms * self.mv[j][d] + cs * self.cv[j][d];
            }
        }
        let residual = force
            .iter()
            .zip(&au)
            .map(|(f, a)| (c64::new(*f, 0.0) - a).norm_sqr())
            .sum::<f64>()
            .sqrt();
        Some((residual / force_norm, u))
    }
}

impl HarmonicSolver {
    /// The responses at every angular frequency of `omegas` (rad/s) under real nodal force
    /// amplitudes `force` (µN, one per node), from a reduced model checked on the full system
    /// (module docs); the same responses as [`HarmonicSolver::solve`] at each frequency, to
    /// `options.residual_tolerance`.
    pub fn sweep(
        &self,
        omegas: &[f64],
        force: &[Vector3<f64>],
        options: &SweepOptions,
    ) -> Result<Sweep, FemError> {
        if force.len() != self.node_count {
            return Err(FemError::LengthMismatch {
                what: "harmonic force",
                expected: self.node_count,
                found: force.len(),
            });
        }
        if let Some(&omega) = omegas.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return Err(FemError::InvalidParameter {
                what: "angular frequency (rad/s)",
                value: omega,
                expected: "finite and >= 0",
            });
        }
        if !(options.residual_tolerance.is_finite() && options.residual_tolerance > 0.0) {
            return Err(FemError::InvalidParameter {
                what: "sweep residual tolerance",
                value: options.residual_tolerance,
                expected: "finite and > 0",
            });
        }
        let f = self.reduction.restrict(|d| force[d / 3][d % 3]);
        let force_norm = dot(&f, &f).sqrt();
        let zero = vec![[c64::new(0.0, 0.0); 3]; self.node_count];
        if force_norm == 0.0 {
            return Ok(Sweep {
                responses: vec![zero; omegas.len()],
                report: SweepReport {
                    basis_size: 0,
                    shifts_hz: Vec::new(),
                    direct_solves: 0,
                    max_relative_residual: 0.0,
                },
            });
        }
        let mut basis = Basis::new();
        let mut shifts: Vec<f64> = Vec::new();
        let mut results: Vec<Option<(f64, Vec<c64>)>> = vec![None; omegas.len()];
        // the first round: two shifts at a quarter and three quarters of the (logarithmic)
        // range, factorised in parallel; then each round places up to two more
        let mut round = initial_shifts(omegas);
        round.truncate(options.max_shifts);
        while !round.is_empty() {
            let moments: Vec<Vec<Vec<c64>>> = round
                .par_iter()
                .map(|&shift| self.moments(&f, shift, options.moments_per_shift))
                .collect::<Result<_, _>>()?;
            shifts.extend(&round);
            let parts = moments.iter().flatten().flat_map(|u| {
                [
                    u.iter().map(|z| z.re).collect(),
                    u.iter().map(|z| z.im).collect(),
                ]
            });
            basis.extend(self, &f, parts.collect());
            results = omegas
                .par_iter()
                .map(|&omega| basis.solve(self, &f, force_norm, omega))
                .collect();
            let budget = options.max_shifts.saturating_sub(shifts.len()).min(2);
            round = next_shifts(
                omegas,
                &results,
                options.residual_tolerance,
                &shifts,
                budget,
            );
        }
        let mut direct_solves = 0;
        let mut max_relative_residual = 0.0f64;
        let mut responses = Vec::with_capacity(omegas.len());
        for (result, &omega) in results.into_iter().zip(omegas) {
            match result {
                Some((residual, u)) if residual <= options.residual_tolerance => {
                    max_relative_residual = max_relative_residual.max(residual);
                    responses.push(self.expand(&u));
                }
                _ => {
                    direct_solves += 1;
                    responses.push(self.solve(omega, force)?);
                }
            }
        }
        Ok(Sweep {
            responses,
            report: SweepReport {
                basis_size: basis.len(),
                shifts_hz: shifts
                    .iter()
                    .map(|w| w / (2.0 * std::f64::consts::PI))
                    .collect(),
                direct_solves,
                max_relative_residual,
            },
        })
    }

    /// The first `count` Taylor coefficients of the response about the angular frequency
    /// `shift`: with δ = ω − ω_s,
    /// A(ω) = A_s + δA₁ + δ²A₂, A₁ = iD − 2ω_s M, A₂ = −M, D = βK + αM + C, the coefficients
    /// solve A_s u₀ = F̂ and A_s u_k = −A₁u_{k−1} + M u_{k−2}, one factorisation of A_s.
    fn moments(&self, force: &[f64], shift: f64, count: usize) -> Result<Vec<Vec<c64>>, FemError> {
        let (alpha, beta) = (self.rayleigh.mass, self.rayleigh.stiffness);
        self.with_factor(shift, |solve| {
            let mut out: Vec<Vec<c64>> = Vec::with_capacity(count);
            let mut u: Vec<c64> = force.iter().map(|&x| c64::new(x, 0.0)).collect();
            solve(&mut u);
            out.push(u);
            // M u_{k−2}, the previous step's M u_{k−1}
            let mut older: Option<(Vec<f64>, Vec<f64>)> = None;
            for k in 1..count {
                let prev = &out[k - 1];
                let (re, im): (Vec<f64>, Vec<f64>) = prev.iter().map(|z| (z.re, z.im)).unzip();
                let (k_re, k_im) = (self.stiffness_times(&re), self.stiffness_times(&im));
                let (c_re, c_im) = (self.dashpot.times(&re), self.dashpot.times(&im));
                let (m_re, m_im) = (self.mass.times(&re), self.mass.times(&im));
                let mut rhs: Vec<c64> = (0..prev.len())
                    .map(|d| {
                        let d_re = beta * k_re[d] + alpha * m_re[d] + c_re[d];
                        let d_im = beta * k_im[d] + alpha * m_im[d] + c_im[d];
                        // −A₁u = −i D u + 2ω_s M u
                        c64::new(d_im, -d_re) + c64::new(m_re[d], m_im[d]) * (2.0 * shift)
                    })
                    .collect();
                if let Some((o_re, o_im)) = &older {
                    for (r, (a, b)) in rhs.iter_mut().zip(o_re.iter().zip(o_im)) {
                        *r += c64::new(*a, *b);
                    }
                }
                older = Some((m_re, m_im));
                solve(&mut rhs);
                out.push(rhs);
            }
            Ok(out)
        })
    }

    /// K x over the unknowns (the full symmetric pattern is stored).
    fn stiffness_times(&self, x: &[f64]) -> Vec<f64> {
        let s = self.stiffness.symbolic();
        let values = self.stiffness.val();
        let mut y = vec![0.0; x.len()];
        for (col, &xc) in x.iter().enumerate() {
            for k in s.col_ptr()[col]..s.col_ptr()[col + 1] {
                y[s.row_idx()[k]] += values[k] * xc;
            }
        }
        y
    }
}

/// Two shifts at a quarter and three quarters of the logarithmic range of `omegas` (one at
/// the frequency itself when there is only one; none when there is none).
fn initial_shifts(omegas: &[f64]) -> Vec<f64> {
    let positive: Vec<f64> = omegas.iter().copied().filter(|w| *w > 0.0).collect();
    let (Some(lo), Some(hi)) = (
        positive.iter().copied().reduce(f64::min),
        positive.iter().copied().reduce(f64::max),
    ) else {
        return if omegas.is_empty() {
            Vec::new()
        } else {
            vec![0.0]
        };
    };
    if hi <= lo * (1.0 + 1e-9) {
        return vec![lo];
    }
    let (a, b) = (lo.ln(), hi.ln());
    vec![(a + 0.25 * (b - a)).exp(), (a + 0.75 * (b - a)).exp()]
}

/// Up to `budget` new shifts: the worst frequency of each run of consecutive frequencies above
/// `tolerance` (unsolvable ones count as above), worst runs first, skipping frequencies that
/// are shifts already.
fn next_shifts(
    omegas: &[f64],
    results: &[Option<(f64, Vec<c64>)>],
    tolerance: f64,
    shifts: &[f64],
    budget: usize,
) -> Vec<f64> {
    let residual = |k: usize| results[k].as_ref().map_or(f64::INFINITY, |r| r.0);
    let mut order: Vec<usize> = (0..omegas.len()).collect();
    order.sort_by(|&a, &b| omegas[a].total_cmp(&omegas[b]));
    let mut worst_of_runs: Vec<(f64, f64)> = Vec::new();
    let mut run: Option<(f64, f64)> = None;
    for &k in &order {
        let r = residual(k);
        if r > tolerance && !shifts.contains(&omegas[k]) {
            run = Some(match run {
                Some((worst, w)) if worst >= r => (worst, w),
                _ => (r, omegas[k]),
            });
        } else if let Some(done) = run.take() {
            worst_of_runs.push(done);
        }
    }
    worst_of_runs.extend(run);
    worst_of_runs.sort_by(|a, b| b.0.total_cmp(&a.0));
    worst_of_runs
        .into_iter()
        .take(budget)
        .map(|(_, w)| w)
        .collect()
}
