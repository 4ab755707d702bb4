//! The chain template and the poses it is scored at: the atlas chain as +1 inside and -1 in
//! a thin shell outside, scored on a bone map at a similarity pose, and the compass search
//! that refines a pose from the coarse correlation's peaks.

use nalgebra::{Point3, Rotation3, Vector3};
use rayon::prelude::*;

use crate::atlas::Atlas;
use crate::image::Sampler;
use crate::mesh::spatial::SignedSurface;

/// A template: point offsets from its centre \[mm\], each with a weight.
#[derive(Debug, Clone)]
pub(super) struct Template {
    pub(super) points: Vec<(Vector3<f64>, f64)>,
    /// The largest offset \[mm\].
    pub(super) radius: f64,
}

impl Template {
    /// The atlas chain (its bones and joints as one solid) on a lattice of spacing `lattice`:
    /// +1 at the points inside it, -1 at those in the shell `shell` mm outside it, each set
    /// normalised to a total weight of 1; offsets from `centre`. `None` when the chain's
    /// surface cannot be indexed.
    pub(super) fn of(
        atlas: &Atlas,
        centre: &Point3<f64>,
        lattice: f64,
        shell: (f64, f64),
    ) -> Option<Template> {
        let surface =
            SignedSurface::new(&atlas.chain_surface(atlas.nodes()), "atlas chain").ok()?;
        let (lo, hi) = surface.bounds();
        let lo = lo.coords - Vector3::repeat(shell.1);
        let n =
            ((hi.coords + Vector3::repeat(shell.1) - lo) / lattice).map(|v| v.ceil() as usize + 1);
        let lattice_points: Vec<Vector3<f64>> = (0..n.z)
            .flat_map(|k| (0..n.y).flat_map(move |j| (0..n.x).map(move |i| (i, j, k))))
            .map(|(i, j, k)| lo + Vector3::new(i as f64, j as f64, k as f64) * lattice)
            .collect();
        let classified: Vec<(Vector3<f64>, i8)> = lattice_points
            .par_iter()
            .filter_map(|p| {
                let d = surface.signed_distance(&Point3::from(*p));
                let class = if d < 0.0 {
                    1
                } else if d > shell.0 && d < shell.1 {
                    -1
                } else {
                    return None;
                };
                Some((p - centre.coords, class))
            })
            .collect();
        let inside = classified.iter().filter(|c| c.1 > 0).count().max(1) as f64;
        let outside = classified.iter().filter(|c| c.1 < 0).count().max(1) as f64;
        let points: Vec<(Vector3<f64>, f64)> = classified
            .into_iter()
            .map(|(p, c)| (p, if c > 0 { 1.0 / inside } else { -1.0 / outside }))
            .collect();
        let radius = points.iter().map(|(p, _)| p.norm()).fold(0.0, f64::max);
        Some(Template { points, radius })
    }

    /// The score at `pose` on `level` (outside the image reads [`UNSEEN`]).
    pub(super) fn score(&self, level: &Sampler, pose: &Pose) -> f64 {
        let m = pose.rotation.matrix() * pose.scale;
        self.points
            .iter()
            .map(|(p, w)| {
                let q = Point3::from(pose.centre + m * p);
                w * level.sample(&q).unwrap_or(UNSEEN) as f64
            })
            .sum()
    }
}

/// The bone map's value outside the image: neither bone nor air, so that a template
/// hanging over the image's edge gains nothing from what it cannot see.
pub(super) const UNSEEN: f32 = 0.5;

/// Where the atlas chain's centre lands, how it is turned and scaled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Pose {
    pub(super) rotation: Rotation3<f64>,
    pub(super) centre: Vector3<f64>,
    pub(super) scale: f64,
}

/// Steps of the pattern search: rotation \[rad\], translation \[mm\], log scale.
#[derive(Debug, Clone, Copy)]
pub(super) struct Steps {
    pub(super) angle: f64,
    pub(super) shift: f64,
    pub(super) log_scale: f64,
}

impl Steps {
    fn halved(self) -> Steps {
        Steps {
            angle: self.angle / 2.0,
            shift: self.shift / 2.0,
            log_scale: self.log_scale / 2.0,
        }
    }
}

/// The scale a refined pose, or a placement after a registration (`auto_landmarks`), may
/// take (people's ossicles differ by about ±15 %).
pub(crate) const SCALE_RANGE: (f64, f64) = (0.8, 1.25);

/// Compass search: each of the seven moves (three turns about the chain's centre, three
/// shifts, the scale) tried both ways; any gain is taken, and when none is left every step is
/// halved, down to `last`'s angle.
pub(super) fn refine(
    template: &Template,
    level: &Sampler,
    start: Pose,
    first: Steps,
    last: f64,
) -> (Pose, f64) {
    let mut pose = start;
    let mut best = template.score(level, &pose);
    let mut steps = first;
    let mut evaluations = 0;
    while steps.angle >= last && evaluations < 2000 {
        let mut improved = false;
        for k in 0..7 {
            for sign in [1.0, -1.0] {
                let mut trial = pose;
                match k {
                    0..3 => {
                        let axis = Vector3::ith(k, sign * steps.angle);
                        trial.rotation = Rotation3::new(axis) * pose.rotation;
                    }
                    3..6 => trial.centre[k - 3] += sign * steps.shift,
                    _ => {
                        trial.scale *= (sign * steps.log_scale).exp();
                        if !(SCALE_RANGE.0..=SCALE_RANGE.1).contains(&trial.scale) {
                            continue;
                        }
                    }
                }
                evaluations += 1;
                let s = template.score(level, &trial);
                if s > best {
                    (pose, best) = (trial, s);
                    improved = true;
                }
            }
        }
        if !improved {
            steps = steps.halved();
        }
    }
    (pose, best)
}

/// Two poses are distinct candidates when their centres are over 2 mm or their turns over
/// 30° apart.
pub(super) fn distinct_poses(a: &Pose, b: &Pose) -> bool {
    (a.centre - b.centre).norm() > 2.0
        || (a.rotation.transpose() * b.rotation).angle() > 30f64.to_radians()
}
