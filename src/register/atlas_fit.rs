//! The atlas registered onto a patient image: the atlas landmarks fitted onto the patient's
//! (rigid or similarity), the atlas placed by that transform, then the deformable stage on its
//! surfaces — ossicle boundaries probed as bone edges through the FEM, then the eardrum.
//!
//! The atlas must already be on the patient's side (see [`Atlas::mirrored`]): three landmarks
//! cannot tell a left ear from a right one, so the side is decided before anything else.

use std::time::Instant;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::DeformSettings;
use super::articulate::{Articulation, articulate, articulated_shape};
use super::deform::{DeformError, DeformResult, DeformStatus, IterationStats, deform};
use super::eardrum::{EardrumFit, fit_eardrum};
use super::probes::probe_triangles;
use super::refine::{Refinement, refine};
use super::rigid::{RigidFit, SimilarityTransform, fit_similarity};
use super::support::EdgeSupport;
use crate::atlas::Atlas;
use crate::ear::Landmarks;
use crate::image::Sampler;
use crate::mesh::quality::{ElementFloors, REGISTRATION_SHAPE_QUALITY, flattest_below_floors};
use crate::progress::Reporter;

/// Fits the atlas landmarks onto the patient's; `None` when the patient's are degenerate.
pub fn fit_landmarks(atlas: &Atlas, patient: &Landmarks, with_scale: bool) -> Option<RigidFit> {
    let source = atlas.landmark_positions(atlas.nodes());
    fit_similarity(&source.points(), &patient.points(), with_scale)
}

/// The atlas nodes mapped by `transform` (atlas to patient: the landmark fit's, or a pose
/// found in the image).
pub fn place(atlas: &Atlas, transform: &SimilarityTransform) -> Vec<Point3<f64>> {
    atlas.nodes().iter().map(|p| transform.apply(p)).collect()
}

/// Wall-clock seconds of each level of the deformable stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct LevelSeconds {
    /// The registrations the atlas was placed again from (`placement`).
    pub placement: f64,
    pub articulate: f64,
    pub fem: f64,
    pub refine: f64,
    pub eardrum: f64,
}

/// What the deformable stage made: the registered nodes with the record of each step.
#[derive(Debug, Clone)]
pub struct Registered {
    /// Each ossicle's own pose (absent when `[articulate]` is off).
    pub articulation: Option<Articulation>,
    pub deform: DeformResult,
    /// The surface level after the FEM levels (absent when `[refine]` is off).
    pub refinement: Option<Refinement>,
    pub eardrum: EardrumFit,
    /// How much of each registered ossicle's surface lies on a bone edge (`support`): measured
    /// on the registration `run` keeps (`placement::deform_placed_again`), empty on the
    /// intermediate ones.
    pub edge_support: Vec<EdgeSupport>,
    /// The scale of each placement of the atlas made from a registration before this one
    /// (`placement::deform_placed_again`), in order.
    pub placed_again: Vec<f64>,
    pub seconds: LevelSeconds,
}

/// The deformable stage's record: `OUT/stages/deform.json`, `metrics.json`'s `deform`, read
/// back by `run --from` and by the reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeformRecord {
    /// Each ossicle's own pose (absent when `[articulate]` is off).
    pub articulation: Option<Articulation>,
    pub status: DeformStatus,
    pub iterations: usize,
    /// The FEM levels' iterations, in order.
    pub history: Vec<IterationStats>,
    /// The surface level after the FEM levels (absent when `[refine]` is off).
    #[serde(default)]
    pub refinement: Option<Refinement>,
    pub eardrum: EardrumFit,
    /// How much of each registered ossicle's surface lies on a bone edge (`support`; empty in
    /// a record written before it was kept).
    #[serde(default)]
    pub edge_support: Vec<EdgeSupport>,
    /// The scale of each placement of the atlas made from a registration before this one
    /// (`[deform] placement_passes`), in order.
    #[serde(default)]
    pub placed_again: Vec<f64>,
    /// The probe step (the smallest voxel spacing) \[mm\].
    pub probe_step_mm: f64,
}

impl Registered {
    /// The record of this registration, probed with step `step` \[mm\].
    pub fn record(&self, step: f64) -> DeformRecord {
        DeformRecord {
            articulation: self.articulation.clone(),
            status: self.deform.status.clone(),
            iterations: self.deform.history.len(),
            history: self.deform.history.clone(),
            refinement: self.refinement.clone(),
            eardrum: self.eardrum,
            edge_support: self.edge_support.clone(),
            placed_again: self.placed_again.clone(),
            probe_step_mm: step,
        }
    }
}

