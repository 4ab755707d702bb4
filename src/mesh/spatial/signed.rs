//! A triangle surface indexed for signed-distance queries: the exact closest point from the
//! [`Bvh`] and its sign from the [`Pseudonormals`] of the feature it lies on (Bærentzen &
//! Aanæs 2005); positive outside, negative inside. Exact for closed, consistently oriented
//! 2-manifolds.

use nalgebra::Point3;

use super::{Bvh, Pseudonormals, SpatialError};
use crate::mesh::TriMesh;

/// A surface indexed for signed closest-point queries.
#[derive(Debug, Clone)]
pub struct SignedSurface {
    pub bvh: Bvh,
    pub normals: Pseudonormals,
}

impl SignedSurface {
    /// Indexes `mesh`; `role` names it in errors.
    pub fn new(mesh: &TriMesh, role: &'static str) -> Result<Self, SpatialError> {
        let (bvh, normals) =
            rayon::join(|| Bvh::new(mesh, role), || Pseudonormals::new(mesh, role));
        Ok(SignedSurface {
            bvh: bvh?,
            normals: normals?,
        })
    }

    /// Signed distance of `p` (mm): positive outside, negative inside.
    #[inline]
    pub fn signed_distance(&self, p: &Point3<f64>) -> f64 {
        let hit = self.bvh.closest(p);
        self.normals.signed_distance(p, &hit)
    }

    /// Axis-aligned bounds of the surface (lowest and highest corner, mm).
    #[inline]
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        self.bvh.bounds()
    }
}
