//! Least-squares alignment of corresponding points: Kabsch (rotation + translation) with the
//! determinant correction, so a reflection is never returned, and optionally Umeyama's
//! isotropic scale. With the three landmarks of the method the cross-covariance has rank 2,
//! so the sign correction on its smallest singular vector is what keeps the fit proper.
//!
//! References: W. Kabsch, Acta Cryst. A32 (1976) 922; S. Umeyama, IEEE TPAMI 13(4) (1991) 376.

use nalgebra::{Matrix3, Matrix4, Point3, Vector3};
use serde::{Deserialize, Serialize};

/// x ↦ scale · R x + t. Its direction is named where it is stored (e.g. `atlas_to_patient`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimilarityTransform {
    /// Rotation, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation in mm.
    pub translation: [f64; 3],
    /// Isotropic scale (1 for a rigid fit).
    pub scale: f64,
}

impl SimilarityTransform {
    /// The identity.
    pub fn identity() -> SimilarityTransform {
        SimilarityTransform::new(Matrix3::identity(), Vector3::zeros(), 1.0)
    }

    /// From a rotation matrix, a translation and a scale.
    pub fn new(
        rotation: Matrix3<f64>,
        translation: Vector3<f64>,
        scale: f64,
    ) -> SimilarityTransform {
        SimilarityTransform {
            rotation: std::array::from_fn(|r| std::array::from_fn(|c| rotation[(r, c)])),
            translation: translation.into(),
            scale,
        }
    }

    /// The rotation as a matrix.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| self.rotation[r][c])
    }

    /// Maps a point.
    pub fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(
            self.rotation_matrix() * p.coords * self.scale + Vector3::from(self.translation),
        )
    }

    /// Maps a direction (rotation only; lengths scale by `scale`).
    pub fn apply_vector(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rotation_matrix() * v * self.scale
    }

    /// The 4x4 homogeneous matrix.
    pub fn matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation_matrix() * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::from(self.translation));
        m
    }

    /// The inverse map.
    pub fn inverse(&self) -> SimilarityTransform {
        let rt = self.rotation_matrix().transpose();
        let s = 1.0 / self.scale;
        SimilarityTransform::new(rt, -(rt * Vector3::from(self.translation)) * s, s)
    }
}

/// A fitted transform with its residual at each point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidFit {
    pub transform: SimilarityTransform,
    /// |T(source_i) - target_i| in mm, per point.
    pub residuals_mm: Vec<f64>,
    /// Root mean square of the residuals, mm.
    pub rms_mm: f64,
}

/// The rigid stage's record (`OUT/stages/rigid.json`): the fit, its matrix and whether it
/// carried a scale.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidRecord {
    pub atlas_to_patient: SimilarityTransform,
    /// The 4x4 homogeneous matrix, row-major.
    pub matrix4: Vec<f64>,
    pub residuals_mm: Vec<f64>,
    pub rms_mm: f64,
    pub with_scale: bool,
}

impl RigidRecord {
    /// The record of `fit`.
    pub fn of(fit: &RigidFit, with_scale: bool) -> RigidRecord {
        RigidRecord {
            atlas_to_patient: fit.transform,
            matrix4: fit.transform.matrix4().transpose().as_slice().to_vec(),
            residuals_mm: fit.residuals_mm.clone(),
            rms_mm: fit.rms_mm,
            with_scale,
        }
    }

    /// The fit it records.
    pub fn fit(&self) -> RigidFit {
        RigidFit {
            transform: self.atlas_to_patient,
            residuals_mm: self.residuals_mm.clone(),
            rms_mm: self.rms_mm,
        }
    }
}

