//! A cone-beam CT imaging model for synthetic cases: a noise-free tissue field (HU at a world
//! point) is integrated over each voxel by supersampling (partial volume), blurred by a
//! Gaussian point-spread function, then corrupted by noise and optional cone-beam artefacts
//! (cupping, rings, streaks). Every random number comes from an explicit seed, per slice, so
//! the output is byte-identical whatever the thread count.
//!
//! Sources for the model (see docs/phantom.md for the HU levels):
//! - CBCT PSF and noise of NewTom-class scanners: Pauwels et al., "Technical aspects of dental
//!   CBCT: state of the art", Dentomaxillofac Radiol 44 (2015) 20140224 (cupping, rings and
//!   streaks are the characteristic artefacts; noise of tens of HU; MTF of ~1-2 lp/mm).
//! - Schulze et al., "Artefacts in CBCT: a review", Dentomaxillofac Radiol 40 (2011) 265-273.

use nalgebra::{Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::image::Volume;
use crate::image::filter::blur_axis;

/// One sample of a tissue field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldSample {
    /// Hounsfield units at the point.
    pub hu: f32,
    /// A radius (mm) around the point within which the field is constant; 0 when unknown.
    pub clearance_mm: f64,
}

/// The noise-free anatomy: Hounsfield units at a world (LPS mm) point.
pub trait TissueField: Sync {
    /// The field at `p`. `footprint_mm` is the size of the region the sample stands for: a
    /// field may average structures thinner than that over it (0: a point sample).
    fn sample(&self, p: &Point3<f64>, footprint_mm: f64) -> FieldSample;
}

/// A plain function of the point: no clearance known, so every voxel is supersampled.
impl<F: Fn(&Point3<f64>) -> f32 + Sync> TissueField for F {
    fn sample(&self, p: &Point3<f64>, _footprint_mm: f64) -> FieldSample {
        FieldSample {
            hu: self(p),
            clearance_mm: 0.0,
        }
    }
}

/// The sampling grid of the scanner (a Volume without data).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub dims: [usize; 3],
    pub spacing: [f64; 3],
    pub origin: Vector3<f64>,
    pub direction: Matrix3<f64>,
}

/// Imaging parameters (all recorded in a case's truth.json).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagingParams {
    /// Sub-samples per voxel and axis for partial volume (n³ samples per voxel).
    pub supersample: usize,
    /// Full width at half maximum of the Gaussian point-spread function \[mm\].
    pub psf_fwhm_mm: f64,
    /// Standard deviation of the additive Gaussian noise \[HU\].
    pub noise_sd_hu: f64,
    /// Cupping: depression at the centre of the field of view relative to its edge \[HU\].
    pub cupping_hu: f64,
    /// Ring artefacts: number of rings and their amplitude \[HU\].
    pub rings: usize,
    pub ring_amplitude_hu: f64,
    /// Streak artefacts: number of streaks and their amplitude \[HU\].
    pub streaks: usize,
    pub streak_amplitude_hu: f64,
    /// Seed of every random number of the image.
    pub seed: u64,
}

impl ImagingParams {
    /// A NewTom 5G-class acquisition without artefacts other than noise and blur.
    pub fn clean(seed: u64) -> ImagingParams {
        ImagingParams {
            supersample: 3,
            psf_fwhm_mm: 0.25,
            noise_sd_hu: 40.0,
            cupping_hu: 0.0,
            rings: 0,
            ring_amplitude_hu: 0.0,
            streaks: 0,
            streak_amplitude_hu: 0.0,
            seed,
        }
    }
}

impl Grid {
    /// The world point of (fractional) voxel index `ijk`.
    pub fn world(&self, ijk: Vector3<f64>) -> Point3<f64> {
        let m = self.direction * Matrix3::from_diagonal(&Vector3::from(self.spacing));
        Point3::from(self.origin + m * ijk)
    }
}

/// A voxel is supersampled when the field's clearance at its centre is below this many
/// half-diagonals (a margin for distances that are bounds only to first order).
const CLEARANCE_MARGIN: f64 = 1.25;

