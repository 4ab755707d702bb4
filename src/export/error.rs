//! What can stop a package from being written or verified: a file, the atlas, a mesh or the
//! mechanics behind the scene, each with its own message, or a folder that is not a package.

use std::path::PathBuf;

use crate::atlas::AtlasError;
use crate::io_util::FileError;
use crate::mechanics::MechanicsError;
use crate::mesh::io::MeshIoError;

/// A package could not be written or verified.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error(transparent)]
    Atlas(#[from] AtlasError),
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error(transparent)]
    Mechanics(#[from] MechanicsError),
    /// The atlas cannot be written as a SOFA scene.
    #[error("atlas '{atlas}': {message}")]
    Materials { atlas: String, message: String },
    #[error("{path}: cannot serialise: {message}")]
    Serialise { path: PathBuf, message: String },
    #[error("{path}: not a package folder (expected a folder with {manifest})")]
    NotAPackage {
        path: PathBuf,
        manifest: &'static str,
    },
}