/// Fits `target ≈ T(source)` in the least-squares sense, with isotropic scale when
/// `with_scale`. `None` for fewer than three points or a degenerate (collinear) set.
pub fn fit_similarity(
    source: &[Point3<f64>],
    target: &[Point3<f64>],
    with_scale: bool,
) -> Option<RigidFit> {
    let n = source.len();
    if n < 3 || target.len() != n {
        return None;
    }
    let centroid =
        |pts: &[Point3<f64>]| pts.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n as f64;
    let (cs, ct) = (centroid(source), centroid(target));
    let mut h = Matrix3::zeros();
    let mut var_s = 0.0;
    for (s, t) in source.iter().zip(target) {
        let (ds, dt) = (s.coords - cs, t.coords - ct);
        h += dt * ds.transpose();
        var_s += ds.norm_squared();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    // the two largest singular values must be non-zero: otherwise the points are collinear
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    if sv[1] <= 1e-12 * sv[0].max(f64::MIN_POSITIVE) {
        return None;
    }
    let d = if (u * v_t).determinant() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let correction = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
    // nalgebra orders singular values decreasingly, so the correction hits the smallest
    let rotation = u * correction * v_t;
    let scale = if with_scale {
        (svd.singular_values
            .component_mul(&Vector3::new(1.0, 1.0, d)))
        .sum()
            / var_s
    } else {
        1.0
    };
    let translation = ct - rotation * cs * scale;
    let transform = SimilarityTransform::new(rotation, translation, scale);
    let residuals_mm: Vec<f64> = source
        .iter()
        .zip(target)
        .map(|(s, t)| (transform.apply(s) - t).norm())
        .collect();
    let rms_mm = (residuals_mm.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
    Some(RigidFit {
        transform,
        residuals_mm,
        rms_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn triangle() -> Vec<Point3<f64>> {
        vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.0, 0.0, 6.0),
            Point3::new(-3.5, 0.5, 1.5),
        ]
    }

    #[test]
    fn recovers_a_known_rigid_motion_from_three_points() {
        let r = Rotation3::from_euler_angles(2.5, -1.1, 0.3);
        let t = Vector3::new(4.0, -7.0, 120.0);
        let src = triangle();
        let dst: Vec<_> = src.iter().map(|p| Point3::from(r * p.coords + t)).collect();
        let fit = fit_similarity(&src, &dst, false).unwrap();
        assert!((fit.transform.rotation_matrix() - r.matrix()).norm() < 1e-12);
        assert!((Vector3::from(fit.transform.translation) - t).norm() < 1e-10);
        assert!(fit.rms_mm < 1e-10);
    }

    #[test]
    fn recovers_scale_with_umeyama() {
        let r = Rotation3::from_euler_angles(0.2, 0.9, -2.0);
        let src = triangle();
        let dst: Vec<_> = src
            .iter()
            .map(|p| Point3::from(r * p.coords * 1.13 + Vector3::new(1.0, 2.0, 3.0)))
            .collect();
        let fit = fit_similarity(&src, &dst, true).unwrap();
        assert!((fit.transform.scale - 1.13).abs() < 1e-12);
        assert!(fit.rms_mm < 1e-10);
        let back = fit.transform.inverse().apply(&dst[2]);
        assert!((back - src[2]).norm() < 1e-10);
    }

    #[test]
    fn a_mirrored_target_never_yields_a_reflection() {
        // three points and their mirror image are congruent: the best proper rotation exists
        // and fits exactly, and det must stay +1
        let src = triangle();
        let mirrored: Vec<_> = src.iter().map(|p| Point3::new(-p.x, p.y, p.z)).collect();
        let fit = fit_similarity(&src, &mirrored, false).unwrap();
        assert!((fit.transform.rotation_matrix().determinant() - 1.0).abs() < 1e-12);
        assert!(fit.rms_mm < 1e-10);
        // with four non-coplanar points the mirror cannot be fitted by a rotation
        let mut src4 = src.clone();
        src4.push(Point3::new(1.0, 3.0, 2.0));
        let mir4: Vec<_> = src4.iter().map(|p| Point3::new(-p.x, p.y, p.z)).collect();
        let fit4 = fit_similarity(&src4, &mir4, false).unwrap();
        assert!((fit4.transform.rotation_matrix().determinant() - 1.0).abs() < 1e-12);
        assert!(fit4.rms_mm > 0.1);
    }

    #[test]
    fn collinear_points_are_refused() {
        let line = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, 1.0),
            Point3::new(2.0, 2.0, 2.0),
        ];
        assert!(fit_similarity(&line, &line, false).is_none());
    }
}
