//! The eardrum's attachment to the manubrium: every node of the membrane's attachment line
//! becomes a node of the malleus, whatever the two meshes' sizes.
//!
//! The membrane is triangulated on its own cone, whose superior generator runs near, not on,
//! the manubrium's surface (up to 0.45 mm off), and its attachment line has a node every
//! membrane edge while the malleus's surface has one every tetrahedron edge. Merging each line
//! node with a nearby surface node of the malleus therefore attached fewer line nodes the finer
//! the drum (13, 13, 11, 9, 7 at drum edges 0.24, 0.17, 0.12, 0.085, 0.06 mm: a merge that
//! moves a node 0.4 mm flips the small triangles beside it and is refused), so a finer drum
//! hung on the manubrium by fewer points, and it did not converge (docs/mechanics.md, "The
//! eardrum's own convergence"). Now:
//!
//! 1. **Conform**: each line node's offset to its closest point on the manubrium's outer
//!    surface is blended over the drum (Gaussian weights, 0.15 mm) and tapered to nothing
//!    1 mm from the line, so the line comes to lie on or near the bone and its neighbours
//!    follow smoothly.
//! 2. **Tie**: each line node is merged with a malleus node at most 0.03 mm from it, or else
//!    inserted into the malleus's surface at its closest point: the tetrahedron owning that
//!    boundary face is split into three at the point (moved toward the face's centroid as far
//!    as needed), or else the tetrahedra around the face's nearest edge are split in two,
//!    keeping every dihedral angle at 10° or more (the mesher's guarantee); or else merged
//!    with the face's nearest free corner, however far. A
//!    tie that would flip a membrane triangle, or that no such point allows, is refused and
//!    undone, and reported in the atlas's provenance.

use std::collections::BTreeSet;

use nalgebra::{Point3, Vector3};

use super::membrane::MembraneMesh;
use crate::mesh::TetMesh;
use crate::mesh::quality::dihedral_range;
use crate::mesh::spatial::closest_point_on_triangle;
use crate::mesh::tet::BoundaryOf;

/// How far a line node may be from the manubrium's surface to be attached [mm].
pub(super) const ATTACH_TOLERANCE_MM: f64 = 0.45;

/// A line node this close to a malleus node is merged with it rather than inserted [mm].
const MERGE_TOLERANCE_MM: f64 = 0.03;

/// The conforming displacement's Gaussian blend width and reach from the line [mm].
const BLEND_SIGMA_MM: f64 = 0.15;
const BLEND_REACH_MM: f64 = 1.0;

/// The smallest barycentric weights tried, in turn, for an inserted node on its face: the
/// first keeps it closest to where the line meets the bone, the last is the face's centroid.
const FACE_WEIGHT_FLOORS: [f64; 5] = [0.1, 0.15, 0.2, 0.27, 1.0 / 3.0];

/// The smallest dihedral angle an inserted node may leave (the mesher's guarantee) [°].
const MIN_DIHEDRAL_DEG: f64 = 10.0;

/// What attaching the membrane did.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Attachment {
    /// Membrane node → node of the joined mesh.
    pub membrane_node: Vec<u32>,
    /// Line nodes merged with malleus nodes, inserted into its surface, and left free.
    pub merged: usize,
    pub inserted: usize,
    pub refused: usize,
    /// Largest distance a line node moved to its tie [mm] (conforming included).
    pub farthest_mm: f64,
}

