//! Smoothing and coarsening a volume: a separable Gaussian (the phantom's point-spread
//! function, the chain search's smoothed bone map) and a box-averaged downsampling by whole
//! voxels (the chain search's coarse levels).

use rayon::prelude::*;

use super::Volume;

/// Separable Gaussian blur along one index axis (`sigma` in voxels), edges clamped.
pub fn blur_axis(data: &mut [f32], dims: [usize; 3], axis: usize, sigma: f64) {
    if sigma < 0.05 || dims.iter().product::<usize>() != data.len() {
        return;
    }
    let radius = (3.0 * sigma).ceil() as isize;
    let weights: Vec<f64> = (-radius..=radius)
        .map(|d| (-(d as f64).powi(2) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = weights.iter().sum();
    let weights: Vec<f64> = weights.iter().map(|w| w / total).collect();
    let strides = [1, dims[0], dims[0] * dims[1]];
    let len = dims[axis] as isize;
    let stride = strides[axis];
    let source = data.to_vec();
    // each output from the source copy
    data.par_iter_mut().enumerate().for_each(|(idx, out)| {
        let pos = ((idx / stride) % dims[axis]) as isize;
        let base = idx as isize - pos * stride as isize;
        let mut acc = 0.0;
        for (w, d) in weights.iter().zip(-radius..=radius) {
            let q = (pos + d).clamp(0, len - 1);
            acc += w * source[(base + q * stride as isize) as usize] as f64;
        }
        *out = acc as f32;
    });
}

/// Gaussian blur of `volume` with standard deviation `sigma_mm` along every axis.
pub fn gaussian_blur(volume: &mut Volume, sigma_mm: f64) {
    for axis in 0..3 {
        let sigma = sigma_mm / volume.spacing[axis];
        blur_axis(&mut volume.data, volume.dims, axis, sigma);
    }
}

/// `volume` averaged over blocks of whole voxels, about `target_mm` along each axis (a
/// factor of 1 where the voxels are already that large); the blocks that would hang over the
/// far edge are dropped. The result's voxel centres are the blocks' centres.
pub fn downsample(volume: &Volume, target_mm: f64) -> Volume {
    let factor: [usize; 3] =
        std::array::from_fn(|a| ((target_mm / volume.spacing[a]).round() as usize).max(1));
    let dims: [usize; 3] = std::array::from_fn(|a| (volume.dims[a] / factor[a]).max(1));
    let [nx, ny, _] = dims;
    let plane = nx * ny;
    let mut data = vec![0f32; dims.iter().product()];
    data.par_chunks_mut(plane).enumerate().for_each(|(k, out)| {
        for j in 0..ny {
            for i in 0..nx {
                let (mut sum, mut count) = (0f64, 0usize);
                for dk in 0..factor[2] {
                    for dj in 0..factor[1] {
                        for di in 0..factor[0] {
                            let (si, sj, sk) =
                                (i * factor[0] + di, j * factor[1] + dj, k * factor[2] + dk);
                            if si < volume.dims[0] && sj < volume.dims[1] && sk < volume.dims[2] {
                                sum += volume.data[volume.index(si, sj, sk)] as f64;
                                count += 1;
                            }
                        }
                    }
                }
                out[i + nx * j] = (sum / count.max(1) as f64) as f32;
            }
        }
    });
    let half_block = nalgebra::Vector3::from_fn(|a, _| (factor[a] as f64 - 1.0) / 2.0);
    Volume {
        dims,
        spacing: std::array::from_fn(|a| volume.spacing[a] * factor[a] as f64),
        origin: volume.index_to_world(half_block),
        direction: volume.direction,
        data,
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Vector3};

    use super::*;

    fn ramp(dims: [usize; 3], spacing: f64) -> Volume {
        let mut data = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    data.push((i + 2 * j + 3 * k) as f32);
                }
            }
        }
        Volume {
            dims,
            spacing: [spacing; 3],
            origin: Vector3::new(1.0, 2.0, 3.0),
            direction: Matrix3::identity(),
            data,
        }
    }

    /// A linear ramp averaged over blocks is the ramp at the blocks' centres: the coarse
    /// volume's geometry puts each value where the fine volume had it.
    #[test]
    fn downsampling_a_ramp_keeps_it_where_it_was() {
        let fine = ramp([9, 8, 7], 0.25);
        let coarse = downsample(&fine, 0.5);
        assert_eq!(coarse.dims, [4, 4, 3]);
        assert_eq!(coarse.spacing, [0.5; 3]);
        let fine_world_to_index = |p: Vector3<f64>| (p - fine.origin) / 0.25;
        for k in 0..3 {
            for j in 0..4 {
                for i in 0..4 {
                    let p = coarse.index_to_world(Vector3::new(i as f64, j as f64, k as f64));
                    let ijk = fine_world_to_index(p);
                    let expected = ijk.x + 2.0 * ijk.y + 3.0 * ijk.z;
                    let got = coarse.data[coarse.index(i, j, k)] as f64;
                    assert!(
                        (got - expected).abs() < 1e-5,
                        "{i} {j} {k}: {got} vs {expected}"
                    );
                }
            }
        }
    }

    /// A Gaussian keeps a constant and the mean of a point source, and spreads it with the
    /// asked standard deviation.
    #[test]
    fn a_point_blurred_has_the_asked_spread() {
        let dims = [41, 41, 41];
        let mut v = ramp(dims, 0.1);
        v.data.iter_mut().for_each(|x| *x = 0.0);
        let centre = v.index(20, 20, 20);
        v.data[centre] = 1.0;
        gaussian_blur(&mut v, 0.3);
        let total: f64 = v.data.iter().map(|&x| x as f64).sum();
        assert!((total - 1.0).abs() < 1e-4, "{total}");
        let variance: f64 = (0..41)
            .map(|i| {
                let x = (i as f64 - 20.0) * 0.1;
                x * x * v.data[v.index(i, 20, 20)] as f64
            })
            .sum::<f64>()
            / (0..41)
                .map(|i| v.data[v.index(i, 20, 20)] as f64)
                .sum::<f64>();
        assert!((variance.sqrt() - 0.3).abs() < 0.01, "{}", variance.sqrt());
    }
}
