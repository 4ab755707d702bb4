//! Errors of the surface-distance module: which mesh (by role) or option is wrong, and what
//! was expected, so a user can fix the input file or configuration.

use crate::mesh::spatial::SpatialError;

/// Why a surface comparison could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshDevError {
    /// A surface cannot be indexed (empty, bad index, non-finite vertex, too large).
    #[error(transparent)]
    Spatial(#[from] SpatialError),
    #[error("{mesh} mesh: has zero total area; expected at least one non-degenerate triangle")]
    ZeroArea { mesh: &'static str },
    #[error("option {field} = {value}: expected {expected}")]
    InvalidOption {
        field: &'static str,
        value: String,
        expected: &'static str,
    },
}