/// Renders `field` on `grid` with the imaging model `params`.
///
/// Partial volume is adaptive: a voxel whose centre is farther from every interface than its
/// half-diagonal (the field's clearance) is uniform and takes the centre value; any other
/// voxel is the mean of `supersample`³ samples, each standing for a footprint of one
/// sub-voxel (so thin sheets are averaged rather than aliased).
pub fn render(field: &dyn TissueField, grid: &Grid, params: &ImagingParams) -> Volume {
    let [nx, ny, nz] = grid.dims;
    let plane = nx * ny;
    let n = params.supersample.max(1);
    let offsets: Vec<f64> = (0..n).map(|s| (s as f64 + 0.5) / n as f64 - 0.5).collect();
    let half_diagonal = 0.5 * grid.spacing.iter().map(|s| s * s).sum::<f64>().sqrt();
    let footprint = grid.spacing.iter().copied().fold(f64::INFINITY, f64::min) / n as f64;
    let mut data = vec![0f32; plane * nz];
    data.par_chunks_mut(plane).enumerate().for_each(|(k, out)| {
        for j in 0..ny {
            for i in 0..nx {
                let ijk = Vector3::new(i as f64, j as f64, k as f64);
                let centre = field.sample(&grid.world(ijk), 0.0);
                if centre.clearance_mm > CLEARANCE_MARGIN * half_diagonal {
                    out[i + nx * j] = centre.hu;
                    continue;
                }
                let mut sum = 0.0f64;
                for dz in &offsets {
                    for dy in &offsets {
                        for dx in &offsets {
                            let p = grid.world(ijk + Vector3::new(*dx, *dy, *dz));
                            sum += field.sample(&p, footprint).hu as f64;
                        }
                    }
                }
                out[i + nx * j] = (sum / (n * n * n) as f64) as f32;
            }
        }
    });
    let sigma_mm = params.psf_fwhm_mm / (8.0 * std::f64::consts::LN_2).sqrt();
    for axis in 0..3 {
        blur_axis(&mut data, grid.dims, axis, sigma_mm / grid.spacing[axis]);
    }
    add_artefacts(&mut data, grid, params);
    Volume {
        dims: grid.dims,
        spacing: grid.spacing,
        origin: grid.origin,
        direction: grid.direction,
        data,
    }
}

