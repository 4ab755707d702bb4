//! Finding the ossicular chain in an image without landmarks: where it is, how it is turned,
//! and which ear it is.
//!
//! The ossicles are the densest small structures in an air-filled cavity, so the atlas's
//! ossicle surfaces are searched for as bone edges: a template of point pairs, one just
//! inside each patch of bone surface (weight +a) and one just outside (weight −a), scores
//! bone inside and air outside, and scores 0 in solid bone and in air alike.
//!
//! 1. Coarse: the image's bone map, smoothed, on a 1 mm grid; the template is turned through
//!    rotations spread over all of SO(3) (the super-Fibonacci spiral) and, for each, scored
//!    at every translation at once by FFT cross-correlation (`correlate`). Both sides are
//!    searched: the left template is the mirror image of the right, and no proper rotation
//!    turns one into the other.
//! 2. The best distinct poses of each side (at least a set distance or angle apart) are
//!    refined by a pattern search over rotation, translation and scale, first on the smoothed
//!    map, then on a sharper one.
//! 3. The best refined pose of each side; the better side wins, and the margin between the
//!    two sides' scores is the handedness's confidence.
//!
//! The result is a similarity transform of the atlas onto the image, the start the
//! registration otherwise takes from three picked landmarks.

mod bone_map;
mod correlate;
mod rotations;

use std::time::Instant;

use nalgebra::{Matrix3, Point3, Rotation3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use bone_map::Levels;
use correlate::Correlator;

use crate::atlas::Atlas;
use crate::ear::Side;
use crate::image::filter::{downsample, gaussian_blur};
use crate::image::{Sampler, Volume};
use crate::progress::Reporter;
use crate::mesh::spatial::SignedSurface;
use crate::register::probes::probe_triangles;
use crate::register::rigid::SimilarityTransform;

/// The search's settings (`[auto_landmarks]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchConfig {
    /// Rotations tried per side in the coarse search.
    pub rotations: usize,
    /// Grid spacing of the coarse search \[mm\] (coarser for a field of view wider than 80
    /// such steps).
    pub coarse_spacing_mm: f64,
    /// Distinct coarse poses refined per side.
    pub candidates: usize,
    /// The least refined score that counts as a chain found \[fraction of a perfect edge\].
    pub min_score: f64,
    /// The coarsest image searched \[mm, smallest voxel spacing\].
    pub max_voxel_mm: f64,
}

impl Default for SearchConfig {
    fn default() -> Self {
        SearchConfig {
            rotations: 600,
            coarse_spacing_mm: 0.5,
            candidates: 32,
            min_score: 0.3,
            max_voxel_mm: 0.5,
        }
    }
}

/// Why no chain was found.
#[derive(Debug, thiserror::Error)]
pub enum SearchError {
    #[error(
        "the image is too coarse to find the ossicles in: {voxel_mm:.3} mm voxels (the search \
         needs {max_mm} mm or finer; the stapes's crura are about 0.3 mm thick)"
    )]
    TooCoarse { voxel_mm: f64, max_mm: f64 },
    #[error(
        "the image has no contrast to find bone in: its 1st and 99.5th percentiles are \
         {air:.0} and {bone:.0}"
    )]
    NoContrast { air: f64, bone: f64 },
    #[error(
        "no air cavity in the image: {air_percent:.2} % of it is darker than half-way from its \
         air level ({air:.0}) to its bone level ({bone:.0}); the ossicles lie in the air of the \
         tympanic cavity"
    )]
    NoAir {
        air_percent: f64,
        air: f64,
        bone: f64,
    },
    #[error(
        "no ossicular chain found: {rotations} orientations of each side's atlas chain were \
         tried at every position in the field of view and the best refined match scores \
         {best:.2} ({side} ear, centre at {centre_mm:.1?} mm LPS), below the {min:.2} a chain \
         scores; is the middle ear in the field of view?"
    )]
    NotFound {
        rotations: usize,
        best: f64,
        min: f64,
        side: &'static str,
        centre_mm: [f64; 3],
    },
}

/// A template: point offsets from its centre \[mm\], each with a weight.
#[derive(Debug, Clone)]
struct Template {
    points: Vec<(Vector3<f64>, f64)>,
    /// The largest offset \[mm\].
    radius: f64,
}