/// Attaches `membrane` to the malleus handle `handle_region` of `tets` (module docs): adds the
/// membrane's free nodes and the inserted ones to `tets` and splits the tetrahedra the
/// insertions need. `medial` orients the flip test.
pub(super) fn attach_membrane(
    tets: &mut TetMesh,
    membrane: &MembraneMesh,
    handle_region: u16,
    medial: Vector3<f64>,
) -> Attachment {
    let handle: BTreeSet<u32> = tets
        .boundary(BoundaryOf::Region(handle_region))
        .node_of_vertex
        .into_iter()
        .collect();
    let conformed = conform(tets, membrane, &handle);
    let mut target: Vec<Option<u32>> = vec![None; conformed.nodes.len()];
    // the malleus nodes tied so far, and the handle's faces (again after each insertion)
    let mut taken: BTreeSet<u32> = BTreeSet::new();
    let mut faces = handle_faces(tets, &handle);
    let (mut merged, mut inserted, mut refused) = (0, 0, 0);
    let mut farthest = 0.0f64;
    for &m in &membrane.attachment {
        let p = conformed.nodes[m as usize];
        let Some((face, weights, distance)) = closest_face(tets, &faces, &p) else {
            refused += 1;
            continue;
        };
        if distance > ATTACH_TOLERANCE_MM {
            refused += 1;
            continue;
        }
        let near = face
            .iter()
            .copied()
            .filter(|v| !taken.contains(v))
            .map(|v| ((tets.nodes[v as usize] - p).norm(), v))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let original = membrane.nodes[m as usize];
        let merge = |target: &mut Vec<Option<u32>>, nodes: &[Point3<f64>], v: u32| {
            target[m as usize] = Some(v);
            let flips = flips_a_triangle(&conformed, membrane, target, nodes, medial);
            if flips {
                target[m as usize] = None;
            }
            !flips
        };
        // a malleus node at the line node: merge; else insert one; else merge with the
        // nearest free corner of the face however far, if that flips nothing
        if let Some((_, v)) = near.filter(|(d, _)| *d <= MERGE_TOLERANCE_MM) {
            if merge(&mut target, &tets.nodes, v) {
                taken.insert(v);
                merged += 1;
                farthest = farthest.max((tets.nodes[v as usize] - original).norm());
                continue;
            }
        } else if let Some(changed) = insert_on_face(tets, face, weights) {
            let new = (tets.nodes.len() - 1) as u32;
            target[m as usize] = Some(new);
            if !flips_a_triangle(&conformed, membrane, &target, &tets.nodes, medial) {
                taken.insert(new);
                faces = handle_faces(tets, &handle);
                inserted += 1;
                farthest = farthest.max((tets.nodes[new as usize] - original).norm());
                continue;
            }
            target[m as usize] = None;
            undo(tets, changed);
        }
        match near {
            Some((_, v)) if merge(&mut target, &tets.nodes, v) => {
                taken.insert(v);
                merged += 1;
                farthest = farthest.max((tets.nodes[v as usize] - original).norm());
            }
            _ => refused += 1,
        }
    }
    let membrane_node = target
        .iter()
        .enumerate()
        .map(|(k, t)| match t {
            Some(v) => *v,
            None => {
                tets.nodes.push(conformed.nodes[k]);
                (tets.nodes.len() - 1) as u32
            }
        })
        .collect();
    Attachment {
        membrane_node,
        merged,
        inserted,
        refused,
        farthest_mm: farthest,
    }
}

/// The handle's outer boundary faces (the mesh's boundary faces whose nodes are all the
/// handle's).
fn handle_faces(tets: &TetMesh, handle: &BTreeSet<u32>) -> Vec<[u32; 3]> {
    tets.boundary(BoundaryOf::Whole)
        .node_triangles()
        .into_iter()
        .filter(|f| f.iter().all(|v| handle.contains(v)))
        .collect()
}

/// The face of `faces` closest to `p`: its nodes, the closest point's barycentric weights on
/// it, and the distance.
fn closest_face(
    tets: &TetMesh,
    faces: &[[u32; 3]],
    p: &Point3<f64>,
) -> Option<([u32; 3], [f64; 3], f64)> {
    faces
        .iter()
        .map(|&f| {
            let [a, b, c] = f.map(|v| tets.nodes[v as usize]);
            let (q, _) = closest_point_on_triangle(p, &a, &b, &c);
            (f, barycentric(&q, &a, &b, &c), (q - p).norm())
        })
        .min_by(|a, b| a.2.total_cmp(&b.2))
}

