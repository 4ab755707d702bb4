//! Scoring a registration against a manual segmentation: each structure's registered surface
//! against the segmentation's surface of the same name, with the surface distances of
//! `meshdev` (MASD, HD95, ... as defined in docs/metrics.md), and the per-vertex deviation
//! maps of the registered surfaces.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Point3;
use rayon::prelude::*;
use serde::Serialize;

use crate::Error;
use crate::atlas::{Atlas, Part};
use crate::image::IngestConfig;
use crate::mesh::TriMesh;
use crate::mesh::union::outer_surface;
use crate::meshdev::sampling::DEFAULT_SEED;
use crate::meshdev::structures::{FUSED_NAMES, default_label_table, load_structures};
use crate::meshdev::{
    CompareOptions, LabelDeviation, MeshDevError, PreparedReference, Sampling, SurfaceDistances,
    compare_prepared, deviation_by_label,
};

/// The name given to the separate ossicles united (one of the fused names).
const CHAIN: &str = FUSED_NAMES[1].0;

/// Area samples per surface and direction: the sampling error of a mean distance is then far
/// below a micrometre on an ossicle (~30 mm² of surface), at a fraction of the default cost.
const SAMPLES_PER_SURFACE: usize = 40_000;

/// The distance beyond which the per-region summary counts an area as far, for a surface-Dice
/// tolerance of one voxel: two voxels, the HD95 target (docs/metrics.md).
fn far_mm(tolerance_mm: f64) -> f64 {
    2.0 * tolerance_mm
}

impl StructureScore {
    /// The distance beyond which `by_region` counts an area as far \[mm\]: twice the
    /// surface-Dice tolerance.
    pub fn far_mm(&self) -> f64 {
        far_mm(self.distances.tolerance_mm)
    }
}

/// The reference surfaces of a segmentation, by structure name.
pub struct Reference {
    pub surfaces: BTreeMap<String, TriMesh>,
}

impl Reference {
    /// Reads a segmentation folder (per-structure meshes, or a label map with the default
    /// label table: 1 malleus, 2 incus, 3 stapes, 4 eardrum). Separate, closed ossicles are
    /// also united into the chain as one solid (`chain`), unless a fused surface is given:
    /// an image cannot show where one ossicle ends and the next begins at a joint, so only
    /// the chain's outer surface is the image's to decide (docs/metrics.md).
    pub fn load(path: &Path, ingest: &IngestConfig) -> Result<Reference, Error> {
        let structures = load_structures(path, &default_label_table(), ingest)?;
        let mut surfaces: BTreeMap<String, TriMesh> = structures
            .into_iter()
            .map(|s| (s.name.to_ascii_lowercase(), s.mesh))
            .collect();
        let fused_given = FUSED_NAMES.iter().any(|(f, _)| surfaces.contains_key(*f));
        let bones: Option<Vec<&TriMesh>> =
            Part::BONES.iter().map(|p| surfaces.get(p.name())).collect();
        if let Some(bones) = bones.filter(|_| !fused_given)
            // surfaces without an inside are not united
            && let Ok(chain) = outer_surface(&bones, "reference")
        {
            surfaces.insert(CHAIN.to_string(), chain);
        }
        Ok(Reference { surfaces })
    }
}

/// One structure's score.
#[derive(Debug, Clone, Serialize)]
pub struct StructureScore {
    pub distances: SurfaceDistances,
    /// The deviation map summed per atlas region, by region name.
    pub by_region: BTreeMap<String, LabelDeviation>,
    /// The registered surface that was scored (a structure's own, or the chain's outer
    /// surface for a fused reference).
    #[serde(skip)]
    pub surface: TriMesh,
    /// Signed distance of each registered-surface vertex to the reference \[mm\].
    #[serde(skip)]
    pub deviation: Vec<f64>,
    #[serde(skip)]
    pub colours: Vec<[u8; 3]>,
}

