//! `TriMesh`: an indexed triangle surface in world coordinates (LPS mm), counter-clockwise
//! triangles seen from outside (outward normals by the right-hand rule).

use nalgebra::{Point3, Vector3};

/// An indexed triangle surface.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<Point3<f64>>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// The three corners of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Point3<f64>; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Twice the area times the unit normal of triangle `t` (right-hand rule).
    #[inline]
    pub fn area_normal2(&self, t: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(t);
        (b - a).cross(&(c - a))
    }

    /// Area of triangle `t`.
    pub fn triangle_area(&self, t: usize) -> f64 {
        0.5 * self.area_normal2(t).norm()
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t))
            .sum()
    }

    /// Signed enclosed volume (positive for a closed, outward-oriented surface).
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.origin_tetra_volume(t))
            .sum()
    }

    /// Signed volume of the tetrahedron from the origin to triangle `t`: its share of the
    /// enclosed volume.
    pub fn origin_tetra_volume(&self, t: usize) -> f64 {
        let [a, b, c] = self.corners(t);
        a.coords.dot(&b.coords.cross(&c.coords)) / 6.0
    }

    /// The surface of `triangles` over a larger node array, with only the nodes they use
    /// (in order of first use).
    pub fn compacted(triangles: &[[u32; 3]], nodes: &[Point3<f64>]) -> TriMesh {
        let mut index = std::collections::HashMap::new();
        let mut mesh = TriMesh::default();
        for t in triangles {
            let tri = t.map(|v| {
                *index.entry(v).or_insert_with(|| {
                    mesh.vertices.push(nodes[v as usize]);
                    (mesh.vertices.len() - 1) as u32
                })
            });
            mesh.triangles.push(tri);
        }
        mesh
    }

    /// The surface of the triangles whose `keep` is true, with only the vertices they use.
    pub fn kept(&self, keep: &[bool]) -> TriMesh {
        let kept: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(t, _)| *t)
            .collect();
        TriMesh::compacted(&kept, &self.vertices)
    }

    /// The surfaces side by side in one mesh (vertices and triangles appended in order; faces
    /// where they touch or overlap are kept: `mesh::union` drops those).
    pub fn concatenated(meshes: &[&TriMesh]) -> TriMesh {
        let mut out = TriMesh::default();
        for m in meshes {
            let base = out.vertices.len() as u32;
            out.vertices.extend_from_slice(&m.vertices);
            out.triangles
                .extend(m.triangles.iter().map(|t| t.map(|v| v + base)));
        }
        out
    }

    /// Barycentre of triangle `t`.
    pub fn triangle_centroid(&self, t: usize) -> Point3<f64> {
        let [a, b, c] = self.corners(t);
        Point3::from((a.coords + b.coords + c.coords) / 3.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cube_area_and_volume() {
        let c = crate::mesh::shapes::box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), 3);
        assert!((c.area() - 6.0).abs() < 1e-12);
        assert!((c.signed_volume() - 1.0).abs() < 1e-12);
    }
}
