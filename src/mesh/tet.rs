//! `TetMesh`: a region-labelled linear tetrahedral mesh (LPS mm), its volumes and boundary
//! surfaces.
//!
//! Orientation convention: every tet `[a, b, c, d]` has positive signed volume
//! `(b - a) · ((c - a) × (d - a)) / 6 > 0`. Its outward faces are then `(a, c, b)`, `(a, b, d)`,
//! `(a, d, c)` and `(b, c, d)` (right-hand rule), which is how boundary triangles are emitted.

use std::collections::HashMap;

use nalgebra::Point3;

use super::TriMesh;

/// Outward faces (local corner indices) of a positively oriented tet.
pub const TET_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

/// A tetrahedral mesh with one region label per tet.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetMesh {
    pub nodes: Vec<Point3<f64>>,
    pub tets: Vec<[u32; 4]>,
    pub regions: Vec<u16>,
}

/// A boundary surface cut out of a `TetMesh`: the triangles (outward) with their own compact
/// vertex list, and for each surface vertex the mesh node it came from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Boundary {
    pub surface: TriMesh,
    pub node_of_vertex: Vec<u32>,
    /// For each triangle, the tetrahedron it bounds (so its region).
    pub triangle_tets: Vec<u32>,
}

impl Boundary {
    /// The boundary triangles in the tet mesh's node numbering (same order and orientation).
    pub fn node_triangles(&self) -> Vec<[u32; 3]> {
        self.surface
            .triangles
            .iter()
            .map(|t| t.map(|v| self.node_of_vertex[v as usize]))
            .collect()
    }
}

/// Which tets a boundary is taken of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoundaryOf<'a> {
    /// The whole mesh: faces not shared with any other tet.
    Whole,
    /// One region: faces of its tets not shared with another tet of the same region.
    Region(u16),
    /// A union of regions: faces of their tets not shared with another tet of the union.
    Regions(&'a [u16]),
}

/// A structural defect found by [`TetMesh::validate`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TetMeshError {
    #[error("tet mesh has {tets} tets but {regions} region labels; expected one label per tet")]
    RegionCount { tets: usize, regions: usize },
    #[error("tet {tet} refers to node {node}, but the mesh has {nodes} nodes")]
    NodeIndex { tet: usize, node: u32, nodes: usize },
    #[error("tet {tet} repeats node {node}; expected four distinct nodes")]
    RepeatedNode { tet: usize, node: u32 },
}

/// Signed volume of the tet with corners `a, b, c, d`.
#[inline]
pub fn signed_volume(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>, d: &Point3<f64>) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

impl TetMesh {
    /// Checks index ranges, repeated nodes and that there is one region label per tet.
    pub fn validate(&self) -> Result<(), TetMeshError> {
        if self.regions.len() != self.tets.len() {
            return Err(TetMeshError::RegionCount {
                tets: self.tets.len(),
                regions: self.regions.len(),
            });
        }
        for (t, tet) in self.tets.iter().enumerate() {
            for (i, &n) in tet.iter().enumerate() {
                if n as usize >= self.nodes.len() {
                    return Err(TetMeshError::NodeIndex {
                        tet: t,
                        node: n,
                        nodes: self.nodes.len(),
                    });
                }
                if tet[..i].contains(&n) {
                    return Err(TetMeshError::RepeatedNode { tet: t, node: n });
                }
            }
        }
        Ok(())
    }

