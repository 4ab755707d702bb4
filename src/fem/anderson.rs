//! Anderson acceleration of a fixed-point iteration x ← x + g(x) (Walker & Ni 2011, "Anderson
//! acceleration for fixed-point iterations", SIAM J. Numer. Anal. 49(4); the "type II" form).
//!
//! The static solver's chord steps (one factorised tangent T kept over several iterations,
//! g = T⁻¹ r(x)) converge only linearly, because T is not the exact Jacobian (the warped
//! tangent has no dR/dx term and drops compressive membrane stress): 0.2-0.56 per iteration on
//! the eardrum's static curve. Anderson mixing keeps the last few pairs (Δx, Δg) and takes the
//! step that minimises the linearised next g over their span,
//!
//! γ = argmin ‖g_k − ΔG γ‖,  x_{k+1} = x_k + g_k − (ΔX + ΔG) γ,
//!
//! which turns a linear rate into a much faster one at the cost of a small least-squares
//! problem per iteration; with an empty history it is the plain step. The history belongs to
//! one map g: it must be cleared when T is refactorised.

use nalgebra::{DMatrix, DVector};

/// The history of one accelerated iteration.
#[derive(Debug)]
pub(crate) struct Anderson {
    depth: usize,
    /// The previous iterate and step (flattened), once there is one.
    last: Option<(Vec<f64>, Vec<f64>)>,
    /// Columns Δx_i = x_{i+1} − x_i and Δg_i = g_{i+1} − g_i, oldest first.
    dx: Vec<Vec<f64>>,
    dg: Vec<Vec<f64>>,
}

impl Anderson {
    /// Mixing over the last `depth` differences; 0 leaves every step as it is.
    pub(crate) fn new(depth: usize) -> Self {
        Anderson {
            depth,
            last: None,
            dx: Vec::new(),
            dg: Vec::new(),
        }
    }

    /// Forgets the history (the map g changed).
    pub(crate) fn clear(&mut self) {
        self.last = None;
        self.dx.clear();
        self.dg.clear();
    }

    /// Replaces the plain step `g` (taken at iterate `x`) by the accelerated one.
    pub(crate) fn accelerate(&mut self, x: &[f64], g: &mut [f64]) {
        if self.depth == 0 {
            return;
        }
        if let Some((x0, g0)) = self.last.take() {
            self.dx
                .push(x.iter().zip(&x0).map(|(a, b)| a - b).collect());
            self.dg
                .push(g.iter().zip(&g0).map(|(a, b)| a - b).collect());
            if self.dx.len() > self.depth {
                self.dx.remove(0);
                self.dg.remove(0);
            }
        }
        self.last = Some((x.to_vec(), g.to_vec()));
        let m = self.dg.len();
        if m == 0 {
            return;
        }
        // the normal equations ΔGᵀΔG γ = ΔGᵀ g, m ≤ depth, solved by SVD with the directions
        // of singular values under 1e-12 of the largest dropped (nearly parallel differences)
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let gram = DMatrix::from_fn(m, m, |i, j| dot(&self.dg[i], &self.dg[j]));
        let rhs = DVector::from_fn(m, |i, _| dot(&self.dg[i], g));
        let svd = gram.svd(true, true);
        let largest = svd.singular_values.max();
        let Ok(gamma) = svd.solve(&rhs, 1e-12 * largest) else {
            self.clear();
            return;
        };
        let mut accelerated = g.to_vec();
        for (j, c) in gamma.iter().enumerate() {
            for (a, (x, y)) in accelerated
                .iter_mut()
                .zip(self.dx[j].iter().zip(&self.dg[j]))
            {
                *a -= c * (x + y);
            }
        }
        if accelerated.iter().all(|v| v.is_finite()) {
            g.copy_from_slice(&accelerated);
        } else {
            self.clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear fixed-point iteration with a poor approximate inverse: x ← x + P(b − A x),
    /// the plain iteration contracting at 0.9 per step. Anderson's iterates reach the exact
    /// solution in at most (dimension + 1) steps (a Krylov method on a linear map), the plain
    /// ones are still 0.9^k away.
    #[test]
    fn a_linear_iteration_converges_in_dimension_plus_one_steps() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0]);
        let b = DVector::from_vec(vec![1.0, -2.0, 0.5]);
        let exact = a.clone().lu().solve(&b).unwrap();
        let p = 0.1 / 4.0; // a scaled identity as the approximate inverse
        let step = |x: &DVector<f64>| (&b - &a * x) * p;
        let run = |depth: usize, iterations: usize| {
            let mut anderson = Anderson::new(depth);
            let mut x = DVector::zeros(3);
            for _ in 0..iterations {
                let mut g: Vec<f64> = step(&x).iter().copied().collect();
                anderson.accelerate(x.as_slice(), &mut g);
                x += DVector::from_vec(g);
            }
            (x - &exact).norm() / exact.norm()
        };
        assert!(run(3, 5) < 1e-10, "{}", run(3, 5));
        assert!(run(0, 5) > 0.3, "{}", run(0, 5));
        // with the history cleared at every step it is the plain iteration
        let mut anderson = Anderson::new(3);
        let mut x = DVector::zeros(3);
        for _ in 0..5 {
            anderson.clear();
            let mut g: Vec<f64> = step(&x).iter().copied().collect();
            anderson.accelerate(x.as_slice(), &mut g);
            x += DVector::from_vec(g);
        }
        assert!(((x - &exact).norm() / exact.norm() - run(0, 5)).abs() < 1e-12);
    }
}
