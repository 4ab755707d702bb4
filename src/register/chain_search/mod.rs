//! Finding the ossicular chain in an image without landmarks: where it is, how it is turned,
//! and which ear it is.
//!
//! The ossicles are the densest small structures in an air-filled cavity, so the atlas chain
//! is searched for in the image's bone map (0 for air and soft tissue, 1 for bone, from the
//! image's own levels) as a template: +1 inside the chain (bones and joints as one solid), -1
//! in a thin shell outside it, each part normalised, so that bone inside and air around score
//! up to 1, and solid bone or air score 0.
//!
//! 1. Coarse: the bone map on a 0.5 mm grid, without the bone thicker than 2.5 mm (a
//!    top-hat: the walls and the otic capsule, which would otherwise pass for the chain's
//!    bulk), slightly smoothed. The template is turned through rotations spread over all of
//!    SO(3) (the super-Fibonacci spiral) and, for each, scored at every translation at once
//!    by FFT cross-correlation (`correlate`); each rotation's best local maxima are kept.
//!    Both sides are searched: the left template is the mirror image of the right, and no
//!    rotation turns one into the other.
//! 2. The best distinct poses of each side (2 mm or 30° apart) are refined by a compass
//!    search over rotation, translation and scale on the coarse map, and the best of those
//!    again on a sharp map at the image's resolution.
//! 3. The best refined pose of each side; the better side wins, and the margin between the
//!    two sides' scores is the handedness's evidence. Below `min_score` no chain was found.
//!    The next distinct refined poses are kept as alternatives: the best score can go to the
//!    chain turned about one of its joints by a few thousandths (`auto_landmarks`).
//!
//! The result is a similarity transform of the atlas onto the image: the start that the
//! registration otherwise takes from three picked landmarks.

mod bone_map;
mod correlate;
mod rotations;
mod template;

use std::time::Instant;

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use bone_map::Levels;
use correlate::Correlator;
pub(crate) use template::SCALE_RANGE;
use template::{Pose, Steps, Template, UNSEEN, distinct_poses, refine};

use crate::atlas::Atlas;
use crate::ear::Side;
use crate::image::filter::{downsample, gaussian_blur};
use crate::image::{Sampler, Volume};
use crate::progress::Reporter;
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
    /// The least refined score that counts as a chain found \[1 for a perfect edge\].
    pub min_score: f64,
    /// The coarsest image searched \[mm, smallest voxel spacing\].
    pub max_voxel_mm: f64,
    /// Times the atlas is placed again, by the similarity that best maps its ossicles onto
    /// where the registration took them, and registered again from there
    /// (`auto_landmarks::propose_landmarks`).
    #[serde(default = "default_rescale_passes")]
    pub rescale_passes: usize,
    /// Distinct refined poses of each side kept besides its best (2 mm or 30° from a better
    /// one): registered in turn when the best one's registration leaves the stapes poorly
    /// supported by the image (`auto_landmarks::propose_landmarks`).
    #[serde(default = "default_alternative_poses")]
    pub alternative_poses: usize,
}

fn default_alternative_poses() -> usize {
    3
}

fn default_rescale_passes() -> usize {
    2
}