impl Template {
    /// The atlas chain (its bones and joints as one solid) on a lattice of spacing `lattice`:
    /// +1 at the points inside it, -1 at those in the shell `shell` mm outside it, each set
    /// normalised to a total weight of 1; offsets from `centre`. `None` when the chain's
    /// surface cannot be indexed.
    fn of(atlas: &Atlas, centre: &Point3<f64>, lattice: f64, shell: (f64, f64)) -> Option<Template> {
        let surface = SignedSurface::new(&atlas.chain_surface(atlas.nodes()), "atlas chain").ok()?;
        let (lo, hi) = surface.bounds();
        let lo = lo.coords - Vector3::repeat(shell.1);
        let n = ((hi.coords + Vector3::repeat(shell.1) - lo) / lattice).map(|v| v.ceil() as usize + 1);
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
    fn score(&self, level: &Sampler, pose: &Pose) -> f64 {
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

/// The coarse search's map leaves out bone this thick (a top-hat), so that the walls and the
/// otic capsule cannot pass for the chain; the ossicles' thin parts (manubrium, long process,
/// crura) stay, and they are what tells the chain's orientation \[mm\].
const THICK_MM: f64 = 2.5;

/// Coarse-refined candidates refined again on the sharp map, per side.
const FINE_CANDIDATES: usize = 8;

/// Local maxima of the coarse score kept per rotation: the chain's own peak may be only the
/// second or third of a rotation some degrees off.
const PEAKS_PER_ROTATION: usize = 4;

/// The bone map's value outside the image: neither bone nor air, so that a template
/// hanging over the image's edge gains nothing from what it cannot see.
const UNSEEN: f32 = 0.5;

/// Where the atlas chain's centre lands, how it is turned and scaled.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pose {
    rotation: Rotation3<f64>,
    centre: Vector3<f64>,
    scale: f64,
}

/// Steps of the pattern search: rotation \[rad\], translation \[mm\], log scale.
#[derive(Debug, Clone, Copy)]
struct Steps {
    angle: f64,
    shift: f64,
    log_scale: f64,
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

/// The scale a refined pose may take (people's ossicles differ by about ±15 %).
const SCALE_RANGE: (f64, f64) = (0.8, 1.25);

/// Compass search: each of the seven moves (three turns about the chain's centre, three
/// shifts, the scale) tried both ways; any gain is taken, and when none is left every step is
/// halved, down to `last`'s angle.
fn refine(template: &Template, level: &Sampler, start: Pose, first: Steps, last: f64) -> (Pose, f64) {
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

/// One side's best pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SideMatch {
    pub side: Side,
    /// The refined score on the sharp bone map \[fraction of a perfect edge\].
    pub score: f64,
    /// The atlas (on this side) onto the image.
    pub atlas_to_image: SimilarityTransform,
}

/// What the search found: the chosen side's match, the other side's, and its figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainSearch {
    pub best: SideMatch,
    /// The other side's best match (the handedness's evidence).
    pub other: SideMatch,
    /// 1 - other / best: how much better the chosen side's mirror image fits \[fraction\].
    pub side_margin: f64,
    /// The image's air and bone levels \[image units\].
    pub air_level: f64,
    pub bone_level: f64,
    pub rotations_per_side: usize,
    pub candidates_per_side: usize,
    pub coarse_spacing_mm: f64,
    pub seconds: f64,
}

/// The atlas of each side, with the centre of its ossicle surfaces.
pub struct SideAtlas<'a> {
    pub side: Side,
    pub atlas: &'a Atlas,
}

/// Area-weighted centre of the atlas's probed ossicle surfaces.
fn chain_centre(atlas: &Atlas) -> Point3<f64> {
    let x = atlas.nodes();
    let (mut sum, mut area) = (Vector3::zeros(), 0.0);
    for t in probe_triangles(atlas) {
        let [a, b, c] = t.nodes.map(|k| x[k as usize]);
        let w = 0.5 * (b - a).cross(&(c - a)).norm();
        sum += (a.coords + b.coords + c.coords) / 3.0 * w;
        area += w;
    }
    Point3::from(sum / area.max(f64::MIN_POSITIVE))
}

/// The image's bone map averaged to about `spacing`, without the bone thicker than
/// `thick_mm` when given, and smoothed by `sigma` \[mm\].
fn level(bone: &Volume, spacing: f64, thick_mm: Option<f64>, sigma: f64) -> Volume {
    let mut v = downsample(bone, spacing);
    if let Some(thick) = thick_mm {
        let voxel = v.spacing.iter().copied().fold(f64::INFINITY, f64::min);
        bone_map::top_hat(&mut v, (thick / voxel / 2.0).round() as usize);
    }
    gaussian_blur(&mut v, sigma);
    v
}

/// The world box of the image's voxel centres.
fn world_box(volume: &Volume) -> (Vector3<f64>, Vector3<f64>) {
    let d = volume.dims.map(|n| n.saturating_sub(1) as f64);
    let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
    for corner in 0..8 {
        let ijk = Vector3::from_fn(|a, _| if (corner >> a) & 1 == 1 { d[a] } else { 0.0 });
        let p = volume.index_to_world(ijk);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    (lo, hi)
}

/// Searches `volume` for the chain of each side's atlas.
pub fn search_chain(
    volume: &Volume,
    sides: &[SideAtlas; 2],
    cfg: &SearchConfig,
    progress: &dyn Reporter,
) -> Result<ChainSearch, SearchError> {
    let clock = Instant::now();
    let voxel = volume.spacing.iter().copied().fold(f64::INFINITY, f64::min);
    if !(voxel <= cfg.max_voxel_mm) {
        return Err(SearchError::TooCoarse {
            voxel_mm: voxel,
            max_mm: cfg.max_voxel_mm,
        });
    }
    let levels = Levels::of(volume).ok_or(SearchError::NoContrast {
        air: f64::NAN,
        bone: f64::NAN,
    })?;
    if !(levels.bone - levels.air > 200.0) {
        return Err(SearchError::NoContrast {
            air: levels.air,
            bone: levels.bone,
        });
    }
    let half = 0.5 * (levels.air + levels.bone);
    let dark = volume.data.iter().filter(|&&v| (v as f64) < half).count();
    let air_percent = 100.0 * dark as f64 / volume.data.len().max(1) as f64;
    if air_percent < 1.0 {
        return Err(SearchError::NoAir {
            air_percent,
            air: levels.air,
            bone: levels.bone,
        });
    }
    let bone = bone_map::bone_map(volume, &levels);
    let coarse_volume = level(&bone, 0.5, Some(THICK_MM), 0.2);
    let fine_volume = level(&bone, voxel.max(0.2), None, 0.25);
    drop(bone);
    let (coarse, fine) = match (Sampler::new(&coarse_volume), Sampler::new(&fine_volume)) {
        (Some(c), Some(f)) => (c, f),
        _ => {
            return Err(SearchError::NoContrast {
                air: levels.air,
                bone: levels.bone,
            });
        }
    };
    let rotations = rotations::super_fibonacci(cfg.rotations.max(1));
    let (lo, hi) = world_box(volume);
    let extent = (hi - lo).max();
    let h = cfg.coarse_spacing_mm.max(extent / 80.0);
    progress.log(&format!(
        "chain search: {} rotations x 2 sides on a {h:.2} mm grid",
        rotations.len()
    ));
    let mut matches = Vec::new();
    for side_atlas in sides {
        let centre = chain_centre(side_atlas.atlas);
        let (Some(coarse_template), Some(fine_template)) = (
            Template::of(side_atlas.atlas, &centre, 0.5, (0.25, 0.75)),
            Template::of(side_atlas.atlas, &centre, 0.25, (0.15, 0.5)),
        ) else {
            matches.push(SideMatch {
                side: side_atlas.side,
                score: f64::NEG_INFINITY,
                atlas_to_image: SimilarityTransform::identity(),
            });
            continue;
        };
        let pad = coarse_template.radius * SCALE_RANGE.1 + h;
        // the chain's centre lies inside the field of view, not at its edge
        let inset = Vector3::repeat(2.0).inf(&((hi - lo) / 2.0));
        let correlator = Correlator::new(&coarse, (lo + inset, hi - inset), h, pad, UNSEEN);
        let mut found: Vec<(f64, Pose)> = rotations
            .par_iter()
            .map_init(Vec::new, |buffer, r| {
                let peaks = correlator.best_translations(
                    &coarse_template.points,
                    r.matrix(),
                    1.0,
                    PEAKS_PER_ROTATION,
                    buffer,
                );
                peaks
                    .into_iter()
                    .map(|(score, centre)| {
                        let pose = Pose {
                            rotation: *r,
                            centre,
                            scale: 1.0,
                        };
                        (score, pose)
                    })
                    .collect::<Vec<_>>()
            })
            .flatten()
            .collect();
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        // distinct poses: 2 mm or 30° from every one kept
        let mut kept: Vec<Pose> = Vec::new();
        for (_, pose) in &found {
            let distinct = kept.iter().all(|k| {
                (k.centre - pose.centre).norm() > 2.0
                    || (k.rotation.transpose() * pose.rotation).angle() > 30f64.to_radians()
            });
            if distinct {
                kept.push(*pose);
                if kept.len() == cfg.candidates.max(1) {
                    break;
                }
            }
        }
        let coarse_steps = Steps {
            angle: 10f64.to_radians(),
            shift: 0.5,
            log_scale: 0.05,
        };
        let fine_steps = Steps {
            angle: 3f64.to_radians(),
            shift: 0.3,
            log_scale: 0.02,
        };
        // every candidate refined on the coarse map, the best on the sharp one
        let mut refined: Vec<(Pose, f64)> = kept
            .par_iter()
            .map(|start| {
                refine(&coarse_template, &coarse, *start, coarse_steps, 1f64.to_radians())
            })
            .collect();
        refined.sort_by(|a, b| b.1.total_cmp(&a.1));
        refined.truncate(FINE_CANDIDATES);
        let best = refined
            .par_iter()
            .map(|(pose, _)| {
                refine(&fine_template, &fine, *pose, fine_steps, 0.2f64.to_radians())
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let (pose, score) = best.unwrap_or((
            Pose {
                rotation: Rotation3::identity(),
                centre: (lo + hi) / 2.0,
                scale: 1.0,
            },
            f64::NEG_INFINITY,
        ));
        // atlas → image: x ↦ s R (x - c) + t
        let m: Matrix3<f64> = *pose.rotation.matrix();
        let translation = pose.centre - m * centre.coords * pose.scale;
        matches.push(SideMatch {
            side: side_atlas.side,
            score,
            atlas_to_image: SimilarityTransform::new(m, translation, pose.scale),
        });
    }
    let (a, b) = (matches[0], matches[1]);
    let (best, other) = if a.score >= b.score { (a, b) } else { (b, a) };
    if !(best.score >= cfg.min_score) {
        let atlas = sides.iter().find(|s| s.side == best.side).unwrap_or(&sides[0]);
        let centre = best.atlas_to_image.apply(&chain_centre(atlas.atlas));
        return Err(SearchError::NotFound {
            rotations: rotations.len(),
            best: best.score.max(0.0),
            min: cfg.min_score,
            side: best.side.as_str(),
            centre_mm: centre.coords.into(),
        });
    }
    Ok(ChainSearch {
        best,
        other,
        side_margin: 1.0 - other.score.max(0.0) / best.score,
        air_level: levels.air,
        bone_level: levels.bone,
        rotations_per_side: rotations.len(),
        candidates_per_side: cfg.candidates,
        coarse_spacing_mm: h,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod debug_tests {
    use super::*;

    #[test]
    #[ignore]
    fn debug_sample_case() {
        let case = std::path::PathBuf::from(std::env::var("DEBUG_CASE").unwrap());
        let loaded = crate::image::load(&case.join("image.nii.gz"), None, &crate::config::Config::default_config().unwrap().ingest).unwrap();
        let atlas = crate::atlas::load_atlas(None, Some(Side::Right)).unwrap();
        let truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(case.join("truth.json")).unwrap()).unwrap();
        let pt = |k: &str| {
            let a = &truth["landmarks"][k];
            Point3::new(a[0].as_f64().unwrap(), a[1].as_f64().unwrap(), a[2].as_f64().unwrap())
        };
        let lm = crate::ear::Landmarks::from_points([pt("umbo"), pt("incudomalleolar"), pt("incudostapedial")]);
        let fit = crate::register::atlas_fit::fit_landmarks(&atlas, &lm, true).unwrap();
        let volume = &loaded.volume;
        let levels = Levels::of(volume).unwrap();
        eprintln!("levels {levels:?}");
        let bone = bone_map::bone_map(volume, &levels);
        let thick: f64 = std::env::var("DEBUG_THICK").unwrap().parse().unwrap();
        let coarse_volume = level(&bone, 0.5, (thick > 0.0).then_some(thick), std::env::var("DEBUG_SIGMA").unwrap().parse().unwrap());
        let fine_volume = level(&bone, volume.spacing[0].max(0.2), None, 0.25);
        let coarse = Sampler::new(&coarse_volume).unwrap();
        let fine = Sampler::new(&fine_volume).unwrap();
        let centre = chain_centre(&atlas);
        let ev = |k: &str| -> f64 { std::env::var(k).unwrap().parse().unwrap() };
        let ct = Template::of(&atlas, &centre, 0.5, (ev("DEBUG_S0"), ev("DEBUG_S1"))).unwrap();
        let ft = Template::of(&atlas, &centre, 0.25, (0.15, 0.5)).unwrap();
        eprintln!("points {} {} radius {}", ct.points.len(), ft.points.len(), ct.radius);
        let t = fit.transform;
        let pose = Pose { rotation: Rotation3::from_matrix_unchecked(t.rotation_matrix()), centre: t.apply(&centre).coords, scale: t.scale };
        eprintln!("truth pose: coarse {:.3} fine {:.3}", ct.score(&coarse, &pose), ft.score(&fine, &pose));
        // inner only, outer only
        let inner: f64 = ft.points.iter().filter(|p| p.1 > 0.0).map(|(p, w)| w * fine.sample(&Point3::from(pose.centre + pose.rotation.matrix() * p * pose.scale)).unwrap_or(-1.0) as f64).sum();
        let outer: f64 = ft.points.iter().filter(|p| p.1 < 0.0).map(|(p, w)| w * fine.sample(&Point3::from(pose.centre + pose.rotation.matrix() * p * pose.scale)).unwrap_or(-1.0) as f64).sum();
        eprintln!("inner {inner:.3} outer {outer:.3}");
        let parts = |t: &Template, lv: &Sampler, pose: &Pose| {
            let f = |sign: f64| -> f64 { t.points.iter().filter(|p| p.1 * sign > 0.0).map(|(p, w)| w.abs() * lv.sample(&Point3::from(pose.centre + pose.rotation.matrix() * p * pose.scale)).unwrap_or(0.5) as f64).sum() };
            (f(1.0), f(-1.0))
        };
        eprintln!("coarse parts at truth {:?}", parts(&ct, &coarse, &pose));
        let raw = Sampler::new(volume).unwrap();
        let bs = Sampler::new(&bone).unwrap();
        for k in ["umbo", "incudomalleolar", "incudostapedial"] {
            let p = pt(k);
            eprintln!("{k}: raw {:?} bone {:?} fine {:?} coarse {:?}", raw.sample(&p), bs.sample(&p), fine.sample(&p), coarse.sample(&p));
        }
        let n_in = ct.points.iter().filter(|p| p.1 > 0.0).count();
        eprintln!("coarse inner points {n_in}, fine inner {}", ft.points.iter().filter(|p| p.1 > 0.0).count());
        let surf = atlas.chain_surface(atlas.nodes());
        eprintln!("chain surface volume {:.2} area {:.2}", surf.signed_volume(), surf.area());
        let (lo, hi) = world_box(volume);
        eprintln!("box {lo:?} {hi:?} dims {:?}", volume.dims);
        let t0 = std::time::Instant::now();
        let corr = Correlator::new(&coarse, (lo, hi), 0.5, ct.radius * 1.25 + 1.0, UNSEEN);
        eprintln!("grid {} built in {:?}", corr.len(), t0.elapsed());
        let mut buf = Vec::new();
        let t0 = std::time::Instant::now();
        let (s, c) = corr.best_translations(&ct.points, pose.rotation.matrix(), pose.scale, 1, &mut buf)[0];
        eprintln!("one rotation {:?}", t0.elapsed());
        eprintln!("fft at truth rotation: {s:.3} at {c:?} (truth centre {:?})", pose.centre);
        let at = Pose { centre: c, scale: 1.0, ..pose };
        eprintln!("coarse parts at fft {:?} direct {:.3}", parts(&ct, &coarse, &at), ct.score(&coarse, &at));
        for dz in [-1.0, 0.0, 1.0] { for dy in [-1.0, 0.0, 1.0] { for dx in [-1.0f64, 0.0, 1.0] {
            let p = Pose { centre: pose.centre + Vector3::new(dx, dy, dz) * 0.5, ..pose };
            eprint!("{:.2} ", ct.score(&coarse, &p));
        }}}
        eprintln!();
        let rots = rotations::super_fibonacci(std::env::var("DEBUG_ROT").unwrap().parse().unwrap());
        let t0 = std::time::Instant::now();
        let mut found: Vec<(f64, Pose)> = rots.par_iter().map_init(Vec::new, |b, r| {
            corr.best_translations(&ct.points, r.matrix(), 1.0, 4, b).into_iter().map(|(s, c)|
            (s, Pose { rotation: *r, centre: c, scale: 1.0 })).collect::<Vec<_>>()
        }).flatten().collect();
        eprintln!("600 rotations {:?}", t0.elapsed());
        found.sort_by(|a, b| b.0.total_cmp(&a.0));
        let near = found.iter().position(|(_, p)| (p.centre - pose.centre).norm() < 2.0 && (p.rotation.transpose() * pose.rotation).angle() < 25f64.to_radians());
        let best_rot = found.iter().map(|(_, p)| (p.rotation.transpose() * pose.rotation).angle().to_degrees()).fold(999.0, f64::min);
        eprintln!("first near truth at rank {near:?} (score {:?}); nearest rotation sampled {best_rot:.1} deg", near.map(|k| found[k].0));
        let mut kept: Vec<(f64, Pose)> = Vec::new();
        for (sc, p) in &found {
            if kept.iter().all(|(_, k)| (k.centre - p.centre).norm() > 2.0 || (k.rotation.transpose() * p.rotation).angle() > 30f64.to_radians()) {
                kept.push((*sc, *p));
                if kept.len() == 60 { break; }
            }
        }
        let t0 = std::time::Instant::now();
        let mut refined: Vec<(f64, Pose, f64, Pose)> = kept.par_iter().map(|(sc, p)| {
            let (r1, s1) = refine(&ct, &coarse, *p, Steps { angle: 0.17, shift: 0.5, log_scale: 0.05 }, 0.017);
            (*sc, *p, s1, r1)
        }).collect();
        eprintln!("coarse refinement of {} in {:?}", kept.len(), t0.elapsed());
        refined.sort_by(|a, b| b.2.total_cmp(&a.2));
        for (rank, (sc, p, s1, r1)) in refined.iter().take(12).enumerate() {
            let (sc, p, s1, r1) = (*sc, *p, *s1, *r1);
            let (r2, s2) = refine(&ft, &fine, r1, Steps { angle: 0.05, shift: 0.3, log_scale: 0.02 }, 0.0035);
            eprintln!("#{rank} {sc:.3} dist {:.1} angle {:.0} -> coarse {s1:.3} dist {:.1} angle {:.0} -> fine {s2:.3} dist {:.2} angle {:.1}",
                (p.centre - pose.centre).norm(), (p.rotation.transpose() * pose.rotation).angle().to_degrees(),
                (r1.centre - pose.centre).norm(), (r1.rotation.transpose() * pose.rotation).angle().to_degrees(),
                (r2.centre - pose.centre).norm(), (r2.rotation.transpose() * pose.rotation).angle().to_degrees());
        }
        let (p2, s2) = refine(&ct, &coarse, pose, Steps { angle: 0.17, shift: 1.0, log_scale: 0.05 }, 0.017);
        eprintln!("refined from truth: {s2:.3} moved {:.2}", (p2.centre - pose.centre).norm());
    }
}
