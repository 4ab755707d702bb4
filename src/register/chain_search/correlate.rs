//! The score of a point template at every translation at once: the template, rotated, is
//! splatted onto a regular world grid and cross-correlated with the image's bone map by FFT
//! (S = F⁻¹(conj(F T) · F G)), so one rotation costs two 3-D FFTs whatever the field of view.
//! Splatting with trilinear weights is the adjoint of trilinear sampling, so S at a grid node
//! is exactly the template's score (Σ wᵢ G(t + pᵢ), G interpolated) placed there.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

use crate::image::Sampler;

/// A world-aligned grid holding the bone map's spectrum, ready to correlate templates with.
pub struct Correlator {
    /// World position of node (0, 0, 0) \[mm\].
    origin: Vector3<f64>,
    /// Node spacing \[mm\].
    h: f64,
    n: [usize; 3],
    /// The nodes where a template's centre may lie (inside the image), per axis.
    valid: [std::ops::Range<usize>; 3],
    spectrum: Vec<Complex32>,
    forward: [Arc<dyn Fft<f32>>; 3],
    inverse: [Arc<dyn Fft<f32>>; 3],
}

/// The smallest n' ≥ n whose prime factors are 2, 3 and 5 (fast FFT lengths).
fn smooth_length(n: usize) -> usize {
    (n.max(1)..)
        .find(|&m| {
            let mut r = m;
            for p in [2, 3, 5] {
                while r % p == 0 {
                    r /= p;
                }
            }
            r == 1
        })
        .unwrap_or(n)
}

/// One FFT along `axis` of every line of a grid of size `n` (i fastest).
fn fft_axis(data: &mut [Complex32], n: [usize; 3], axis: usize, fft: &dyn Fft<f32>) {
    // one scratch for every line (`Fft::process` would allocate one per call)
    let mut scratch = vec![Complex32::default(); fft.get_inplace_scratch_len()];
    if axis == 0 {
        fft.process_with_scratch(data, &mut scratch);
        return;
    }
    let len = n[axis];
    let stride = if axis == 1 { n[0] } else { n[0] * n[1] };
    let mut line = vec![Complex32::default(); len];
    let outer = data.len() / (len * stride);
    for o in 0..outer {
        for i in 0..stride {
            let base = o * len * stride + i;
            for (k, v) in line.iter_mut().enumerate() {
                *v = data[base + k * stride];
            }
            fft.process_with_scratch(&mut line, &mut scratch);
            for (k, v) in line.iter().enumerate() {
                data[base + k * stride] = *v;
            }
        }
    }
}

