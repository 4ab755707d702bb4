//! The corotated constant-strain element shared by tetrahedra and membrane triangles.
//!
//! Rest data are the shape-function gradients g_a (1/mm, world rest frame), a measure w (the
//! volume V for a tetrahedron, h·A for a membrane, mm³), the Lamé pair and the rest unit normal
//! N (zero for a tetrahedron, so that the in-plane projector P = I − N Nᵀ is the identity).
//! Linear stiffness blocks (Voigt form K_e = w·BᵀDB, docs/fem.md, written per
//! node pair): K_ab = w(λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) P).
//! Corotation (Müller & Gross 2004; Nesme et al. 2005): with element rotation R,
//! f = −R K (Rᵀx − X). Using F = Σ x_a g_aᵀ and Σ X_a g_aᵀ = P this is the stress form
//! H = RᵀF − P, ε = P sym(H) P, σ = λ tr(ε) P + 2μ ε, f_a = −w R σ g_a; the warped tangent is
//! R K_ab Rᵀ = w(λ ĝ_a ĝ_bᵀ + μ ĝ_b ĝ_aᵀ + μ (g_a·g_b)(I − n̂ n̂ᵀ)) with ĝ = R g, n̂ = R N.

use nalgebra::{Matrix3, Point3, Vector3};

use super::material::Lame;

/// The tensile part σ⁺ = Σ max(λ_i, 0) v_i v_iᵀ of a symmetric stress. For a membrane
/// (`normal` ≠ 0) σ lies in the plane ⟂ normal and its 2×2 eigenproblem is solved in closed
/// form; otherwise by a 3×3 symmetric eigendecomposition.
fn tensile_part(sigma: &Matrix3<f64>, normal: &Vector3<f64>) -> Matrix3<f64> {
    let Some(n) = normal.try_normalize(1e-12) else {
        let eig = sigma.symmetric_eigen();
        let mut out = Matrix3::zeros();
        for (k, &value) in eig.eigenvalues.iter().enumerate() {
            if value > 0.0 {
                let v = eig.eigenvectors.column(k);
                out += v * v.transpose() * value;
            }
        }
        return out;
    };
    let helper = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let t1 = n.cross(&helper).normalize();
    let t2 = n.cross(&t1);
    let (a, b, c) = (
        t1.dot(&(sigma * t1)),
        t1.dot(&(sigma * t2)),
        t2.dot(&(sigma * t2)),
    );
    let mean = 0.5 * (a + c);
    let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = (mean + radius, mean - radius);
    // eigenvector of l1 in the (t1, t2) basis
    let (x, y) = if radius <= 1e-300 {
        (1.0, 0.0)
    } else if (a - c) >= 0.0 {
        let v = Vector3::new(a - l2, b, 0.0);
        let norm = (v.x * v.x + v.y * v.y).sqrt();
        (v.x / norm, v.y / norm)
    } else {
        let v = Vector3::new(b, l1 - a, 0.0);
        let norm = (v.x * v.x + v.y * v.y).sqrt();
        (v.x / norm, v.y / norm)
    };
    let v1 = t1 * x + t2 * y;
    let v2 = n.cross(&v1);
    v1 * v1.transpose() * l1.max(0.0) + v2 * v2.transpose() * l2.max(0.0)
}

/// Rest data of one corotated constant-strain element with `N` nodes.
#[derive(Debug, Clone)]
pub(crate) struct CorotElement<const N: usize> {
    pub nodes: [u32; N],
    pub grads: [Vector3<f64>; N],
    pub measure: f64,
    pub lame: Lame,
    pub rest_normal: Vector3<f64>,
}

impl<const N: usize> CorotElement<N> {
    /// Deformation gradient F = Σ x_a g_aᵀ (maps the rest plane only, for a membrane).
    pub fn deformation(&self, x: &[Point3<f64>]) -> Matrix3<f64> {
        let mut f = Matrix3::zeros();
        for (node, g) in self.nodes.iter().zip(&self.grads) {
            f += x[*node as usize].coords * g.transpose();
        }
        f
    }

    fn projector(&self) -> Matrix3<f64> {
        Matrix3::identity() - self.rest_normal * self.rest_normal.transpose()
    }

    /// Corotated elastic nodal forces (µN) for rotation `r` and deformation gradient `f`.
    pub fn forces(&self, r: &Matrix3<f64>, f: &Matrix3<f64>) -> [Vector3<f64>; N] {
        let rs = r * self.stress(r, f) * (-self.measure);
        self.grads.map(|g| rs * g)
    }

    /// Corotated small-strain stress σ (Pa) in the rest frame: H = RᵀF − P,
    /// ε = P sym(H) P, σ = λ tr(ε) P + 2μ ε.
    pub fn stress(&self, r: &Matrix3<f64>, f: &Matrix3<f64>) -> Matrix3<f64> {
        self.linear_stress(&(r.transpose() * f - self.projector()))
    }