/// Noise, cupping, rings and streaks. The rotation axis of the cone beam is the grid's k axis
/// through the centre of the field of view.
fn add_artefacts(data: &mut [f32], grid: &Grid, params: &ImagingParams) {
    let [nx, ny, _] = grid.dims;
    let plane = nx * ny;
    let cx = (nx as f64 - 1.0) / 2.0 * grid.spacing[0];
    let cy = (ny as f64 - 1.0) / 2.0 * grid.spacing[1];
    let r_max = (cx * cx + cy * cy).sqrt().max(1e-9);
    let mut setup = ChaCha8Rng::seed_from_u64(params.seed ^ 0x5EED_A27E_FAC7_0001);
    let rings: Vec<(f64, f64)> = (0..params.rings)
        .map(|_| {
            let sign = if setup.random::<bool>() { 1.0 } else { -1.0 };
            (
                setup.random::<f64>() * r_max,
                sign * params.ring_amplitude_hu,
            )
        })
        .collect();
    let streaks: Vec<(f64, f64, f64)> = (0..params.streaks)
        .map(|_| {
            let angle = setup.random::<f64>() * std::f64::consts::PI;
            let offset = (setup.random::<f64>() - 0.5) * r_max;
            let sign = if setup.random::<bool>() { 1.0 } else { -1.0 };
            (angle, offset, sign * params.streak_amplitude_hu)
        })
        .collect();
    let ring_width = grid.spacing[0].max(grid.spacing[1]);
    let noise = Normal::new(0.0, params.noise_sd_hu.max(0.0)).ok();
    data.par_chunks_mut(plane).enumerate().for_each(|(k, out)| {
        let mut rng =
            ChaCha8Rng::seed_from_u64(params.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k as u64);
        for j in 0..ny {
            for i in 0..nx {
                let x = i as f64 * grid.spacing[0] - cx;
                let y = j as f64 * grid.spacing[1] - cy;
                let r = (x * x + y * y).sqrt();
                let mut v = out[i + nx * j] as f64;
                v -= params.cupping_hu * (1.0 - (r / r_max).powi(2));
                for (radius, amplitude) in &rings {
                    v += amplitude * (-((r - radius) / ring_width).powi(2)).exp();
                }
                for (angle, offset, amplitude) in &streaks {
                    let d = x * angle.sin() - y * angle.cos() - offset;
                    v += amplitude * (-(d / ring_width).powi(2)).exp();
                }
                if let Some(noise) = &noise {
                    v += noise.sample(&mut rng);
                }
                out[i + nx * j] = v as f32;
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, spacing: f64) -> Grid {
        Grid {
            dims: [n, n, n],
            spacing: [spacing; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
        }
    }

    fn quiet() -> ImagingParams {
        ImagingParams {
            noise_sd_hu: 0.0,
            psf_fwhm_mm: 0.0,
            ..ImagingParams::clean(1)
        }
    }

    #[test]
    fn partial_volume_of_a_half_space_is_the_covered_fraction() {
        // a plane at x = 1.05 mm cuts voxel i = 5 (0.2 mm, spanning 0.9..1.1) at a quarter
        let field = |p: &Point3<f64>| if p.x < 1.05 { 1000.0 } else { 0.0 };
        let params = ImagingParams {
            supersample: 8,
            ..quiet()
        };
        let v = render(&field, &grid(8, 0.2), &params);
        assert!((v.data[v.index(4, 3, 3)] - 1000.0).abs() < 1e-3);
        assert!(
            (v.data[v.index(5, 3, 3)] - 750.0).abs() < 1e-3,
            "{}",
            v.data[v.index(5, 3, 3)]
        );
        assert!(v.data[v.index(6, 3, 3)].abs() < 1e-3);
    }

    #[test]
    fn blur_preserves_the_mean_and_noise_has_its_sd() {
        let field = |p: &Point3<f64>| {
            if (p - Point3::new(1.6, 1.6, 1.6)).norm() < 0.8 {
                1000.0
            } else {
                0.0
            }
        };
        let sharp = render(&field, &grid(16, 0.2), &quiet());
        let blurred = render(
            &field,
            &grid(16, 0.2),
            &ImagingParams {
                psf_fwhm_mm: 0.4,
                ..quiet()
            },
        );
        let mean = |v: &Volume| v.data.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64;
        // the sphere sits well inside, so clamped edges do not change the mean
        assert!((mean(&sharp) - mean(&blurred)).abs() < 1e-3 * mean(&sharp));
        let peak = |v: &Volume| v.data.iter().copied().fold(f32::MIN, f32::max);
        assert!(peak(&blurred) < peak(&sharp));
        let flat = |_: &Point3<f64>| 0.0f32;
        let noisy = render(
            &flat,
            &grid(24, 0.2),
            &ImagingParams {
                noise_sd_hu: 50.0,
                ..quiet()
            },
        );
        let n = noisy.len() as f64;
        let sd = (noisy.data.iter().map(|x| (*x as f64).powi(2)).sum::<f64>() / n).sqrt();
        assert!((sd - 50.0).abs() < 2.0, "sd {sd}");
    }

    #[test]
    fn same_seed_same_image_different_seed_different_noise() {
        let field = |p: &Point3<f64>| (p.x * 100.0) as f32;
        let params = ImagingParams {
            rings: 3,
            ring_amplitude_hu: 30.0,
            streaks: 2,
            streak_amplitude_hu: 50.0,
            cupping_hu: 80.0,
            ..ImagingParams::clean(7)
        };
        let a = render(&field, &grid(10, 0.25), &params);
        let b = render(&field, &grid(10, 0.25), &params);
        assert_eq!(a.data, b.data);
        let c = render(
            &field,
            &grid(10, 0.25),
            &ImagingParams { seed: 8, ..params },
        );
        assert_ne!(a.data, c.data);
    }
}
