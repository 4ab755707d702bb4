//! The atlas registered onto a patient image: the atlas landmarks fitted onto the patient's
//! (rigid or similarity), the atlas placed by that transform, then the deformable stage on its
//! surfaces — ossicle boundaries probed as bone edges through the FEM, then the eardrum.
//!
//! The atlas must already be on the patient's side (see [`Atlas::mirrored`]): three landmarks
//! cannot tell a left ear from a right one, so the side is decided before anything else.

use std::time::Instant;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::articulate::{ArticulateConfig, Articulation, articulate, articulated_shape};
use super::deform::{
    DeformConfig, DeformError, DeformResult, DeformStatus, IterationStats, deform,
};
use super::eardrum::{EardrumFit, fit_eardrum};
use super::probes::probe_triangles;
use super::refine::{RefineConfig, Refinement, refine};
use super::rigid::{RigidFit, fit_similarity};
use crate::atlas::Atlas;
use crate::ear::Landmarks;
use crate::image::Sampler;
use crate::mesh::tet::signed_volume;
use crate::progress::Reporter;

/// Fits the atlas landmarks onto the patient's; `None` when the patient's are degenerate.
pub fn fit_landmarks(atlas: &Atlas, patient: &Landmarks, with_scale: bool) -> Option<RigidFit> {
    let source = atlas.landmark_positions(atlas.nodes());
    fit_similarity(&source.points(), &patient.points(), with_scale)
}

/// The atlas nodes mapped by the landmark fit (atlas to patient).
pub fn place(atlas: &Atlas, fit: &RigidFit) -> Vec<Point3<f64>> {
    atlas
        .nodes()
        .iter()
        .map(|p| fit.transform.apply(p))
        .collect()
}

/// No tetrahedron may keep less than this fraction of its volume in the placed atlas after a
/// rest-shape update (each level's FEM only keeps it above a tenth of its own rest volume).
const MIN_VOLUME_RATIO: f64 = 0.05;

/// The smallest ratio of a tetrahedron's volume at `x` to its volume at `placed`.
fn smallest_volume_ratio(atlas: &Atlas, placed: &[Point3<f64>], x: &[Point3<f64>]) -> f64 {
    let volume = |p: &[Point3<f64>], t: &[u32; 4]| {
        let [a, b, c, d] = t.map(|k| p[k as usize]);
        signed_volume(&a, &b, &c, &d)
    };
    atlas
        .mesh
        .tets
        .tets
        .iter()
        .map(|t| volume(x, t) / volume(placed, t).max(f64::MIN_POSITIVE))
        .fold(f64::INFINITY, f64::min)
}

/// Wall-clock seconds of each level of the deformable stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct LevelSeconds {
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
            probe_step_mm: step,
        }
    }
}

/// The settings of the deformable stage's levels.
#[derive(Debug, Clone, Copy)]
pub struct DeformSettings<'a> {
    pub articulate: &'a ArticulateConfig,
    pub deform: &'a DeformConfig,
    pub refine: &'a RefineConfig,
}

/// The deformable stage from the placed atlas: each ossicle's pose, then the ossicles and
/// their connective tissue through the FEM (its rest shape the articulated atlas), then the
/// eardrum. `step` is the probe step (the smallest voxel spacing, mm).
pub fn deform_atlas(
    atlas: &Atlas,
    placed: &[Point3<f64>],
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
        (x, Some(record))
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
        let level = deform(&model, &probes, sampler, step, cfg, progress)?;
        // a later level may not flatten an element: the FEM only guards against inversion,
        // and each level regularises from the last one's shape
        if level_index > 0
            && smallest_volume_ratio(atlas, placed, &level.positions) < MIN_VOLUME_RATIO
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
            &probes,
            &mut result.positions,
            sampler,
            step,
            cfg,
            refine_cfg,
        )
    });
    seconds.refine = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    let eardrum = fit_eardrum(atlas, placed, &mut result.positions, sampler, step, cfg);
    seconds.eardrum = clock.elapsed().as_secs_f64();
    Ok(Registered {
        articulation,
        deform: result,
        refinement,
        eardrum,
        seconds,
    })
}
