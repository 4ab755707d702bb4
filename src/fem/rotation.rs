//! Rotation part of a 3×3 deformation gradient by polar decomposition, never a reflection.
//!
//! F = U Σ Vᵀ (SVD); R = U·diag(1, 1, det(U Vᵀ))·Vᵀ with the sign flip put on the direction of
//! the smallest singular value (Müller & Gross 2004; Irving et al. 2004 for the inverted case).
//! For det F > 0 this is the rotation of the polar decomposition F = R S.

use nalgebra::Matrix3;

/// Maximum SVD sweeps; a finite 3×3 converges in far fewer. A non-converging (non-finite)
/// input falls back to the identity, and callers reject non-finite positions beforehand.
const MAX_SVD_SWEEPS: usize = 64;

/// The proper rotation (det = +1) closest to `f` in the Frobenius norm.
pub(crate) fn polar_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let Some(svd) = f.try_svd(true, true, f64::EPSILON, MAX_SVD_SWEEPS) else {
        return Matrix3::identity();
    };
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    if (u * v_t).determinant() < 0.0 {
        let s = svd.singular_values;
        let k = if s[0] <= s[1] && s[0] <= s[2] {
            0
        } else if s[1] <= s[2] {
            1
        } else {
            2
        };
        u.column_mut(k).neg_mut();
    }
    u * v_t
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    #[test]
    fn recovers_rotation_of_stretched_rotation() {
        let q = Rotation3::from_axis_angle(&Vector3::y_axis(), 1.1).into_inner();
        let s = Matrix3::new(1.2, 0.1, 0.0, 0.1, 0.9, 0.05, 0.0, 0.05, 1.05);
        let r = polar_rotation(&(q * s));
        assert!((r - q).norm() < 1e-12);
    }

    #[test]
    fn never_returns_a_reflection() {
        let f = Matrix3::from_diagonal(&Vector3::new(1.0, 0.8, -0.1));
        let r = polar_rotation(&f);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-12);
        assert!((r - Matrix3::identity()).norm() < 1e-12);
    }
}
