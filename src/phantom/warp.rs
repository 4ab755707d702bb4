//! The map from the atlas frame to a synthetic patient's scanner space: a similarity scale, a
//! smooth random deformation, then a rigid pose (any rotation, any translation).
//!
//! With `w` the patient's (unposed) frame, the deformation is defined directly as its inverse,
//! `s · a = w + d(w)`, a sum of a few low-frequency plane waves
//! `d(w) = Σ_k A_k sin(κ_k · w + φ_k)`. Its displacement is bounded by `Σ |A_k|` and its
//! gradient by `g = Σ |A_k| |κ_k|`; with `g < 1`, `I + ∇d` is invertible everywhere (its
//! smallest singular value is at least `1 - g > 0`, so its determinant stays positive along the
//! path from the identity), and the forward map is the fixed point `w = s · a - d(w)`, a
//! contraction of rate `g` (Banach). Rendering only needs the inverse, which is explicit.

use nalgebra::{Matrix3, Matrix4, Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

/// One plane wave of the deformation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaveMode {
    /// Displacement amplitude vector \[mm\].
    pub amplitude_mm: [f64; 3],
    /// Wave vector κ [rad/mm].
    pub wave_vector: [f64; 3],
    pub phase: f64,
}

/// The smooth deformation `d`, in the patient's unposed frame (mm).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Deformation {
    pub modes: Vec<WaveMode>,
}

impl Deformation {
    /// `d(w)`.
    pub fn displacement(&self, w: &Vector3<f64>) -> Vector3<f64> {
        self.modes.iter().fold(Vector3::zeros(), |acc, m| {
            let k = Vector3::from(m.wave_vector);
            acc + Vector3::from(m.amplitude_mm) * (k.dot(w) + m.phase).sin()
        })
    }

    /// `∇d(w)` (rows: displacement components, columns: derivatives).
    pub fn jacobian(&self, w: &Vector3<f64>) -> Matrix3<f64> {
        self.modes.iter().fold(Matrix3::zeros(), |acc, m| {
            let k = Vector3::from(m.wave_vector);
            acc + Vector3::from(m.amplitude_mm) * k.transpose() * (k.dot(w) + m.phase).cos()
        })
    }

    /// Upper bound of `|d|` \[mm\].
    pub fn displacement_bound(&self) -> f64 {
        self.modes
            .iter()
            .map(|m| Vector3::from(m.amplitude_mm).norm())
            .sum()
    }

    /// Upper bound `g` of the spectral norm of `∇d`.
    pub fn gradient_bound(&self) -> f64 {
        self.modes
            .iter()
            .map(|m| Vector3::from(m.amplitude_mm).norm() * Vector3::from(m.wave_vector).norm())
            .sum()
    }
}

/// The whole atlas → patient map.
#[derive(Debug, Clone, PartialEq)]
pub struct PatientWarp {
    /// Similarity scale applied to the atlas.
    pub scale: f64,
    pub deformation: Deformation,
    /// Rigid pose in the scanner: `x = rotation · w + translation`.
    pub rotation: Rotation3<f64>,
    pub translation: Vector3<f64>,
}

/// Fixed-point iterations stop at this step size [mm].
const FORWARD_TOLERANCE_MM: f64 = 1e-10;
const FORWARD_MAX_ITERATIONS: usize = 200;

impl PatientWarp {
    /// The patient (scanner LPS) point of an atlas point.
    pub fn to_patient(&self, a: &Point3<f64>) -> Point3<f64> {
        let b = a.coords * self.scale;
        let mut w = b;
        for _ in 0..FORWARD_MAX_ITERATIONS {
            let next = b - self.deformation.displacement(&w);
            let step = (next - w).norm();
            w = next;
            if step < FORWARD_TOLERANCE_MM {
                break;
            }
        }
        Point3::from(self.rotation * w + self.translation)
    }

    /// The atlas point of a patient (scanner LPS) point: explicit.
    #[inline]
    pub fn to_atlas(&self, x: &Point3<f64>) -> Point3<f64> {
        let w = self
            .rotation
            .inverse_transform_vector(&(x.coords - self.translation));
        Point3::from((w + self.deformation.displacement(&w)) / self.scale)
    }

    /// A patient ball of radius r maps into an atlas ball of radius r times this.
    pub fn inverse_lipschitz(&self) -> f64 {
        (1.0 + self.deformation.gradient_bound()) / self.scale
    }

    /// The similarity part (no deformation) as a homogeneous 4x4 matrix, atlas → patient.
    pub fn atlas_to_patient_similarity(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation.matrix() * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn warp() -> PatientWarp {
        PatientWarp {
            scale: 1.07,
            deformation: Deformation {
                modes: vec![
                    WaveMode {
                        amplitude_mm: [0.3, -0.2, 0.1],
                        wave_vector: [0.3, 0.2, -0.4],
                        phase: 0.4,
                    },
                    WaveMode {
                        amplitude_mm: [-0.1, 0.25, 0.2],
                        wave_vector: [-0.5, 0.1, 0.2],
                        phase: 2.0,
                    },
                ],
            },
            rotation: Rotation3::from_euler_angles(0.3, -1.2, 2.5),
            translation: Vector3::new(12.0, -40.0, 7.5),
        }
    }

    #[test]
    fn forward_and_inverse_maps_are_each_others_inverse() {
        let w = warp();
        assert!(w.deformation.gradient_bound() < 1.0);
        for a in [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.5, -2.0, 5.0),
            Point3::new(-3.0, 4.0, -1.0),
        ] {
            let x = w.to_patient(&a);
            assert!((w.to_atlas(&x) - a).norm() < 1e-9);
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = warp().deformation;
        let p = Vector3::new(0.7, -1.1, 2.3);
        let j = d.jacobian(&p);
        let h = 1e-6;
        for c in 0..3 {
            let mut e = Vector3::zeros();
            e[c] = h;
            let fd = (d.displacement(&(p + e)) - d.displacement(&(p - e))) / (2.0 * h);
            assert!((j.column(c) - fd).norm() < 1e-7);
        }
    }
}
