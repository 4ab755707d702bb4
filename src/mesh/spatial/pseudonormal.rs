//! Inside/outside sign of a point relative to a reference surface, from the angle-weighted
//! pseudonormal of the feature its closest point lies on.
//!
//! Bærentzen & Aanæs, "Signed distance computation using the angle weighted pseudonormal",
//! IEEE TVCG 11(3), 2005: for a closed, consistently oriented 2-manifold, the sign of
//! `n(q*)·(p − q*)` is the inside/outside sign of `p` when `n` is the face normal for a face
//! hit, the sum of the two face normals for an edge hit, and the sum of incident face normals
//! weighted by their corner angles for a vertex hit. Convention of the surface-distance
//! metrics (docs/metrics.md): positive = the point is outside the reference. Boundary
//! edges of open surfaces use their one face normal; non-manifold edges sum all their faces.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::bvh::ClosestHit;
use super::closest::Feature;
use super::error::{SpatialError, validate_mesh};
use crate::mesh::TriMesh;

/// Face, edge and vertex pseudonormals of one surface.
#[derive(Debug, Clone)]
pub struct Pseudonormals {
    triangles: Vec<[u32; 3]>,
    face: Vec<Vector3<f64>>,
    /// Per triangle, per local edge (0: corners 0–1, 1: 1–2, 2: 2–0).
    edge: Vec<[Vector3<f64>; 3]>,
    vertex: Vec<Vector3<f64>>,
}

/// Interior angle at corner `a` of triangle (a, b, c).
fn corner_angle(a: &Point3<f64>, b: &Point3<f64>, c: &Point3<f64>) -> f64 {
    let (u, v) = (b - a, c - a);
    u.cross(&v).norm().atan2(u.dot(&v))
}

impl Pseudonormals {
    /// Computes the pseudonormals of `mesh`; `role` names the mesh in errors.
    pub fn new(mesh: &TriMesh, role: &'static str) -> Result<Self, SpatialError> {
        validate_mesh(mesh, role)?;
        let n = mesh.triangles.len();
        let face: Vec<Vector3<f64>> = (0..n)
            .into_par_iter()
            .map(|t| {
                mesh.area_normal2(t)
                    .try_normalize(0.0)
                    .unwrap_or_else(Vector3::zeros)
            })
            .collect();
        let mut vertex = vec![Vector3::zeros(); mesh.vertices.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let c = mesh.corners(t);
            for i in 0..3 {
                let angle = corner_angle(&c[i], &c[(i + 1) % 3], &c[(i + 2) % 3]);
                vertex[tri[i] as usize] += face[t] * angle;
            }
        }
        // Undirected edges, sorted so that the faces sharing an edge are adjacent.
        let mut edges: Vec<(u32, u32, u32, u8)> = Vec::with_capacity(3 * n);
        for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
            for (e, (p, q)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
                edges.push((p.min(q), p.max(q), t as u32, e as u8));
            }
        }
        edges.par_sort_unstable();
        let mut edge = vec![[Vector3::zeros(); 3]; n];
        for group in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let sum: Vector3<f64> = group.iter().map(|g| face[g.2 as usize]).sum();
            for g in group {
                edge[g.2 as usize][g.3 as usize] = sum;
            }
        }
        Ok(Pseudonormals {
            triangles: mesh.triangles.clone(),
            face,
            edge,
            vertex,
        })
    }

    /// The pseudonormal (not normalised) at the closest-point feature `hit`.
    pub fn normal(&self, hit: &ClosestHit) -> Vector3<f64> {
        let t = hit.triangle as usize;
        match hit.feature {
            Feature::Face => self.face[t],
            Feature::Edge(e) => self.edge[t][e as usize],
            Feature::Vertex(v) => self.vertex[self.triangles[t][v as usize] as usize],
        }
    }

    /// Signed distance of `p` given its closest hit on this surface: `+hit.distance` outside,
    /// `−hit.distance` inside (0 on the surface).
    pub fn signed_distance(&self, p: &Point3<f64>, hit: &ClosestHit) -> f64 {
        if self.normal(hit).dot(&(p - hit.point)) < 0.0 {
            -hit.distance
        } else {
            hit.distance
        }
    }
}