    /// The four corners of tet `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Point3<f64>; 4] {
        self.tets[t].map(|n| self.nodes[n as usize])
    }

    /// Signed volume of tet `t` (positive under the orientation convention).
    #[inline]
    pub fn tet_volume(&self, t: usize) -> f64 {
        let [a, b, c, d] = self.corners(t);
        signed_volume(&a, &b, &c, &d)
    }

    /// Sum of the signed tet volumes.
    pub fn volume(&self) -> f64 {
        (0..self.tets.len()).map(|t| self.tet_volume(t)).sum()
    }

    /// Sum of the signed volumes of the tets of `region`.
    pub fn region_volume(&self, region: u16) -> f64 {
        (0..self.tets.len())
            .filter(|&t| self.regions[t] == region)
            .map(|t| self.tet_volume(t))
            .sum()
    }

    /// The distinct region labels present, ascending.
    pub fn region_ids(&self) -> Vec<u16> {
        let mut ids = self.regions.clone();
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// Number of tets with non-positive signed volume.
    pub fn inverted_count(&self) -> usize {
        (0..self.tets.len())
            .filter(|&t| self.tet_volume(t) <= 0.0)
            .count()
    }

    /// Swaps two corners of every negatively oriented tet so that all have positive volume
    /// (degenerate tets of zero volume are left as they are).
    pub fn orient_positive(&mut self) {
        for t in 0..self.tets.len() {
            if self.tet_volume(t) < 0.0 {
                self.tets[t].swap(2, 3);
            }
        }
    }

    /// Every face shared by two tets: its sorted node triple and the two tets (lower index
    /// first), in order of the first tet and its faces (deterministic).
    pub fn interior_faces(&self) -> Vec<([u32; 3], usize, usize)> {
        let mut first: HashMap<[u32; 3], usize> = HashMap::new();
        let mut out = Vec::new();
        for (t, tet) in self.tets.iter().enumerate() {
            for f in &TET_FACES {
                let mut k = f.map(|i| tet[i]);
                k.sort_unstable();
                match first.remove(&k) {
                    Some(s) => out.push((k, s, t)),
                    None => {
                        first.insert(k, t);
                    }
                }
            }
        }
        out
    }

    /// Area of the triangle on three nodes.
    pub fn face_area(&self, face: &[u32; 3]) -> f64 {
        let [a, b, c] = face.map(|n| self.nodes[n as usize]);
        0.5 * (b - a).cross(&(c - a)).norm()
    }

    /// The boundary surface of the whole mesh or of one region, outward oriented.
    ///
    /// Triangles come in tet order and face order, vertices in order of first use, so the
    /// result is deterministic.
    pub fn boundary(&self, of: BoundaryOf<'_>) -> Boundary {
        let selected = |t: usize| match of {
            BoundaryOf::Whole => true,
            BoundaryOf::Region(r) => self.regions[t] == r,
            BoundaryOf::Regions(rs) => rs.contains(&self.regions[t]),
        };
        // every selected tet's faces by their sorted nodes; a face is on the boundary when
        // no other selected tet has it (a sort, not a hash map: this runs on every surface
        // query of an atlas, several per registration)
        let mut faces: Vec<([u32; 3], u32)> = (0..self.tets.len())
            .filter(|&t| selected(t))
            .flat_map(|t| {
                TET_FACES.iter().enumerate().map(move |(f, corners)| {
                    let mut k = corners.map(|i| self.tets[t][i]);
                    k.sort_unstable();
                    (k, (4 * t + f) as u32)
                })
            })
            .collect();
        faces.sort_unstable();
        let mut on_boundary = vec![false; 4 * self.tets.len()];
        for (k, &(key, slot)) in faces.iter().enumerate() {
            let shared = (k > 0 && faces[k - 1].0 == key)
                || faces.get(k + 1).is_some_and(|next| next.0 == key);
            on_boundary[slot as usize] = !shared;
        }
        let mut vertex_of_node: Vec<Option<u32>> = vec![None; self.nodes.len()];
        let mut out = Boundary::default();
        for t in (0..self.tets.len()).filter(|&t| selected(t)) {
            for (f, corners) in TET_FACES.iter().enumerate() {
                if !on_boundary[4 * t + f] {
                    continue;
                }
                let tri = corners.map(|i| {
                    let node = self.tets[t][i];
                    *vertex_of_node[node as usize].get_or_insert_with(|| {
                        out.node_of_vertex.push(node);
                        out.surface.vertices.push(self.nodes[node as usize]);
                        (out.node_of_vertex.len() - 1) as u32
                    })
                });
                out.surface.triangles.push(tri);
                out.triangle_tets.push(t as u32);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube split into 6 tets around the diagonal 0-6 (Kuhn triangulation).
    pub(crate) fn kuhn_cube() -> TetMesh {
        let nodes = (0..8)
            .map(|i| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        // Corners by bit index: x = bit 0, y = bit 1, z = bit 2; diagonal 0 -> 7.
        let paths = [[1, 3], [1, 5], [2, 3], [2, 6], [4, 5], [4, 6]];
        let mut m = TetMesh {
            nodes,
            tets: paths.iter().map(|p| [0, p[0], p[1], 7]).collect(),
            regions: vec![1, 1, 1, 2, 2, 2],
        };
        m.orient_positive();
        m
    }

    #[test]
    fn kuhn_cube_volumes_and_orientation() {
        let m = kuhn_cube();
        m.validate().unwrap();
        assert_eq!(m.inverted_count(), 0);
        for t in 0..6 {
            assert!((m.tet_volume(t) - 1.0 / 6.0).abs() < 1e-12);
        }
        assert!((m.volume() - 1.0).abs() < 1e-12);
        assert!((m.region_volume(1) - 0.5).abs() < 1e-12);
        assert_eq!(m.region_ids(), vec![1, 2]);
    }

    #[test]
    fn whole_boundary_is_the_cube_surface_outward() {
        let m = kuhn_cube();
        let b = m.boundary(BoundaryOf::Whole);
        assert_eq!(b.surface.triangles.len(), 12);
        assert_eq!(b.surface.vertices.len(), 8);
        assert!((b.surface.area() - 6.0).abs() < 1e-12);
        assert!((b.surface.signed_volume() - 1.0).abs() < 1e-12);
        for (v, &n) in b.node_of_vertex.iter().enumerate() {
            assert_eq!(b.surface.vertices[v], m.nodes[n as usize]);
        }
    }

    #[test]
    fn region_boundaries_share_the_interface() {
        let m = kuhn_cube();
        let b1 = m.boundary(BoundaryOf::Region(1));
        let b2 = m.boundary(BoundaryOf::Region(2));
        assert!((b1.surface.signed_volume() - 0.5).abs() < 1e-12);
        assert!((b2.surface.signed_volume() - 0.5).abs() < 1e-12);
        // 6 outer triangles each plus the interface, seen from both sides.
        let faces = |b: &Boundary| -> Vec<[u32; 3]> {
            b.node_triangles()
                .into_iter()
                .map(|mut k| {
                    k.sort_unstable();
                    k
                })
                .collect()
        };
        let (f1, f2) = (faces(&b1), faces(&b2));
        let shared = f1.iter().filter(|f| f2.contains(f)).count();
        assert_eq!(f1.len(), 8);
        assert_eq!(shared, 2);
    }

    #[test]
    fn validate_reports_bad_indices() {
        let mut m = kuhn_cube();
        m.tets[2][1] = 99;
        assert!(matches!(
            m.validate(),
            Err(TetMeshError::NodeIndex {
                tet: 2,
                node: 99,
                ..
            })
        ));
        let mut m = kuhn_cube();
        m.regions.pop();
        assert!(matches!(
            m.validate(),
            Err(TetMeshError::RegionCount { .. })
        ));
    }
}
