//! Why a triangle surface cannot be indexed for closest-point queries, naming the mesh by its
//! role ("test", "reference", "surface") so a user can fix the input file; and the check
//! that every index structure runs first.

use crate::mesh::TriMesh;

/// A triangle surface that cannot be indexed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpatialError {
    #[error("{mesh} mesh: has no triangles; expected a non-empty triangle surface")]
    Empty { mesh: &'static str },
    #[error(
        "{mesh} mesh: triangle {triangle} refers to vertex {index}, but there are only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        mesh: &'static str,
        triangle: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("{mesh} mesh: vertex {vertex} has a non-finite coordinate; expected finite mm")]
    NonFiniteVertex { mesh: &'static str, vertex: usize },
    #[error("{mesh} mesh: {count} triangles exceed the supported 2^32 - 1")]
    TooManyTriangles { mesh: &'static str, count: usize },
}

/// Checks that `mesh` can be indexed: triangles present, indices in range, finite vertices.
pub fn validate_mesh(mesh: &TriMesh, role: &'static str) -> Result<(), SpatialError> {
    if mesh.triangles.is_empty() {
        return Err(SpatialError::Empty { mesh: role });
    }
    if u32::try_from(mesh.triangles.len()).is_err() {
        return Err(SpatialError::TooManyTriangles {
            mesh: role,
            count: mesh.triangles.len(),
        });
    }
    let vertex_count = mesh.vertices.len();
    for (triangle, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(SpatialError::IndexOutOfRange {
                mesh: role,
                triangle,
                index,
                vertex_count,
            });
        }
    }
    if let Some(vertex) = mesh
        .vertices
        .iter()
        .position(|v| !v.coords.iter().all(|x| x.is_finite()))
    {
        return Err(SpatialError::NonFiniteVertex { mesh: role, vertex });
    }
    Ok(())
}