    /// The material law σ(H) = λ tr(ε) P + 2μ ε, ε = P sym(H) P, of a displacement gradient
    /// `h` in the rest frame (P = I for a tetrahedron, whose product is skipped).
    fn linear_stress(&self, h: &Matrix3<f64>) -> Matrix3<f64> {
        let sym = (h + h.transpose()) * 0.5;
        if N == 4 {
            Matrix3::identity() * (self.lame.lambda * sym.trace()) + sym * (2.0 * self.lame.mu)
        } else {
            let p = self.projector();
            let eps = p * sym * p;
            p * (self.lame.lambda * eps.trace()) + eps * (2.0 * self.lame.mu)
        }
    }

    /// The gradient Σ_a p_a g_aᵀ of the nodal vectors `p` (one per node) over the element.
    pub fn gradient(&self, p: &[Vector3<f64>; N]) -> Matrix3<f64> {
        p.iter()
            .zip(&self.grads)
            .fold(Matrix3::zeros(), |m, (p, g)| m + p * g.transpose())
    }

    /// The tensile part σ⁺ of the element's stress (Pa) at rotation `r` and deformation `f`.
    pub fn tension(&self, r: &Matrix3<f64>, f: &Matrix3<f64>) -> Matrix3<f64> {
        tensile_part(&self.stress(r, f), &self.rest_normal)
    }

    /// `scale` times the warped stiffness R K Rᵀ applied to the nodal vectors `p` (one per
    /// node): (K p)_a = w R σ(Rᵀ δF) g_a with δF = Σ_b p_b g_bᵀ and σ the material law of
    /// [`CorotElement::stress`] (without its rest offset), equal to Σ_b
    /// [`CorotElement::warped_blocks`] p_b.
    pub fn warped_product(
        &self,
        r: &Matrix3<f64>,
        p: &[Vector3<f64>; N],
        scale: f64,
    ) -> [Vector3<f64>; N] {
        let df = self.gradient(p);
        let rs = r * self.linear_stress(&(r.transpose() * df)) * (self.measure * scale);
        self.grads.map(|g| rs * g)
    }

    /// Visits the stress (initial-stress, geometric) stiffness of the element for every local
    /// pair a ≤ b as the scalar w·g_aᵀ σ⁺ g_b (the block is that times I₃), with σ⁺ the
    /// tensile part of σ (negative principal stresses dropped, so the term is positive
    /// semi-definite: a membrane has no stiffness in compression, it wrinkles).
    pub fn tensile_stress_stiffness(
        &self,
        r: &Matrix3<f64>,
        f: &Matrix3<f64>,
        mut visit: impl FnMut(usize, usize, f64),
    ) {
        let tension = self.tension(r, f);
        for a in 0..N {
            let ta = tension * self.grads[a];
            for b in a..N {
                visit(a, b, self.measure * ta.dot(&self.grads[b]));
            }
        }
    }

    /// Visits the warped stiffness blocks R K_ab Rᵀ (µN/mm, rows of node a, columns of node
    /// b) for every local pair a ≤ b, in the order (0,0), (0,1), …, (0,N−1), (1,1), ….
    pub fn warped_blocks(
        &self,
        r: &Matrix3<f64>,
        mut visit: impl FnMut(usize, usize, Matrix3<f64>),
    ) {
        let g = self.grads.map(|g| r * g);
        let n = r * self.rest_normal;
        let plane = (Matrix3::identity() - n * n.transpose()) * self.lame.mu;
        let (lambda, mu, w) = (self.lame.lambda, self.lame.mu, self.measure);
        for a in 0..N {
            for b in a..N {
                let dot = self.grads[a].dot(&self.grads[b]);
                let blk =
                    (g[a] * g[b].transpose() * lambda + g[b] * g[a].transpose() * mu + plane * dot)
                        * w;
                visit(a, b, blk);
            }
        }
    }

    /// One warped stiffness block R K_ab Rᵀ (µN/mm); K_ba = K_abᵀ.
    #[cfg(test)]
    pub fn warped_block(&self, r: &Matrix3<f64>, a: usize, b: usize) -> Matrix3<f64> {
        let mut out = Matrix3::zeros();
        self.warped_blocks(r, |i, j, blk| {
            if (i, j) == (a, b) {
                out = blk;
            } else if (j, i) == (a, b) {
                out = blk.transpose();
            }
        });
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-form in-plane split equals the 3×3 eigendecomposition.
    #[test]
    fn tensile_part_of_a_membrane_stress_matches_the_eigendecomposition() {
        let n = Vector3::new(0.3, -0.5, 0.8).normalize();
        let p = Matrix3::identity() - n * n.transpose();
        for raw in [
            Matrix3::new(2.0, 0.5, -1.0, 0.5, -3.0, 0.7, -1.0, 0.7, 1.0),
            Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            Matrix3::new(-1.0, 0.2, 0.0, 0.2, -2.0, 0.1, 0.0, 0.1, -0.5),
        ] {
            let sigma = p * (raw + raw.transpose()) * p * 0.5;
            let closed = tensile_part(&sigma, &n);
            let general = tensile_part(&sigma, &Vector3::zeros());
            assert!(
                (closed - general).norm() < 1e-12 * (1.0 + sigma.norm()),
                "{sigma}"
            );
        }
    }
}