impl Correlator {
    /// The bone map `level` sampled on a grid of spacing `h` over the world box `lo..hi`
    /// (the image) widened by `pad` on every side, so that a template of radius ≤ `pad`
    /// centred anywhere in the box never wraps around; `unseen` outside the image.
    pub fn new(
        level: &Sampler,
        (lo, hi): (Vector3<f64>, Vector3<f64>),
        h: f64,
        pad: f64,
        unseen: f32,
    ) -> Self {
        let margin = (pad / h).ceil() as usize + 1;
        let inner: [usize; 3] = std::array::from_fn(|a| ((hi[a] - lo[a]) / h).ceil() as usize + 1);
        let n: [usize; 3] = std::array::from_fn(|a| smooth_length(inner[a] + 2 * margin));
        let origin = lo - Vector3::repeat(margin as f64 * h);
        let valid = std::array::from_fn(|a| margin..margin + inner[a]);
        let mut grid = vec![Complex32::default(); n.iter().product()];
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let p = origin + Vector3::new(i as f64, j as f64, k as f64) * h;
                    let v = level.sample(&p.into()).unwrap_or(unseen);
                    grid[i + n[0] * (j + n[1] * k)] = Complex32::new(v, 0.0);
                }
            }
        }
        let mut planner = FftPlanner::<f32>::new();
        let forward = std::array::from_fn(|a| planner.plan_fft_forward(n[a]));
        let inverse = std::array::from_fn(|a| planner.plan_fft_inverse(n[a]));
        let mut correlator = Correlator {
            origin,
            h,
            n,
            valid,
            spectrum: Vec::new(),
            forward,
            inverse,
        };
        correlator.transform(&mut grid, false);
        correlator.spectrum = grid;
        correlator
    }

    /// Number of grid nodes.
    pub fn len(&self) -> usize {
        self.n.iter().product()
    }

    fn transform(&self, data: &mut [Complex32], inverse: bool) {
        let plans = if inverse {
            &self.inverse
        } else {
            &self.forward
        };
        for (axis, plan) in plans.iter().enumerate() {
            fft_axis(data, self.n, axis, plan.as_ref());
        }
    }

    /// The template `points` (offsets from its centre \[mm\] with weights) turned by
    /// `rotation` and scaled by `scale`: its `count` best centres inside the image (world mm)
    /// that are local maxima of the score over their 26 neighbours, best first, with their
    /// scores. `buffer` is scratch of [`Correlator::len`] values.
    pub fn best_translations(
        &self,
        points: &[(Vector3<f64>, f64)],
        rotation: &Matrix3<f64>,
        scale: f64,
        count: usize,
        buffer: &mut Vec<Complex32>,
    ) -> Vec<(f64, Vector3<f64>)> {
        let n = self.n;
        buffer.clear();
        buffer.resize(self.len(), Complex32::default());
        for (p, w) in points {
            let q = rotation * p * (scale / self.h);
            let base = q.map(f64::floor);
            let frac = q - base;
            for corner in 0..8 {
                let mut weight = *w;
                let mut index = 0usize;
                let mut stride = 1usize;
                for a in 0..3 {
                    let up = (corner >> a) & 1 == 1;
                    weight *= if up { frac[a] } else { 1.0 - frac[a] };
                    let c = (base[a] as i64 + up as i64).rem_euclid(n[a] as i64) as usize;
                    index += c * stride;
                    stride *= n[a];
                }
                buffer[index] += Complex32::new(weight as f32, 0.0);
            }
        }
        self.transform(buffer, false);
        for (t, g) in buffer.iter_mut().zip(&self.spectrum) {
            *t = t.conj() * g;
        }
        self.transform(buffer, true);
        let norm = 1.0 / self.len() as f64;
        let at = |i: usize, j: usize, k: usize| buffer[i + n[0] * (j + n[1] * k)].re;
        let mut best: Vec<(f64, Vector3<f64>)> = Vec::with_capacity(count + 1);
        for k in self.valid[2].clone() {
            for j in self.valid[1].clone() {
                for i in self.valid[0].clone() {
                    let v = at(i, j, k);
                    let worst = best.last().map_or(f64::NEG_INFINITY, |b| b.0);
                    if best.len() == count && (v as f64) * norm <= worst {
                        continue;
                    }
                    // the valid range lies inside the padding, so every neighbour exists
                    let is_peak = (0..27).all(|m| {
                        let d = [m % 3, (m / 3) % 3, m / 9];
                        m == 13 || at(i + d[0] - 1, j + d[1] - 1, k + d[2] - 1) <= v
                    });
                    if is_peak {
                        let p = self.origin + Vector3::new(i as f64, j as f64, k as f64) * self.h;
                        let score = v as f64 * norm;
                        let slot = best.partition_point(|b| b.0 >= score);
                        best.insert(slot, (score, p));
                        best.truncate(count);
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Volume;
    use nalgebra::{Point3, Rotation3};

    #[test]
    fn smooth_lengths_have_only_small_prime_factors() {
        assert_eq!(smooth_length(31), 32);
        assert_eq!(smooth_length(49), 50);
        assert_eq!(smooth_length(7), 8);
        assert_eq!(smooth_length(45), 45);
    }

    /// The FFT's score at every centre is the direct sum Σ w G(t + R p), and the best centre
    /// is where a blob put into the image is.
    #[test]
    fn the_correlation_is_the_direct_score_and_finds_the_blob() {
        let dims = [30, 26, 22];
        let spacing = 0.5;
        let origin = Vector3::new(-3.0, 4.0, 1.0);
        let blob = Vector3::new(2.5, 9.0, 5.5);
        let mut data = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = origin + Vector3::new(i as f64, j as f64, k as f64) * spacing;
                    let d = p - blob;
                    // an elongated blob, so that the rotation matters
                    let r2 = d.x * d.x / 4.0 + d.y * d.y + d.z * d.z / 0.5;
                    data.push((-r2).exp() as f32);
                }
            }
        }
        let volume = Volume {
            dims,
            spacing: [spacing; 3],
            origin,
            direction: Matrix3::identity(),
            data,
        };
        let sampler = Sampler::new(&volume).unwrap();
        let hi = origin + Vector3::new(29.0, 25.0, 21.0) * spacing;
        let h = 0.5;
        let correlator = Correlator::new(&sampler, (origin, hi), h, 3.0, 0.0);
        // a template along x: +1 on the axis, -1 beside it
        let points: Vec<(Vector3<f64>, f64)> = (-2..=2)
            .flat_map(|i| {
                let x = i as f64;
                [
                    (Vector3::new(x, 0.0, 0.0), 1.0),
                    (Vector3::new(x, 1.5, 0.0), -0.5),
                    (Vector3::new(x, -1.5, 0.0), -0.5),
                ]
            })
            .collect();
        let mut buffer = Vec::new();
        let along_x = Matrix3::identity();
        let (score, centre) =
            correlator.best_translations(&points, &along_x, 1.0, 1, &mut buffer)[0];
        assert!((centre - blob).norm() < 0.3, "{centre} vs {blob}");
        let direct: f64 = points
            .iter()
            .map(|(p, w)| w * sampler.sample(&Point3::from(centre + p)).unwrap_or(0.0) as f64)
            .sum();
        assert!((score - direct).abs() < 1e-3, "{score} vs {direct}");
        // turned across the blob, the template scores less
        let across = *Rotation3::from_axis_angle(&Vector3::z_axis(), 1.2).matrix();
        let (turned, _) = correlator.best_translations(&points, &across, 1.0, 1, &mut buffer)[0];
        assert!(turned < score - 0.5, "{turned} vs {score}");
    }
}
