//! Which atlas triangles the stages probe for image borders: the ossicles' faces on the outer
//! boundary of the atlas, each with the ossicle it belongs to. Shared by the landmark image
//! check, the per-ossicle poses and the deformable stage.

use std::collections::HashSet;

use super::deform::{ProbeKind, ProbeTriangle};
use crate::atlas::{Atlas, Part};
use crate::mesh::tet::BoundaryOf;

/// The surfaces the deformable stage probes: the ossicles' faces on the outer boundary of the
/// atlas (bone edges against air, fluid or soft tissue). Faces an ossicle shares with a joint,
/// ligament or tendon are not probed: a joint is a thin soft layer between two bones that the
/// image blurs into them, and connective tissue has no edge a CBCT can see; those faces follow
/// through the FEM. The eardrum is fitted afterwards (`eardrum::fit_eardrum`).
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
