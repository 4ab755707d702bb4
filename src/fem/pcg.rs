//! Conjugate gradients on a symmetric positive-definite operator (a matrix-free product, e.g.
//! `StepOperator::apply`), preconditioned by a (possibly stale) sparse Cholesky factor: the scheme of Courtecuisse,
//! Allard, Duriez & Cotin 2010 ("asynchronous preconditioners", SOFA's PCGLinearSolver with
//! an AsyncSparseLDLSolver preconditioner; docs/fem.md). With a factor of the
//! current matrix it converges in one iteration; with one a few steps old, in a few.
//! Buffers are allocated once per solver and reused; the residual is tested before the
//! preconditioner is applied, so the last iteration costs no preconditioner solve.

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

    /// Solves A x = b to ‖r‖ ≤ `tolerance`·‖b‖ from the initial guess in `x`, with
    /// `apply(v, out)` writing A v, preconditioned by `factor`; returns the number of
    /// iterations (`IterativeNotConverged` after `max_iterations`).
    pub fn solve(
        &mut self,
        mut apply: impl FnMut(&[f64], &mut [f64]) -> Result<(), FemError>,
        factor: &mut SparseCholesky,
        b: &[f64],
        x: &mut [f64],
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<usize, FemError> {
        let n = self.r.len();
        for (what, len) in [("right-hand side", b.len()), ("solution", x.len())] {
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
        if x.iter().all(|v| *v == 0.0) {
            // a zero initial guess needs no product
            self.r.copy_from_slice(b);
        } else {
            apply(x, &mut self.q)?;
            for ((r, b), q) in self.r.iter_mut().zip(b).zip(&self.q) {
                *r = b - q;
            }
        }
        let mut rz = 0.0;
        for iteration in 0..max_iterations {
            if dot(&self.r, &self.r).sqrt() <= tolerance * b_norm {
                return Ok(iteration);
            }
            self.z.copy_from_slice(&self.r);
            factor.solve_in_place(&mut self.z)?;
            let rz_new = dot(&self.r, &self.z);
            if iteration == 0 {
                self.p.copy_from_slice(&self.z);
            } else {
                let beta = rz_new / rz;
                for (p, z) in self.p.iter_mut().zip(&self.z) {
                    *p = z + beta * *p;
                }
            }
            rz = rz_new;
            apply(&self.p, &mut self.q)?;
            let alpha = rz / dot(&self.p, &self.q);
            for (((x, r), p), q) in x.iter_mut().zip(&mut self.r).zip(&self.p).zip(&self.q) {
                *x += alpha * p;
                *r -= alpha * q;
            }
        }
        let residual = dot(&self.r, &self.r).sqrt() / b_norm;
        if residual <= tolerance {
            return Ok(max_iterations);
        }
        Err(FemError::IterativeNotConverged {
            iterations: max_iterations,
            residual,
            tolerance,
        })
    }
}
