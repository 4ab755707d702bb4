//! The atlas registered onto a patient image: the atlas landmarks fitted onto the patient's
//! (rigid or similarity), the atlas placed by that transform, then the deformable stage on its
//! surfaces — ossicle boundaries probed as bone edges through the FEM, then the eardrum.
//!
//! The atlas must already be on the patient's side (see [`Atlas::mirrored`]): three landmarks
//! cannot tell a left ear from a right one, so the side is decided before anything else.

use std::collections::HashSet;

use nalgebra::Point3;

use super::articulate::{ArticulateConfig, Articulation, articulate, articulated_shape};
use super::deform::{DeformConfig, DeformError, DeformResult, ProbeKind, ProbeTriangle, deform};
use super::eardrum::{EardrumFit, fit_eardrum};
use super::rigid::{RigidFit, fit_similarity};
use crate::atlas::{Atlas, Part};
use crate::ear::Landmarks;
use crate::image::Sampler;
use crate::mesh::tet::BoundaryOf;

/// The surfaces the deformable stage probes: the ossicles' faces on the outer boundary of the
/// atlas (bone edges against air, fluid or soft tissue). Faces an ossicle shares with a joint,
/// ligament or tendon are not probed: a joint is a thin soft layer between two bones that the
/// image blurs into them, and connective tissue has no edge a CBCT can see; those faces follow
/// through the FEM. The eardrum is fitted afterwards (see [`fit_eardrum`]).
pub fn probe_triangles(atlas: &Atlas) -> Vec<ProbeTriangle> {
    probe_triangles_by_part(atlas)
        .into_iter()
        .map(|(_, t)| t)
        .collect()
}

/// [`probe_triangles`] with the ossicle each belongs to.
pub fn probe_triangles_by_part(atlas: &Atlas) -> Vec<(Part, ProbeTriangle)> {
    let key = |t: &[u32; 3]| {
        let mut k = *t;
        k.sort_unstable();
        k
    };
    let outer: HashSet<[u32; 3]> = atlas
        .mesh
        .tets
        .boundary(BoundaryOf::Whole)
        .node_triangles()
        .iter()
        .map(key)
        .collect();
    let mut probes = Vec::new();
    for part in Part::BONES {
        probes.extend(
            atlas
                .part_triangles(part)
                .into_iter()
                .filter(|t| outer.contains(&key(t)))
                .map(|nodes| {
                    (
                        part,
                        ProbeTriangle {
                            nodes,
                            kind: ProbeKind::Bone,
                        },
                    )
                }),
        );
    }
    probes
}

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

/// What the deformable stage made: the registered nodes with the record of each step.
#[derive(Debug, Clone)]
pub struct Registered {
    /// Each ossicle's own pose (absent when `[articulate]` is off).
    pub articulation: Option<Articulation>,
    pub deform: DeformResult,
    pub eardrum: EardrumFit,
}

/// The deformable stage from the placed atlas: each ossicle's pose, then the ossicles and
/// their connective tissue through the FEM (its rest shape the articulated atlas), then the
/// eardrum. `step` is the probe step (the smallest voxel spacing, mm).
pub fn deform_atlas(
    atlas: &Atlas,
    placed: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    articulate_cfg: &ArticulateConfig,
    cfg: &DeformConfig,
) -> Result<Registered, DeformError> {
    let moduli = Some((cfg.regularisation_modulus_pa, cfg.min_modulus_ratio));
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
    let model = atlas.fem_model(&rest, moduli, false)?;
    let mut result = deform(&model, &probe_triangles(atlas), sampler, step, cfg)?;
    let eardrum = fit_eardrum(atlas, placed, &mut result.positions, sampler, step, cfg);
    Ok(Registered {
        articulation,
        deform: result,
        eardrum,
    })
}
