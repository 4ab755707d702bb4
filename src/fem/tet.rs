//! Linear (4-node, constant-strain) tetrahedron: rest shape gradients and current rotation.
//!
//! Dm = [X1−X0, X2−X0, X3−X0], V = |det Dm|/6, rows of Dm⁻¹ are ∇N1..∇N3 and
//! ∇N0 = −(∇N1+∇N2+∇N3) (docs/fem.md). The rotation is the polar rotation of
//! F = Ds·Dm⁻¹ (SOFA TetrahedronFEMForceField method="polar", Müller & Gross 2004). Rest
//! orientation may be either handedness; an element is inverted when det F ≤ 0.

use nalgebra::{Matrix3, Point3, Vector3};

use super::element::CorotElement;
use super::error::FemError;
use super::material::TetMaterial;
use super::rotation::polar_rotation;

/// A rest volume below this fraction of (longest edge)³ is degenerate.
const DEGENERATE_VOLUME: f64 = 1e-12;

pub(crate) type TetElement = CorotElement<4>;

/// Rest data of tetrahedron `index` with nodes `nodes` and material `mat`.
pub(crate) fn rest_tet(
    index: usize,
    nodes: [u32; 4],
    rest: &[Point3<f64>],
    mat: &TetMaterial,
) -> Result<TetElement, FemError> {
    let p = nodes.map(|n| rest[n as usize]);
    let dm = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let volume = dm.determinant().abs() / 6.0;
    let longest = (0..4)
        .flat_map(|a| (a + 1..4).map(move |b| (a, b)))
        .map(|(a, b)| (p[a] - p[b]).norm())
        .fold(0.0, f64::max);
    let inverse = dm
        .try_inverse()
        .filter(|_| volume.is_finite() && volume > DEGENERATE_VOLUME * longest.powi(3));
    let Some(dm_inv) = inverse else {
        return Err(FemError::DegenerateElement {
            kind: "tetrahedron",
            element: index,
            measure_name: "volume mm^3",
            measure: volume,
        });
    };
    let g1 = dm_inv.row(0).transpose();
    let g2 = dm_inv.row(1).transpose();
    let g3 = dm_inv.row(2).transpose();
    Ok(CorotElement {
        nodes,
        grads: [-(g1 + g2 + g3), g1, g2, g3],
        measure: volume,
        lame: mat.lame(),
        rest_normal: Vector3::zeros(),
    })
}

/// An element compressed below this fraction of its rest volume is as unusable as an
/// inverted one: linear tetrahedra that flat ill-condition the stiffness, and a registration
/// that crushes an element has lost the anatomy there (no mechanical load of this tool comes
/// near it: the static and dynamic strains stay far below 1 %).
pub const MIN_VOLUME_RATIO: f64 = 0.1;

/// Whether a tetrahedron with deformation gradient F is admissible: det F >
/// [`MIN_VOLUME_RATIO`].
pub(crate) fn tet_admissible(f: &Matrix3<f64>) -> bool {
    f.determinant() > MIN_VOLUME_RATIO
}

/// Rotation of the tetrahedron and whether it is admissible ([`tet_admissible`]), from F.
pub(crate) fn tet_rotation(f: &Matrix3<f64>) -> (Matrix3<f64>, bool) {
    (polar_rotation(f), tet_admissible(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> (Vec<Point3<f64>>, TetElement) {
        let rest = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let mat = TetMaterial {
            youngs_modulus: 1000.0,
            poisson_ratio: 0.25,
            density: 1e-3,
        };
        let tet = rest_tet(0, [0, 1, 2, 3], &rest, &mat).unwrap();
        (rest, tet)
    }

    /// K_e = V·BᵀDB built from the explicit 6×12 Voigt B and 6×6 D (docs/fem.md).
    fn voigt_stiffness(tet: &TetElement) -> nalgebra::SMatrix<f64, 12, 12> {
        let mut b = nalgebra::SMatrix::<f64, 6, 12>::zeros();
        for (a, g) in tet.grads.iter().enumerate() {
            let c = 3 * a;
            b[(0, c)] = g.x;
            b[(1, c + 1)] = g.y;
            b[(2, c + 2)] = g.z;
            b[(3, c)] = g.y;
            b[(3, c + 1)] = g.x;
            b[(4, c + 1)] = g.z;
            b[(4, c + 2)] = g.y;
            b[(5, c)] = g.z;
            b[(5, c + 2)] = g.x;
        }
        let (l, m) = (tet.lame.lambda, tet.lame.mu);
        let mut d = nalgebra::SMatrix::<f64, 6, 6>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] = l;
            }
            d[(i, i)] = l + 2.0 * m;
            d[(i + 3, i + 3)] = m;
        }
        b.transpose() * d * b * tet.measure
    }

    #[test]
    fn blocks_equal_voigt_b_transpose_d_b() {
        let (_, tet) = unit_tet();
        assert!((tet.measure - 1.0 / 6.0).abs() < 1e-15);
        let k = voigt_stiffness(&tet);
        for a in 0..4 {
            for b in 0..4 {
                let blk = tet.warped_block(&Matrix3::identity(), a, b);
                let reference = k.fixed_view::<3, 3>(3 * a, 3 * b);
                assert!((blk - reference).norm() < 1e-12 * k.norm());
            }
        }
    }

    #[test]
    fn forces_equal_minus_k_times_displacement() {
        let (rest, tet) = unit_tet();
        let u = [
            Vector3::new(0.01, -0.02, 0.003),
            Vector3::new(-0.004, 0.01, 0.02),
            Vector3::new(0.0, 0.005, -0.01),
            Vector3::new(0.02, 0.0, 0.001),
        ];
        let x: Vec<_> = rest.iter().zip(&u).map(|(p, d)| p + d).collect();
        let f = tet.deformation(&x);
        let forces = tet.forces(&Matrix3::identity(), &f);
        let k = voigt_stiffness(&tet);
        let uv =
            nalgebra::SVector::<f64, 12>::from_iterator(u.iter().flat_map(|v| v.iter().copied()));
        let ku = k * uv;
        for (a, force) in forces.iter().enumerate() {
            let expected = -ku.fixed_rows::<3>(3 * a);
            assert!((force - expected).norm() < 1e-12 * ku.norm());
        }
    }

    #[test]
    fn rejects_flat_tetrahedron() {
        let rest = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        let mat = TetMaterial {
            youngs_modulus: 1.0,
            poisson_ratio: 0.3,
            density: 1.0,
        };
        assert!(matches!(
            rest_tet(7, [0, 1, 2, 3], &rest, &mat),
            Err(FemError::DegenerateElement { element: 7, .. })
        ));
    }
}
