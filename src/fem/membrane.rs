//! Constant-strain (CST) plane-stress membrane triangle of thickness h, zero bending stiffness.
//!
//! In-plane gradients ∇N_a = N × (X_c − X_b)/(2A) for (a, b, c) cyclic, i.e. the b_i, c_i of
//! the CST B matrix (docs/fem.md; Felippa, IFEM, "The Linear Triangle"), stored as
//! world-frame vectors in the rest plane, with measure h·A and the plane-stress Lamé pair.
//! Corotation: the rotation maps the rest triangle frame onto the current one, taken as the
//! polar rotation of F + n Nᵀ (n the current winding normal), which fixes the normal and picks
//! the in-plane rotation by polar decomposition, so it does not depend on the vertex order.
//! A triangle is collapsed when its current area vanishes.

use nalgebra::{Matrix3, Point3, Vector3};

use super::element::CorotElement;
use super::error::FemError;
use super::material::MembraneMaterial;
use super::rotation::polar_rotation;

/// A rest area below this fraction of (longest edge)² is degenerate; a current doubled area
/// below this fraction of the rest doubled area is collapsed.
const DEGENERATE_AREA: f64 = 1e-12;

pub(crate) type MembraneElement = CorotElement<3>;

/// Rest data of membrane triangle `index` with nodes `nodes` and material `mat`.
pub(crate) fn rest_membrane(
    index: usize,
    nodes: [u32; 3],
    rest: &[Point3<f64>],
    mat: &MembraneMaterial,
) -> Result<MembraneElement, FemError> {
    let p = nodes.map(|n| rest[n as usize]);
    let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let twice_area = cross.norm();
    let longest = [(0, 1), (1, 2), (2, 0)]
        .iter()
        .map(|&(a, b)| (p[a] - p[b]).norm())
        .fold(0.0, f64::max);
    if !(twice_area.is_finite() && twice_area > DEGENERATE_AREA * longest * longest) {
        return Err(FemError::DegenerateElement {
            kind: "membrane triangle",
            element: index,
            measure_name: "area mm^2",
            measure: twice_area / 2.0,
        });
    }
    let normal = cross / twice_area;
    let grad = |b: usize, c: usize| normal.cross(&(p[c] - p[b])) / twice_area;
    Ok(CorotElement {
        nodes,
        grads: [grad(1, 2), grad(2, 0), grad(0, 1)],
        measure: mat.thickness * twice_area / 2.0,
        lame: mat.plane_stress_lame(),
        rest_normal: normal,
    })
}

/// The unit normal of the membrane triangle at `x`; `None` if it collapsed (its area below
/// [`DEGENERATE_AREA`] times the rest area).
fn current_normal(tri: &MembraneElement, x: &[Point3<f64>]) -> Option<Vector3<f64>> {
    let p = tri.nodes.map(|n| x[n as usize]);
    let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
    let rest_twice_area = 2.0 * tri.measure_area();
    let twice_area = cross.norm();
    (twice_area > DEGENERATE_AREA * rest_twice_area).then(|| cross / twice_area)
}

/// Whether the membrane triangle is admissible (not collapsed) at `x`.
pub(crate) fn membrane_admissible(tri: &MembraneElement, x: &[Point3<f64>]) -> bool {
    current_normal(tri, x).is_some()
}

/// Rotation of the membrane triangle and whether it is admissible (not collapsed).
pub(crate) fn membrane_rotation(
    tri: &MembraneElement,
    x: &[Point3<f64>],
    f: &Matrix3<f64>,
) -> (Matrix3<f64>, bool) {
    match current_normal(tri, x) {
        Some(n) => (polar_rotation(&(f + n * tri.rest_normal.transpose())), true),
        None => {
            let n = tri.rest_normal;
            (polar_rotation(&(f + n * n.transpose())), false)
        }
    }
}

impl MembraneElement {
    /// Rest area A, from the gradients of the linear triangle: |∇N_1 × ∇N_2| = 1/(2A).
    pub(crate) fn measure_area(&self) -> f64 {
        0.5 / self.grads[1].cross(&self.grads[2]).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::SMatrix;

    /// The textbook CST (docs/fem.md): local frame, b_i = y_j − y_k, c_i = x_k − x_j, B, D_ps,
    /// K = h·A·BᵀDB.
    #[test]
    fn blocks_equal_section_4_3_cst_stiffness() {
        let rest = vec![
            Point3::new(0.2, 0.1, 0.0),
            Point3::new(1.4, 0.3, 0.0),
            Point3::new(0.5, 1.1, 0.0),
        ];
        let mat = MembraneMaterial {
            youngs_modulus: 2.0e7,
            poisson_ratio: 0.3,
            thickness: 0.08,
            bending_thickness: None,
            density: 1e-3,
        };
        let tri = rest_membrane(0, [0, 1, 2], &rest, &mat).unwrap();
        let e1 = (rest[1] - rest[0]).normalize();
        let n = (rest[1] - rest[0]).cross(&(rest[2] - rest[0])).normalize();
        let e2 = n.cross(&e1);
        let loc: Vec<(f64, f64)> = rest
            .iter()
            .map(|p| ((p - rest[0]).dot(&e1), (p - rest[0]).dot(&e2)))
            .collect();
        let area = loc[1].0 * loc[2].1 / 2.0;
        let mut b = SMatrix::<f64, 3, 6>::zeros();
        for i in 0..3 {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            let bi = loc[j].1 - loc[k].1;
            let ci = loc[k].0 - loc[j].0;
            b[(0, 2 * i)] = bi / (2.0 * area);
            b[(1, 2 * i + 1)] = ci / (2.0 * area);
            b[(2, 2 * i)] = ci / (2.0 * area);
            b[(2, 2 * i + 1)] = bi / (2.0 * area);
        }
        let (e, nu) = (mat.youngs_modulus, mat.poisson_ratio);
        let d = SMatrix::<f64, 3, 3>::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, (1.0 - nu) / 2.0)
            * (e / (1.0 - nu * nu));
        let k_loc = b.transpose() * d * b * (mat.thickness * area);
        let t = SMatrix::<f64, 3, 2>::from_columns(&[e1, e2]);
        for a in 0..3 {
            for c in 0..3 {
                let blk = tri.warped_block(&Matrix3::identity(), a, c);
                let reference = t * k_loc.fixed_view::<2, 2>(2 * a, 2 * c) * t.transpose();
                assert!((blk - reference).norm() < 1e-9 * k_loc.norm(), "{a}{c}");
            }
        }
        assert!((tri.measure_area() - area).abs() < 1e-12);
        assert!(tri.grads.iter().all(|g| g.dot(&n).abs() < 1e-15));
    }
}
