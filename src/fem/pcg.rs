//! Conjugate gradients on a symmetric positive-definite matrix given by its lower triangle,
//! preconditioned by a (possibly stale) sparse Cholesky factor: the scheme of Courtecuisse,
//! Allard, Duriez & Cotin 2010 ("asynchronous preconditioners", SOFA's PCGLinearSolver with
//! an AsyncSparseLDLSolver preconditioner; mechanics-metrics §2.6). With a factor of the
//! current matrix it converges in one iteration; with one a few steps old, in a few.
//! Buffers are allocated once per solver and reused.

use faer::sparse::SparseColMatRef;

use super::cholesky::SparseCholesky;
use super::error::FemError;

/// Reusable work vectors of the preconditioned conjugate gradient.
#[derive(Debug, Clone)]
pub struct Pcg {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
}

/// y = A x for A symmetric, stored as its lower triangle (CSC).
fn symmetric_product(a: SparseColMatRef<'_, usize, f64>, x: &[f64], y: &mut [f64]) {
    y.fill(0.0);
    let (col_ptr, row_idx, val) = (a.symbolic().col_ptr(), a.symbolic().row_idx(), a.val());
    for j in 0..a.ncols() {
        let xj = x[j];
        let mut acc = 0.0;
        for k in col_ptr[j]..col_ptr[j + 1] {
            let i = row_idx[k];
            y[i] += val[k] * xj;
            if i != j {
                acc += val[k] * x[i];
            }
        }
        y[j] += acc;
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Pcg {
    /// Work vectors for `n` unknowns.
    pub fn new(n: usize) -> Self {
        Pcg {
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
        }
    }

    /// Solves A x = b to ‖r‖ ≤ `tolerance`·‖b‖ from the initial guess in `x`, preconditioned
    /// by `factor`; returns the number of iterations (`IterativeNotConverged` after
    /// `max_iterations`).
    pub fn solve(
        &mut self,
        a: SparseColMatRef<'_, usize, f64>,
        factor: &mut SparseCholesky,
        b: &[f64],
        x: &mut [f64],
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<usize, FemError> {
        let n = a.nrows();
        for (what, len) in [
            ("right-hand side", b.len()),
            ("solution", x.len()),
            ("work", self.r.len()),
        ] {
            if len != n {
                return Err(FemError::LengthMismatch {
                    what,
                    expected: n,
                    found: len,
                });
            }
        }
        let b_norm = dot(b, b).sqrt();
        if b_norm == 0.0 {
            x.fill(0.0);
            return Ok(0);
        }
        symmetric_product(a, x, &mut self.q);
        for ((r, b), q) in self.r.iter_mut().zip(b).zip(&self.q) {
            *r = b - q;
        }
        self.z.copy_from_slice(&self.r);
        factor.solve_in_place(&mut self.z)?;
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        let mut residual = dot(&self.r, &self.r).sqrt() / b_norm;
        for iteration in 0..=max_iterations {
            if residual <= tolerance {
                return Ok(iteration);
            }
            if iteration == max_iterations {
                break;
            }
            symmetric_product(a, &self.p, &mut self.q);
            let alpha = rz / dot(&self.p, &self.q);
            for (((x, r), p), q) in x.iter_mut().zip(&mut self.r).zip(&self.p).zip(&self.q) {
                *x += alpha * p;
                *r -= alpha * q;
            }
            residual = dot(&self.r, &self.r).sqrt() / b_norm;
            self.z.copy_from_slice(&self.r);
            factor.solve_in_place(&mut self.z)?;
            let rz_new = dot(&self.r, &self.z);
            let beta = rz_new / rz;
            rz = rz_new;
            for (p, z) in self.p.iter_mut().zip(&self.z) {
                *p = z + beta * *p;
            }
        }
        Err(FemError::IterativeNotConverged {
            iterations: max_iterations,
            residual,
            tolerance,
        })
    }
}
