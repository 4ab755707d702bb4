//! `Volume`: a 3-D scalar image in world (LPS, mm) coordinates.
//!
//! Voxel (i, j, k) sits at `origin + direction · diag(spacing) · (i, j, k)`; the columns of
//! `direction` are the unit world directions of the voxel axes i, j, k (they need not be
//! orthogonal: a gantry-tilted series has a sheared third axis). Voxels are stored with i
//! fastest, then j, then k.

use nalgebra::{Matrix3, Vector3};

/// A scalar volume in LPS millimetres. Values are Hounsfield units for CT.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume {
    /// Number of voxels along i, j, k.
    pub dims: [usize; 3],
    /// Voxel spacing along i, j, k in mm.
    pub spacing: [f64; 3],
    /// World position (LPS, mm) of voxel (0, 0, 0).
    pub origin: Vector3<f64>,
    /// Columns: unit LPS directions of the voxel axes i, j, k.
    pub direction: Matrix3<f64>,
    /// Voxel values, i fastest, then j, then k.
    pub data: Vec<f32>,
}

impl Volume {
    /// Flat index of voxel (i, j, k).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The smallest voxel spacing \[mm\] (the step the registration probes with).
    pub fn smallest_spacing(&self) -> f64 {
        self.spacing.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// Total number of voxels.
    pub fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// True when the volume holds no voxel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The 3x3 matrix mapping continuous voxel indices to world offsets (direction · spacing).
    pub fn index_to_world_matrix(&self) -> Matrix3<f64> {
        self.direction * Matrix3::from_diagonal(&Vector3::from(self.spacing))
    }

    /// World position (LPS, mm) of continuous voxel index `ijk`.
    pub fn index_to_world(&self, ijk: Vector3<f64>) -> Vector3<f64> {
        self.origin + self.index_to_world_matrix() * ijk
    }

    /// Continuous voxel index of a world position, or `None` if the geometry is degenerate.
    pub fn world_to_index(&self, p: Vector3<f64>) -> Option<Vector3<f64>> {
        self.index_to_world_matrix()
            .try_inverse()
            .map(|inv| inv * (p - self.origin))
    }

    /// Smallest and largest voxel value, or `None` for an empty volume.
    pub fn value_range(&self) -> Option<(f32, f32)> {
        let mut it = self.data.iter().copied().filter(|v| v.is_finite());
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), v| (lo.min(v), hi.max(v))))
    }

    /// The values at quantiles `q` (each in [0, 1]) of the finite voxel values, read from a
    /// regular subsample of at most `max_samples` voxels; `None` when there is no finite value.
    pub fn quantiles<const N: usize>(&self, q: [f64; N], max_samples: usize) -> Option<[f32; N]> {
        let stride = self.data.len().div_ceil(max_samples.max(1)).max(1);
        let mut values: Vec<f32> = self
            .data
            .iter()
            .step_by(stride)
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        if values.is_empty() {
            return None;
        }
        Some(q.map(|q| {
            let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
            *values.select_nth_unstable_by(k, f32::total_cmp).1
        }))
    }

    /// The direction matrix row-major (9 numbers; columns are the voxel axes in LPS).
    pub fn direction_row_major(&self) -> [f64; 9] {
        let d = &self.direction;
        [
            d[(0, 0)],
            d[(0, 1)],
            d[(0, 2)],
            d[(1, 0)],
            d[(1, 1)],
            d[(1, 2)],
            d[(2, 0)],
            d[(2, 1)],
            d[(2, 2)],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn oblique() -> Volume {
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.7);
        Volume {
            dims: [4, 3, 2],
            spacing: [0.5, 0.25, 2.0],
            origin: Vector3::new(10.0, -5.0, 3.0),
            direction: *r.matrix(),
            data: (0..24).map(|v| v as f32 - 3.0).collect(),
        }
    }

    #[test]
    fn index_world_round_trip() {
        let v = oblique();
        let ijk = Vector3::new(1.5, 2.0, -0.5);
        let back = v.world_to_index(v.index_to_world(ijk)).unwrap();
        assert!((back - ijk).norm() < 1e-12);
        // one step along k moves 2 mm along the third direction column
        let step = v.index_to_world(Vector3::new(0.0, 0.0, 1.0)) - v.origin;
        assert!((step.norm() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn range_and_layout() {
        let v = oblique();
        assert_eq!(v.value_range(), Some((-3.0, 20.0)));
        assert_eq!(v.index(1, 2, 1), 1 + 4 * (2 + 3));
        assert_eq!(v.len(), 24);
    }
}
