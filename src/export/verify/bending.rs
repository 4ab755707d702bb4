//! The bending part of the scene check (`scene_bending`): every FastTriangularBendingSprings
//! acts on membrane triangles of the mesh through a triangle topology beside it; summed over
//! the components, each triangle's `bendingStiffness` is 3 x its flexural rigidity in the
//! atlas (0 for a bending-free triangle); and the ConstantForceFields cancel the springs'
//! force at the mesh's rest positions, recomputed here with SOFA's formula.

use std::collections::HashMap;

use nalgebra::Vector3;
use roxmltree::Node;

use super::faults::Faults;
use super::xml::{Scene, close, numbers};
use crate::atlas::Atlas;
use crate::export::scene::SCENE;
use crate::export::scene_bending::{STIFFNESS_PER_RIGIDITY, add_spring_force};
use crate::mesh::io::VolumeMesh;

/// Largest net force left at rest, relative to the largest spring force there.
const REST_FORCE_TOL: f64 = 1e-9;

/// One bending component: its `bendingStiffness` and its triangles as mesh triangle indices.
struct Component {
    stiffness: f64,
    triangles: Vec<usize>,
}

pub(super) fn check_bending(
    scene: &Scene,
    mesh: &VolumeMesh,
    atlas: Option<&Atlas>,
    faults: &mut Faults,
) {
    let index: HashMap<[u32; 3], usize> = mesh
        .triangles
        .iter()
        .enumerate()
        .map(|(k, t)| (sorted(*t), k))
        .collect();
    let components: Vec<Component> = scene
        .all("FastTriangularBendingSprings")
        .filter_map(|node| component(node, mesh, &index, faults))
        .collect();
    if let Some(atlas) = atlas {
        check_stiffness(&components, atlas, mesh.triangles.len(), faults);
    }
    if components.is_empty() {
        return;
    }
    let x = &mesh.tets.nodes;
    let mut springs = vec![Vector3::zeros(); x.len()];
    for c in &components {
        let tris: Vec<[u32; 3]> = c.triangles.iter().map(|&t| mesh.triangles[t]).collect();
        add_spring_force(x, x, &tris, c.stiffness, &mut springs);
    }
    let mut net = springs.clone();
    for node in scene.all("ConstantForceField") {
        let (Some(indices), Some(forces)) = (
            numbers(node, "indices", faults),
            numbers(node, "forces", faults),
        ) else {
            continue;
        };
        if forces.len() != 3 * indices.len()
            || indices
                .iter()
                .any(|&v| v < 0.0 || v.fract() != 0.0 || v >= x.len() as f64)
        {
            faults.add(
                "scene",
                SCENE,
                format!(
                    "ConstantForceField: {} indices (each a point below {}) need {} force \
                     values, found {}",
                    indices.len(),
                    x.len(),
                    3 * indices.len(),
                    forces.len()
                ),
            );
            continue;
        }
        for (k, &v) in indices.iter().enumerate() {
            net[v as usize] += Vector3::new(forces[3 * k], forces[3 * k + 1], forces[3 * k + 2]);
        }
    }
    let largest = |f: &[Vector3<f64>]| f.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let (push, left) = (largest(&springs), largest(&net));
    if left > REST_FORCE_TOL * push {
        faults.add(
            "scene",
            SCENE,
            format!(
                "the bending springs push the rest shape by up to {push:e} uN and the \
                 ConstantForceFields leave {left:e} uN of it: the eardrum would not rest where \
                 the mesh puts it"
            ),
        );
    }
}

fn sorted(mut t: [u32; 3]) -> [u32; 3] {
    t.sort_unstable();
    t
}

/// The component of `node`: its stiffness and the triangles of the topology it links to (a
/// TriangleSetTopologyContainer in the same node, given by index or as the loader's).
fn component(
    node: Node,
    mesh: &VolumeMesh,
    index: &HashMap<[u32; 3], usize>,
    faults: &mut Faults,
) -> Option<Component> {
    let stiffness = match numbers(node, "bendingStiffness", faults)?.as_slice() {
        &[s] => s,
        other => {
            faults.add(
                "scene",
                SCENE,
                format!(
                    "FastTriangularBendingSprings.bendingStiffness has {} values, expected one",
                    other.len()
                ),
            );
            return None;
        }
    };
    let name = node
        .attribute("topology")
        .unwrap_or("")
        .trim_start_matches('@');
    let Some(topology) = node.parent().and_then(|p| {
        p.children().find(|c| {
            c.tag_name().name() == "TriangleSetTopologyContainer"
                && c.attribute("name") == Some(name)
        })
    }) else {
        faults.add(
            "scene",
            SCENE,
            format!(
                "FastTriangularBendingSprings links topology '{name}', which is no \
                 TriangleSetTopologyContainer beside it"
            ),
        );
        return None;
    };
    if topology
        .attribute("triangles")
        .is_some_and(|t| t.starts_with('@'))
    {
        return Some(Component {
            stiffness,
            triangles: (0..mesh.triangles.len()).collect(),
        });
    }
    let corners = numbers(topology, "triangles", faults)?;
    let mut triangles = Vec::with_capacity(corners.len() / 3);
    for tri in corners.chunks(3) {
        let t = match tri {
            &[a, b, c] => [a, b, c].map(|v| v as u32),
            _ => [u32::MAX; 3],
        };
        match index.get(&sorted(t)) {
            Some(&k) if tri.iter().all(|v| v.fract() == 0.0 && *v >= 0.0) => triangles.push(k),
            _ => {
                faults.add(
                    "scene",
                    SCENE,
                    format!(
                        "bending topology '{name}': {tri:?} is not a membrane triangle of the mesh"
                    ),
                );
                return None;
            }
        }
    }
    Some(Component {
        stiffness,
        triangles,
    })
}

/// Each triangle's summed `bendingStiffness` against 3 x its rigidity in the atlas.
fn check_stiffness(components: &[Component], atlas: &Atlas, n_tris: usize, faults: &mut Faults) {
    let rigidity = atlas.membrane_flexural_rigidity();
    if rigidity.len() != n_tris {
        return;
    }
    let mut sum = vec![0.0; n_tris];
    for c in components {
        c.triangles.iter().for_each(|&t| sum[t] += c.stiffness);
    }
    if let Some(t) = (0..n_tris).find(|&t| !close(sum[t], STIFFNESS_PER_RIGIDITY * rigidity[t])) {
        faults.add(
            "scene",
            SCENE,
            format!(
                "membrane triangle {t} bends at bendingStiffness {} in the scene; its flexural \
                 rigidity in the atlas is {} uN mm, so {} is expected (3 x, Volino's springs)",
                sum[t],
                rigidity[t],
                STIFFNESS_PER_RIGIDITY * rigidity[t]
            ),
        );
    }
}
