//! Errors of the surface-distance module: which mesh (by role) or option is wrong, and what
//! was expected, so a user can fix the input file or configuration.

/// Why a surface comparison could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshDevError {
    #[error("{mesh} mesh: has no triangles; expected a non-empty triangle surface")]
    Empty { mesh: &'static str },
    #[error("{mesh} mesh: has zero total area; expected at least one non-degenerate triangle")]
    ZeroArea { mesh: &'static str },
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
    #[error("option {field} = {value}: expected {expected}")]
    InvalidOption {
        field: &'static str,
        value: String,
        expected: &'static str,
    },
}
