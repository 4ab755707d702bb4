//! Rotation part of a 3×3 deformation gradient by polar decomposition, never a reflection.
//!
//! F = U Σ Vᵀ (SVD); R = U·diag(1, 1, det(U Vᵀ))·Vᵀ with the sign flip put on the direction of
//! the smallest singular value (Müller & Gross 2004; Irving et al. 2004 for the inverted case).
//! For det F > 0 this is the rotation of the polar decomposition F = R S, computed first by
//! Higham's Newton iteration X ← ½(X + X⁻ᵀ) from X = F (quadratic convergence; a few
//! iterations for the near-rotations of small-strain elements, far cheaper than an SVD),
//! with the SVD as the fallback for det F ≤ 0 or a slow iteration (Higham 1986, "Computing
//! the polar decomposition — with applications", SIAM J Sci Stat Comput 7:1160).

use nalgebra::Matrix3;

/// Maximum SVD sweeps; a finite 3×3 converges in far fewer. A non-converging (non-finite)
/// input falls back to the identity, and callers reject non-finite positions beforehand.
const MAX_SVD_SWEEPS: usize = 64;

/// Newton iterations before falling back to the SVD.
const MAX_NEWTON: usize = 12;

/// The iteration stops after a Newton update of at most this (Frobenius norm): it converges
/// quadratically, so the iterate it returns is then within about its square (1e-16, the
/// rounding level) of the rotation, one iteration earlier than waiting for a negligible update.
const NEWTON_LAST_UPDATE: f64 = 1e-8;

/// The proper rotation (det = +1) closest to `f` in the Frobenius norm.
pub(crate) fn polar_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    if f.determinant() > 0.0 {
        let mut x = *f;
        for _ in 0..MAX_NEWTON {
            let Some(inv) = x.try_inverse() else {
                break;
            };
            let next = (x + inv.transpose()) * 0.5;
            let change = (next - x).norm();
            x = next;
            if change <= NEWTON_LAST_UPDATE {
                return x;
            }
        }
    }
    polar_rotation_svd(f)
}

/// The same by SVD (any F, including inverted ones).
fn polar_rotation_svd(f: &Matrix3<f64>) -> Matrix3<f64> {
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
    fn newton_and_svd_agree() {
        let q = Rotation3::from_euler_angles(0.3, -1.2, 2.0).into_inner();
        for s in [
            Matrix3::new(1.001, 0.0005, 0.0, 0.0005, 0.999, 0.0002, 0.0, 0.0002, 1.0),
            Matrix3::new(2.5, 0.4, -0.3, 0.4, 0.2, 0.1, -0.3, 0.1, 1.3),
        ] {
            let f = q * s;
            assert!((polar_rotation(&f) - polar_rotation_svd(&f)).norm() < 1e-12);
        }
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