/// The deformable stage from the placed atlas: each ossicle's pose, then the ossicles and
/// their connective tissue through the FEM (its rest shape the articulated atlas), then the
/// eardrum. `step` is the probe step (the smallest voxel spacing, mm). `reference` is the
/// atlas the element floors (`mesh::quality`) compare volumes with: the atlas placed by the
/// landmark fit, as `verify` compares a package's with (`placed` itself, or, when the atlas
/// was placed again from a registration, the placement before).
pub fn deform_atlas(
    atlas: &Atlas,
    placed: &[Point3<f64>],
    reference: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    settings: DeformSettings,
    progress: &dyn Reporter,
) -> Result<Registered, DeformError> {
    let (articulate_cfg, cfg, refine_cfg) = (settings.articulate, settings.deform, settings.refine);
    let moduli = Some((cfg.regularisation_modulus_pa, cfg.min_modulus_ratio));
    let mut seconds = LevelSeconds::default();
    let clock = Instant::now();
    let (rest, articulation) = if articulate_cfg.enabled {
        let (targets, mut record) = articulate(atlas, placed, sampler, step, cfg, articulate_cfg);
        let placed_model = atlas.fem_model(placed, moduli, false)?;
        let x = articulated_shape(
            &placed_model,
            &targets,
            cfg.regularisation_modulus_pa,
            &mut record,
        )?;
        // the carry may squeeze a joint element flat where two bones close in on it: the
        // atlas then goes the largest part of the way (from the placed atlas, in quarters)
        // that keeps every element above the floors
        let flat = flattest_below_floors(&atlas.mesh.tets.tets, reference, &x);
        match flat {
            None => (x, Some(record)),
            Some(flat) => {
                let part_way = |t: f64| -> Vec<Point3<f64>> {
                    placed
                        .iter()
                        .zip(&x)
                        .map(|(p, q)| p + (q - p) * t)
                        .collect()
                };
                let (t, shortened) = [0.75, 0.5, 0.25]
                    .into_iter()
                    .map(|t| (t, part_way(t)))
                    .find(|(_, x)| {
                        flattest_below_floors(&atlas.mesh.tets.tets, reference, x).is_none()
                    })
                    .unwrap_or_else(|| (0.0, placed.to_vec()));
                record.shortened = Some(format!(
                    "carried {:.0} % of the way: all the way, tetrahedron {} would keep shape \
                     quality {:.3} and {:.3} of its atlas volume",
                    100.0 * t,
                    flat.tetrahedron,
                    flat.shape_quality,
                    flat.volume_ratio
                ));
                (shortened, Some(record))
            }
        }
    } else {
        (placed.to_vec(), None)
    };
    // the FEM regularises each level's change from its rest shape; after a level settles, its
    // result becomes the next level's rest shape (coarse to fine: the shape found so far is no
    // longer held back, only the further change is)
    seconds.articulate = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let probes = probe_triangles(atlas);
    let mut rest = rest;
    let mut result: Option<DeformResult> = None;
    for level_index in 0..=cfg.rest_updates {
        let model = atlas.fem_model(&rest, moduli, false)?;
        let floors = ElementFloors::new(
            &atlas.mesh.tets.tets,
            reference,
            &rest,
            REGISTRATION_SHAPE_QUALITY,
        );
        let level = deform(
            &model,
            &floors,
            &probes,
            sampler,
            step,
            cfg,
            settings.steps,
            progress,
        )?;
        // a later level may not flatten an element (`mesh::quality`'s floors): the FEM only
        // keeps a tenth of each element's volume at its own rest shape, and each level
        // regularises from the last one's shape
        if level_index > 0
            && flattest_below_floors(&atlas.mesh.tets.tets, reference, &level.positions).is_some()
        {
            break;
        }
        rest = level.positions.clone();
        let stop = !matches!(level.status, DeformStatus::Converged { .. });
        result = Some(match result {
            None => level,
            Some(mut all) => {
                let offset = all.history.len();
                all.history.extend(level.history.into_iter().map(|mut h| {
                    h.iteration += offset;
                    h
                }));
                all.positions = level.positions;
                all.status = level.status;
                all
            }
        });
        if stop {
            break;
        }
    }
    let Some(mut result) = result else {
        return Err(DeformError::NothingFound);
    };
    seconds.fem = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let refinement = refine_cfg.enabled.then(|| {
        refine(
            &atlas.mesh.tets,
            reference,
            &probes,
            &mut result.positions,
            sampler,
            step,
            settings,
        )
    });
    seconds.refine = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let eardrum = fit_eardrum(atlas, placed, &mut result.positions, sampler, step, cfg);
    seconds.eardrum = clock.elapsed().as_secs_f64();
    // the levels each keep the floors from where they start; an element the first FEM level or
    // the articulation left below them is refused here rather than written into a package
    if let Some(flat) = flattest_below_floors(&atlas.mesh.tets.tets, reference, &result.positions) {
        let region = atlas.mesh.tets.regions[flat.tetrahedron];
        return Err(DeformError::FlatElement {
            tetrahedron: flat.tetrahedron,
            region: atlas
                .region(region)
                .map_or_else(|| format!("region {region}"), |r| r.name.clone()),
            shape_quality: flat.shape_quality,
            volume_ratio: flat.volume_ratio,
        });
    }
    Ok(Registered {
        articulation,
        deform: result,
        refinement,
        eardrum,
        edge_support: Vec::new(),
        placed_again: Vec::new(),
        seconds,
    })
}
