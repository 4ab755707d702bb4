//! Trilinear sampling of a [`Volume`] at world (LPS mm) positions, with the world-to-index
//! matrix inverted once so that probing thousands of points per iteration stays cheap.

use nalgebra::{Matrix3, Point3, Vector3};

use super::Volume;

/// A volume prepared for repeated sampling at world positions.
#[derive(Debug, Clone)]
pub struct Sampler<'a> {
    volume: &'a Volume,
    world_to_index: Matrix3<f64>,
    /// Per axis: the last voxel centre's index, the last cell's first index, the stride of
    /// `data`, and the step in `data` to the next voxel (the stride, or 0 along an axis of
    /// one voxel, which has no next).
    top: [f64; 3],
    last_cell: [usize; 3],
    stride: [usize; 3],
    step: [usize; 3],
}

impl<'a> Sampler<'a> {
    /// Prepares `volume`; `None` if its geometry is degenerate (singular direction x spacing)
    /// or it has no voxel.
    pub fn new(volume: &'a Volume) -> Option<Sampler<'a>> {
        let world_to_index = volume.index_to_world_matrix().try_inverse()?;
        let d = volume.dims;
        if volume.is_empty() || volume.data.len() != volume.len() {
            return None;
        }
        let stride = [1, d[0], d[0] * d[1]];
        Some(Sampler {
            volume,
            world_to_index,
            top: d.map(|n| (n - 1) as f64),
            last_cell: d.map(|n| n.saturating_sub(2)),
            stride,
            step: std::array::from_fn(|a| if d[a] > 1 { stride[a] } else { 0 }),
        })
    }

    /// The volume sampled.
    pub fn volume(&self) -> &Volume {
        self.volume
    }

    /// Continuous voxel index of a world position.
    #[inline]
    pub fn index_of(&self, p: &Point3<f64>) -> Vector3<f64> {
        self.world_to_index * (p.coords - self.volume.origin)
    }

    /// True if `p` lies inside the image (within half a voxel of the outer voxel centres).
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        let ijk = self.index_of(p);
        (0..3).all(|a| ijk[a] >= -0.5 && ijk[a] <= self.volume.dims[a] as f64 - 0.5)
    }

    /// Trilinear value at world position `p`; `None` outside the voxel-centre hull.
    #[inline]
    pub fn sample(&self, p: &Point3<f64>) -> Option<f32> {
        let ijk = self.index_of(p);
        let mut i0 = 0;
        let mut frac = [0f64; 3];
        for a in 0..3 {
            let top = self.top[a];
            // round-off at the outer voxel centres still counts as inside
            if !(ijk[a] >= -1e-9 && ijk[a] <= top + 1e-9) {
                return None;
            }
            // not negative, so truncation is the floor (and cheaper); along an axis of one
            // voxel x and the cell's start are both 0, so its fraction is 0
            let x = ijk[a].clamp(0.0, top);
            let b = (x as usize).min(self.last_cell[a]);
            i0 += b * self.stride[a];
            frac[a] = x - b as f64;
        }
        let step = self.step;
        let v = &self.volume.data;
        let lerp = |a: f32, b: f32, t: f64| a as f64 + (b as f64 - a as f64) * t;
        let c00 = lerp(v[i0], v[i0 + step[0]], frac[0]);
        let c10 = lerp(v[i0 + step[1]], v[i0 + step[1] + step[0]], frac[0]);
        let c01 = lerp(v[i0 + step[2]], v[i0 + step[2] + step[0]], frac[0]);
        let c11 = lerp(
            v[i0 + step[2] + step[1]],
            v[i0 + step[2] + step[1] + step[0]],
            frac[0],
        );
        let c0 = c00 + (c10 - c00) * frac[1];
        let c1 = c01 + (c11 - c01) * frac[1];
        Some((c0 + (c1 - c0) * frac[2]) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    /// An oblique volume holding the linear field f(p) = 3 + a·p (world coordinates).
    fn linear_volume() -> (Volume, Vector3<f64>) {
        let a = Vector3::new(0.7, -1.3, 2.1);
        let direction = *Rotation3::from_euler_angles(0.3, 0.5, -0.2).matrix();
        let mut v = Volume {
            dims: [6, 5, 4],
            spacing: [0.5, 0.4, 0.8],
            origin: Vector3::new(1.0, -2.0, 3.0),
            direction,
            data: vec![0.0; 120],
        };
        for k in 0..4 {
            for j in 0..5 {
                for i in 0..6 {
                    let p = v.index_to_world(Vector3::new(i as f64, j as f64, k as f64));
                    let idx = v.index(i, j, k);
                    v.data[idx] = (3.0 + a.dot(&p)) as f32;
                }
            }
        }
        (v, a)
    }

    #[test]
    fn trilinear_reproduces_a_linear_field_anywhere_inside() {
        let (v, a) = linear_volume();
        let s = Sampler::new(&v).unwrap();
        for t in [0.0, 0.13, 0.5, 0.77, 1.0] {
            let ijk = Vector3::new(5.0 * t, 4.0 * (1.0 - t), 3.0 * t * t);
            let p = Point3::from(v.index_to_world(ijk));
            let expected = 3.0 + a.dot(&p.coords);
            let got = s.sample(&p).unwrap() as f64;
            assert!(
                (got - expected).abs() < 1e-4 * expected.abs().max(1.0),
                "{got} vs {expected}"
            );
        }
    }

    #[test]
    fn a_single_slice_is_sampled_bilinearly_in_its_plane() {
        let v = Volume {
            dims: [3, 2, 1],
            spacing: [1.0, 1.0, 1.0],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data: vec![0.0, 1.0, 2.0, 10.0, 11.0, 12.0],
        };
        let s = Sampler::new(&v).unwrap();
        // (1 + 2) / 2 and (11 + 12) / 2, halved again
        assert_eq!(s.sample(&Point3::new(1.5, 0.5, 0.0)), Some(6.5));
        assert_eq!(s.sample(&Point3::new(2.0, 1.0, 0.0)), Some(12.0));
        assert_eq!(s.sample(&Point3::new(1.0, 0.5, 0.1)), None);
    }

    #[test]
    fn an_empty_volume_or_one_its_data_does_not_fill_has_no_sampler() {
        let (mut v, _) = linear_volume();
        let empty = Volume {
            dims: [0, 5, 4],
            data: Vec::new(),
            ..v.clone()
        };
        assert!(Sampler::new(&empty).is_none());
        v.data.pop();
        assert!(Sampler::new(&v).is_none());
    }

    #[test]
    fn outside_is_none_and_contains_agrees() {
        let (v, _) = linear_volume();
        let s = Sampler::new(&v).unwrap();
        let outside = Point3::from(v.index_to_world(Vector3::new(-0.6, 1.0, 1.0)));
        assert!(s.sample(&outside).is_none());
        assert!(!s.contains(&outside));
        let edge = Point3::from(v.index_to_world(Vector3::new(5.0, 4.0, 3.0)));
        assert!(s.sample(&edge).is_some() && s.contains(&edge));
    }
}
