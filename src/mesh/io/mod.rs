//! Mesh file formats, read and write: PLY, STL and OBJ surfaces, VTU (VTK XML) and Gmsh MSH
//! 2.2 volumes; VTP (VTK XML PolyData) surfaces with point data are written only. Every reader reports the file, the line or field and what was expected, and
//! never panics on bad input; every writer writes atomically (temporary sibling + rename).

pub mod gmsh;
pub mod obj;
pub mod ply;
pub mod stl;
pub mod volume;
pub mod vtu;
mod xml;

pub use volume::{CellArray, VolumeMesh};

use std::path::{Path, PathBuf};

/// A mesh file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum MeshIoError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {at}: expected {expected}")]
    Parse {
        path: PathBuf,
        /// Line, element or field where reading stopped.
        at: String,
        expected: String,
    },
}

impl MeshIoError {
    pub(crate) fn parse(path: &Path, at: impl Into<String>, expected: impl Into<String>) -> Self {
        MeshIoError::Parse {
            path: path.to_path_buf(),
            at: at.into(),
            expected: expected.into(),
        }
    }
}

/// Reads a whole file.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, MeshIoError> {
    std::fs::read(path).map_err(|source| MeshIoError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes a whole file atomically.
pub(crate) fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), MeshIoError> {
    crate::io_util::write_atomic(path, bytes)
        .map_err(|crate::io_util::FileError { path, source }| MeshIoError::Io { path, source })
}

/// Reads a text file (UTF-8, lossy for stray bytes in comments), holding it once in memory
/// when it is valid UTF-8 (no copy).
pub(crate) fn read_text(path: &Path) -> Result<String, MeshIoError> {
    Ok(String::from_utf8(read_bytes(path)?)
        .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned()))
}

/// Checks that every triangle index is below `vertices`.
pub(crate) fn check_indices(
    path: &Path,
    triangles: &[[u32; 3]],
    vertices: usize,
) -> Result<(), MeshIoError> {
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&v) = tri.iter().find(|&&v| v as usize >= vertices) {
            return Err(MeshIoError::parse(
                path,
                format!("triangle {t}"),
                format!("vertex indices below {vertices}, found {v}"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod meshio_check;
#[cfg(test)]
mod robustness;
#[cfg(test)]
pub(crate) mod test_meshes;