/// Scores the atlas with its nodes at each of `node_sets` (the rigid fit's and the
/// registration's, say) against `reference`, per structure present in both; `tolerance_mm`
/// is the surface-Dice tolerance (one voxel), and twice it the distance beyond which the
/// per-region summary counts an area as far (the HD95 target of two voxels). Each reference
/// surface is indexed and sampled once for all the node sets.
pub fn score<const N: usize>(
    atlas: &Atlas,
    node_sets: [&[Point3<f64>]; N],
    reference: &Reference,
    tolerance_mm: f64,
) -> Result<[BTreeMap<String, StructureScore>; N], MeshDevError> {
    let options = CompareOptions {
        sampling: Sampling::Area {
            count: Some(SAMPLES_PER_SURFACE),
            seed: DEFAULT_SEED,
        },
        ..CompareOptions::with_tolerance(tolerance_mm)
    };
    // each structure against its own reference; a fused reference (one surface for the whole
    // chain, as a CT segmentation that does not separate the ossicles gives) against the
    // registered chain's outer surface as one solid
    // (name, the part scored or None for the chain, the reference surface)
    let mut truths: Vec<(&str, Option<Part>, &TriMesh)> = Vec::new();
    for part in Part::STRUCTURES {
        if let Some(truth) = reference.surfaces.get(part.name())
            && !atlas.labels_of(part).is_empty()
        {
            truths.push((part.name(), Some(part), truth));
        }
    }
    if Part::BONES.iter().all(|p| !atlas.labels_of(*p).is_empty()) {
        for (fused, _) in FUSED_NAMES {
            if let Some(truth) = reference.surfaces.get(fused) {
                truths.push((fused, None, truth));
            }
        }
    }
    // the structures side by side (each comparison is parallel too, but its index builds
    // and sampling are partly serial)
    let scored: Vec<(&str, Vec<StructureScore>)> = truths
        .par_iter()
        .map(|&(name, part, truth)| {
            let prepared = PreparedReference::new(truth, &options.sampling)?;
            let faces = match part {
                Some(part) => atlas.part_faces(part),
                None => atlas.chain_faces(),
            };
            let scores = node_sets
                .iter()
                .map(|nodes| {
                    let test = TriMesh::compacted(&faces.triangles, nodes);
                    let c = compare_prepared(&test, &prepared, &options)?;
                    let by_region = deviation_by_label(
                        &test,
                        &c.deviation.quality,
                        &faces.regions,
                        far_mm(tolerance_mm),
                    )
                    .into_iter()
                    .map(|d| {
                        let name = atlas
                            .region(d.label)
                            .map_or_else(|| format!("label {}", d.label), |r| r.name.clone());
                        (name, d)
                    })
                    .collect();
                    Ok(StructureScore {
                        distances: c.distances,
                        by_region,
                        surface: test,
                        deviation: c.deviation.quality,
                        colours: c.deviation.colours,
                    })
                })
                .collect::<Result<_, MeshDevError>>()?;
            Ok((name, scores))
        })
        .collect::<Result<_, MeshDevError>>()?;
    let mut out: [BTreeMap<String, StructureScore>; N] = std::array::from_fn(|_| BTreeMap::new());
    for (name, scores) in scored {
        for (score, map) in scores.into_iter().zip(&mut out) {
            map.insert(name.to_string(), score);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::atlas::{Region, default_atlas};

    /// The default atlas scored against its own chain with the stapes moved 0.6 mm (four voxels
    /// of 0.15 mm): the area beyond two voxels lies in the stapes, none of it in the malleus or
    /// the incus, which did not move.
    #[test]
    fn a_moved_stapes_is_where_the_far_distances_lie() {
        let atlas = default_atlas().unwrap();
        let nodes = atlas.nodes();
        let tets = &atlas.mesh.tets;
        let mut moved = nodes.to_vec();
        let mut in_stapes = vec![false; nodes.len()];
        for (tet, &region) in tets.tets.iter().zip(&tets.regions) {
            if region == Region::Stapes.label() {
                tet.iter().for_each(|&v| in_stapes[v as usize] = true);
            }
        }
        for (p, _) in moved.iter_mut().zip(&in_stapes).filter(|(_, s)| **s) {
            *p += Vector3::new(0.0, 0.6, 0.0);
        }
        let reference = Reference {
            surfaces: BTreeMap::from([(CHAIN.to_string(), atlas.chain_surface(&moved))]),
        };
        let [scored] = score(&atlas, [nodes], &reference, 0.15).unwrap();
        let chain = &scored[CHAIN];
        assert_eq!(chain.far_mm(), 0.3);
        let far = |region: Region| {
            chain.by_region.get(region.name()).map_or(0.0, |d| {
                d.area_mm2 * (d.far_outside_share + d.far_inside_share)
            })
        };
        let stapes = &chain.by_region[Region::Stapes.name()];
        // a third of it (0.32): the faces across the shift; the crura's sides slide along
        // themselves, and the shifted bone, thinner than 0.6 mm, holds none of the original
        assert!(far(Region::Stapes) > 0.2 * stapes.area_mm2, "{stapes:?}");
        for region in [
            Region::MalleusHead,
            Region::MalleusNeck,
            Region::MalleusHandle,
            Region::IncusBody,
            Region::IncusShortProcess,
        ] {
            assert_eq!(far(region), 0.0, "{region:?}: {:?}", chain.by_region);
        }
        // every triangle of the scored surface is in one region's sum
        let total: f64 = chain.by_region.values().map(|d| d.area_mm2).sum();
        assert!((total - chain.surface.area()).abs() < 1e-9 * total);
    }
}
