//! The image as a bone indicator in [0, 1]: 0 for air, fluid and soft tissue, 1 for bone,
//! from the image's own air and bone levels (CBCT grey values are not calibrated HU, so
//! fixed thresholds would not carry from one scanner to the next).

use crate::image::Volume;

/// Values taken for the levels: at most this many, evenly strided over the volume.
const LEVEL_SAMPLES: usize = 1 << 21;

/// The image's air and bone levels: its 1st and 99.5th percentiles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levels {
    pub air: f64,
    pub bone: f64,
}

impl Levels {
    /// The levels of `volume`; `None` when it holds no finite value.
    pub fn of(volume: &Volume) -> Option<Levels> {
        let [air, bone] = volume.quantiles([0.01, 0.995], LEVEL_SAMPLES)?;
        Some(Levels {
            air: air as f64,
            bone: bone as f64,
        })
    }

    /// The bone indicator of a value: a ramp from 40 % to 55 % of the way from air to bone
    /// (soft tissue and fluid, 35-42 % of the way on CT's scale, read as 0).
    pub fn boneness(&self, v: f32) -> f32 {
        let span = self.bone - self.air;
        let (lo, hi) = (self.air + 0.4 * span, self.air + 0.55 * span);
        (((v as f64 - lo) / (hi - lo)).clamp(0.0, 1.0)) as f32
    }
}

/// `volume` mapped voxel by voxel through [`Levels::boneness`] (non-finite values read 0).
pub fn bone_map(volume: &Volume, levels: &Levels) -> Volume {
    Volume {
        data: volume
            .data
            .iter()
            .map(|&v| {
                if v.is_finite() {
                    levels.boneness(v)
                } else {
                    0.0
                }
            })
            .collect(),
        ..volume.clone()
    }
}

/// A running minimum (`min`) or maximum over a window of `2 r + 1` voxels along `axis`.
fn running_extreme(v: &mut Volume, axis: usize, r: usize, min: bool) {
    let dims = v.dims;
    let stride = [1, dims[0], dims[0] * dims[1]][axis];
    let len = dims[axis];
    let source = v.data.clone();
    for (idx, out) in v.data.iter_mut().enumerate() {
        let pos = (idx / stride) % len;
        let base = idx - pos * stride;
        let (a, b) = (pos.saturating_sub(r), (pos + r).min(len - 1));
        let values = (a..=b).map(|q| source[base + q * stride]);
        *out = if min {
            values.fold(f32::INFINITY, f32::min)
        } else {
            values.fold(f32::NEG_INFINITY, f32::max)
        };
    }
}

/// The white top-hat of `v` with a cube of `2 r + 1` voxels: `v` minus its opening (erosion
/// then dilation). What a cube that size fits inside (the thick bone of the walls and the
/// otic capsule) is removed; thinner bone (the ossicles, a septum) stays.
pub fn top_hat(v: &mut Volume, r: usize) {
    let original = v.data.clone();
    for axis in 0..3 {
        running_extreme(v, axis, r, true);
    }
    for axis in 0..3 {
        running_extreme(v, axis, r, false);
    }
    for (out, o) in v.data.iter_mut().zip(original) {
        *out = o - *out;
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Vector3};

    use super::*;

    #[test]
    fn air_is_zero_bone_is_one_and_soft_tissue_is_zero() {
        // half air, a little soft tissue, ossicle bone, and 1 % otic capsule (the densest)
        let mut data = vec![-1000.0f32; 500];
        data.extend(vec![40.0f32; 100]);
        data.extend(vec![1500.0f32; 390]);
        data.extend(vec![2000.0f32; 10]);
        let volume = Volume {
            dims: [10, 10, 10],
            spacing: [0.2; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data,
        };
        let levels = Levels::of(&volume).unwrap();
        assert_eq!((levels.air, levels.bone), (-1000.0, 2000.0));
        assert_eq!(levels.boneness(-1000.0), 0.0);
        assert_eq!(levels.boneness(40.0), 0.0);
        assert_eq!(levels.boneness(1500.0), 1.0);
        // the middle of the ramp: 47.5 % of the way
        assert!((levels.boneness(425.0) - 0.5).abs() < 1e-6);
    }

    /// A thick block goes and a rod one voxel thin stays: the walls and the ossicles.
    #[test]
    fn the_top_hat_keeps_thin_bone_and_removes_thick_bone() {
        let n = 20;
        let mut data = vec![0f32; n * n * n];
        let index = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        for k in 0..n {
            for j in 0..n {
                // a block 8 voxels thick, x < 8
                for i in 0..8 {
                    data[index(i, j, k)] = 1.0;
                }
            }
            // a rod along z at (14, 10)
            data[index(14, 10, k)] = 1.0;
        }
        let mut v = Volume {
            dims: [n; 3],
            spacing: [0.5; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data,
        };
        top_hat(&mut v, 2);
        assert_eq!(v.data[index(14, 10, 5)], 1.0);
        assert_eq!(v.data[index(3, 10, 5)], 0.0);
        assert_eq!(v.data[index(7, 10, 5)], 0.0);
        assert!(v.data.iter().filter(|&&x| x > 0.0).count() == n);
    }
}