/// Barycentric weights of `q` (in the plane of the triangle) on (a, b, c).
fn barycentric(q: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> [f64; 3] {
    let (v0, v1, v2) = (b - a, c - a, q - a);
    let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
    let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
    let det = d00 * d11 - d01 * d01;
    if det.abs() <= f64::EPSILON * d00 * d11 {
        return [1.0 / 3.0; 3];
    }
    let v = (d11 * d20 - d01 * d21) / det;
    let w = (d00 * d21 - d01 * d20) / det;
    [1.0 - v - w, v, w]
}

/// Inserts a node on the boundary face `face` near the point of barycentric `weights`,
/// keeping every dihedral angle at `MIN_DIHEDRAL_DEG` or more (the mesher's guarantee), by
/// the first of: splitting the tetrahedron that owns the face into three at the point, raised
/// in turn to the weight floors `FACE_WEIGHT_FLOORS`; or splitting every tetrahedron around
/// one of the face's edges in two, at the point's projection on it (kept within the middle
/// 60 % of the edge), the nearest edge first. The new node is the mesh's last; `None` when no
/// such split exists (nothing changed).
fn insert_on_face(tets: &mut TetMesh, face: [u32; 3], weights: [f64; 3]) -> Option<Inserted> {
    let new = tets.nodes.len() as u32;
    let corner = |v: u32| tets.nodes[v as usize];
    let target = Point3::from(
        face.iter()
            .zip(weights)
            .map(|(v, x)| corner(*v).coords * x)
            .sum::<Vector3<f64>>(),
    );
    // (point, the corners it splits off: 3 for the face, 2 for an edge)
    let mut candidates: Vec<(Point3<f64>, Vec<u32>)> = FACE_WEIGHT_FLOORS
        .iter()
        .map(|&floor| {
            let w = weights.map(|x| x.max(floor));
            let sum: f64 = w.iter().sum();
            let point = face
                .iter()
                .zip(w)
                .map(|(v, x)| corner(*v).coords * (x / sum))
                .sum::<Vector3<f64>>();
            (Point3::from(point), face.to_vec())
        })
        .collect();
    let mut edges: Vec<(f64, Point3<f64>, Vec<u32>)> = (0..3)
        .map(|k| {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            let (pa, pb) = (corner(a), corner(b));
            let t = ((target - pa).dot(&(pb - pa)) / (pb - pa).norm_squared()).clamp(0.2, 0.8);
            let point = pa + (pb - pa) * t;
            ((point - target).norm(), point, vec![a, b])
        })
        .collect();
    edges.sort_by(|x, y| x.0.total_cmp(&y.0));
    candidates.extend(edges.into_iter().map(|(_, p, e)| (p, e)));
    let (point, split) = candidates.into_iter().find(|(point, split)| {
        let at = |v: u32| if v == new { *point } else { corner(v) };
        (0..tets.tets.len())
            .filter(|&t| split.iter().all(|v| tets.tets[t].contains(v)))
            .flat_map(|t| children(tets.tets[t], split, new))
            .all(|child| dihedral_range(&child.map(at)).0 >= MIN_DIHEDRAL_DEG.to_radians())
    })?;
    let tets_before = tets.tets.len();
    tets.nodes.push(point);
    let owners: Vec<usize> = (0..tets.tets.len())
        .filter(|&t| split.iter().all(|v| tets.tets[t].contains(v)))
        .collect();
    let mut changed = Vec::with_capacity(owners.len());
    for t in owners {
        let (tet, region) = (tets.tets[t], tets.regions[t]);
        changed.push((t, tet));
        let mut pieces = children(tet, &split, new).into_iter();
        if let Some(first) = pieces.next() {
            tets.tets[t] = first;
        }
        for child in pieces {
            tets.tets.push(child);
            tets.regions.push(region);
        }
    }
    Some(Inserted {
        replaced: changed,
        tets_before,
    })
}

/// What `insert_on_face` changed, to undo it: the tetrahedra it replaced (index, previous
/// nodes) and the tetrahedron count before it appended the rest.
struct Inserted {
    replaced: Vec<(usize, [u32; 4])>,
    tets_before: usize,
}

/// Undoes `insert_on_face`: its replaced tetrahedra back, its new ones and node removed.
fn undo(tets: &mut TetMesh, changed: Inserted) {
    for (t, tet) in changed.replaced {
        tets.tets[t] = tet;
    }
    tets.tets.truncate(changed.tets_before);
    tets.regions.truncate(changed.tets_before);
    tets.nodes.pop();
}

/// The tetrahedra `tet` splits into at a new node `new` on its face or edge `split`: one
/// copy per corner of `split`, that corner replaced by the new node (which keeps the
/// orientation, the node lying inside the face or edge).
fn children(tet: [u32; 4], split: &[u32], new: u32) -> Vec<[u32; 4]> {
    split
        .iter()
        .map(|&v| tet.map(|x| if x == v { new } else { x }))
        .collect()
}

/// The membrane moved so that its attachment line lies on the handle's outer surface
/// (module docs, step 1); the rim stays.
fn conform(tets: &TetMesh, membrane: &MembraneMesh, handle: &BTreeSet<u32>) -> MembraneMesh {
    let faces = handle_faces(tets, handle);
    let offsets: Vec<(Point3<f64>, Vector3<f64>)> = membrane
        .attachment
        .iter()
        .filter_map(|&m| {
            let p = membrane.nodes[m as usize];
            let (face, weights, distance) = closest_face(tets, &faces, &p)?;
            (distance <= ATTACH_TOLERANCE_MM).then(|| {
                let q = face
                    .iter()
                    .zip(weights)
                    .map(|(v, x)| tets.nodes[*v as usize].coords * x)
                    .sum::<Vector3<f64>>();
                (p, q - p.coords)
            })
        })
        .collect();
    let rim: BTreeSet<u32> = membrane.rim.iter().copied().collect();
    let mut out = membrane.clone();
    for (k, node) in out.nodes.iter_mut().enumerate() {
        let nearest = offsets
            .iter()
            .map(|(p, _)| (p - *node).norm())
            .fold(f64::INFINITY, f64::min);
        if rim.contains(&(k as u32)) || nearest >= BLEND_REACH_MM {
            continue;
        }
        let (mut sum, mut weight) = (Vector3::zeros(), 0.0);
        for (p, o) in &offsets {
            let w = (-(p - *node).norm_squared() / (2.0 * BLEND_SIGMA_MM * BLEND_SIGMA_MM)).exp();
            sum += o * w;
            weight += w;
        }
        if weight > 0.0 {
            *node += sum / weight * (1.0 - nearest / BLEND_REACH_MM).powi(2);
        }
    }
    out
}

/// Whether the membrane's triangles touching a tied node, at the tied positions, flip or
/// collapse against their rest orientation in `rest` (the membrane as triangulated).
fn flips_a_triangle(
    membrane: &MembraneMesh,
    rest: &MembraneMesh,
    target: &[Option<u32>],
    tet_nodes: &[Point3<f64>],
    medial: Vector3<f64>,
) -> bool {
    let at = |v: u32| match target[v as usize] {
        Some(h) => tet_nodes[h as usize],
        None => membrane.nodes[v as usize],
    };
    membrane.triangles.iter().any(|t| {
        if t.iter().all(|v| target[*v as usize].is_none()) {
            return false;
        }
        let [a, b, c] = t.map(at);
        let n = (b - a).cross(&(c - a));
        let area = {
            let [a0, b0, c0] = t.map(|v| rest.nodes[v as usize]);
            (b0 - a0).cross(&(c0 - a0)).norm()
        };
        n.dot(&medial) > -0.2 * area
    })
}