impl Default for SearchConfig {
    fn default() -> Self {
        SearchConfig {
            rotations: 600,
            coarse_spacing_mm: 0.5,
            candidates: 32,
            min_score: 0.45,
            max_voxel_mm: 0.5,
            rescale_passes: default_rescale_passes(),
            alternative_poses: default_alternative_poses(),
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

/// The coarse search's map leaves out bone this thick (a top-hat), so that the walls and the
/// otic capsule cannot pass for the chain; the ossicles' thin parts (manubrium, long process,
/// crura) stay, and they are what tells the chain's orientation \[mm\].
const THICK_MM: f64 = 2.5;

/// The least difference between the image's bone and air levels \[image units; HU: air is
/// -1000, the ossicles about 1000-1500\].
const MIN_CONTRAST: f64 = 200.0;

/// The least share of the image darker than half-way from air to bone: the tympanic cavity
/// and the ear canal (in the phantoms a third of the field of view or more) \[%\].
const MIN_AIR_PERCENT: f64 = 3.0;

/// Coarse-refined candidates refined again on the sharp map, per side.
const FINE_CANDIDATES: usize = 8;

/// Local maxima of the coarse score kept per rotation: the chain's own peak may be only the
/// second or third of a rotation some degrees off.
const PEAKS_PER_ROTATION: usize = 4;

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
    /// Each side's next distinct refined poses (2 mm or 30° from a better one), best first.
    pub alternatives: Vec<SideMatch>,
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
        let voxel = v.smallest_spacing();
        bone_map::top_hat(&mut v, (thick / voxel / 2.0).round() as usize);
    }
    gaussian_blur(&mut v, sigma);
    v
}

/// The world box of the image's voxel centres.
fn world_box(volume: &Volume) -> (Vector3<f64>, Vector3<f64>) {
    let d = volume.dims.map(|n| n.saturating_sub(1) as f64);
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
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
    let voxel = volume.smallest_spacing();
    if voxel > cfg.max_voxel_mm || !voxel.is_finite() {
        return Err(SearchError::TooCoarse {
            voxel_mm: voxel,
            max_mm: cfg.max_voxel_mm,
        });
    }
    let levels = Levels::of(volume).ok_or(SearchError::NoContrast {
        air: f64::NAN,
        bone: f64::NAN,
    })?;
    if levels.bone - levels.air < MIN_CONTRAST {
        return Err(SearchError::NoContrast {
            air: levels.air,
            bone: levels.bone,
        });
    }
    let half = 0.5 * (levels.air + levels.bone);
    let dark = volume.data.iter().filter(|&&v| (v as f64) < half).count();
    let air_percent = 100.0 * dark as f64 / volume.data.len().max(1) as f64;
    if air_percent < MIN_AIR_PERCENT {
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
    let mut alternatives = Vec::new();
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
        let mut kept: Vec<Pose> = Vec::new();
        for (_, pose) in &found {
            if kept.iter().all(|k| distinct_poses(k, pose)) {
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
                refine(
                    &coarse_template,
                    &coarse,
                    *start,
                    coarse_steps,
                    1f64.to_radians(),
                )
            })
            .collect();
        refined.sort_by(|a, b| b.1.total_cmp(&a.1));
        refined.truncate(FINE_CANDIDATES);
        let mut sharp: Vec<(Pose, f64)> = refined
            .par_iter()
            .map(|(pose, _)| {
                refine(
                    &fine_template,
                    &fine,
                    *pose,
                    fine_steps,
                    0.2f64.to_radians(),
                )
            })
            .collect();
        sharp.sort_by(|a, b| b.1.total_cmp(&a.1));
        // atlas → image: x ↦ s R (x - c) + t
        let side_match = |(pose, score): &(Pose, f64)| {
            let m: Matrix3<f64> = *pose.rotation.matrix();
            let translation = pose.centre - m * centre.coords * pose.scale;
            SideMatch {
                side: side_atlas.side,
                score: *score,
                atlas_to_image: SimilarityTransform::new(m, translation, pose.scale),
            }
        };
        let mut distinct: Vec<&(Pose, f64)> = Vec::new();
        for candidate in &sharp {
            if distinct
                .iter()
                .all(|(k, _)| distinct_poses(k, &candidate.0))
            {
                distinct.push(candidate);
            }
        }
        let best = distinct.first().map_or(
            SideMatch {
                side: side_atlas.side,
                score: f64::NEG_INFINITY,
                atlas_to_image: SimilarityTransform::identity(),
            },
            |c| side_match(c),
        );
        matches.push(best);
        alternatives.extend(
            distinct
                .iter()
                .skip(1)
                .take(cfg.alternative_poses)
                .map(|c| side_match(c)),
        );
    }
    alternatives.sort_by(|a, b| b.score.total_cmp(&a.score));
    let (a, b) = (matches[0], matches[1]);
    let (best, other) = if a.score >= b.score { (a, b) } else { (b, a) };
    if best.score < cfg.min_score || best.score.is_nan() {
        let atlas = sides
            .iter()
            .find(|s| s.side == best.side)
            .unwrap_or(&sides[0]);
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
        alternatives,
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
mod tests {
    use super::*;
    use crate::progress::Silent;

    fn volume(spacing: f64, value: impl Fn(usize) -> f32) -> Volume {
        let n = 24;
        Volume {
            dims: [n; 3],
            spacing: [spacing; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data: (0..n * n * n).map(value).collect(),
        }
    }

    fn search(v: &Volume) -> Result<ChainSearch, SearchError> {
        let right = crate::atlas::load_atlas(None, Some(Side::Right)).unwrap();
        let left = right.mirrored();
        let sides = [
            SideAtlas {
                side: Side::Right,
                atlas: &right,
            },
            SideAtlas {
                side: Side::Left,
                atlas: &left,
            },
        ];
        search_chain(v, &sides, &SearchConfig::default(), &Silent)
    }

    /// What cannot hold a chain is refused before any search, naming why.
    #[test]
    fn coarse_images_and_images_without_air_or_contrast_are_refused() {
        let noise = |i: usize| ((i * 7919) % 200) as f32;
        assert!(matches!(
            search(&volume(0.6, |i| if i % 2 == 0 { -1000.0 } else { 1500.0 })),
            Err(SearchError::TooCoarse { .. })
        ));
        let bone = search(&volume(0.2, |i| 1100.0 + noise(i)));
        assert!(
            matches!(bone, Err(SearchError::NoContrast { .. })),
            "{bone:?}"
        );
        // bone with 2 % of its voxels air: contrast, but no cavity
        let err = search(&volume(0.2, |i| if i % 50 == 0 { -1000.0 } else { 1100.0 })).unwrap_err();
        assert!(matches!(err, SearchError::NoAir { .. }), "{err:?}");
        assert!(err.to_string().contains("tympanic cavity"), "{err}");
    }
}
