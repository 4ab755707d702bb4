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

/// The surface formats [`read_surface`] reads, by file extension (any case).
pub const SURFACE_EXTENSIONS: [&str; 4] = ["ply", "stl", "obj", "vtu"];

/// The surface format of `path` by its extension (lowercased), if [`read_surface`] reads it.
pub fn surface_extension(path: &Path) -> Option<String> {
    let ext = path.extension()?.to_string_lossy().to_ascii_lowercase();
    SURFACE_EXTENSIONS.contains(&ext.as_str()).then_some(ext)
}

/// The surface files of folder `dir` that [`read_surface`] reads, sorted by name; none when
/// the folder does not exist.
pub fn surface_files(dir: &Path) -> Result<Vec<PathBuf>, MeshIoError> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let entries = std::fs::read_dir(dir).map_err(|source| MeshIoError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && surface_extension(p).is_some())
        .collect();
    files.sort();
    Ok(files)
}

/// Reads a triangle surface by its extension: PLY, STL, OBJ, or a VTU's triangle cells (a
/// VTU of tetrahedra only, such as a finite-element model's: the boundary of its tetrahedra,
/// outward for positively oriented ones).
pub fn read_surface(path: &Path) -> Result<crate::mesh::TriMesh, MeshIoError> {
    Ok(match surface_extension(path).as_deref() {
        Some("ply") => ply::read_ply(path)?.0,
        Some("stl") => stl::read_stl(path)?,
        Some("obj") => obj::read_obj(path)?,
        Some(_) => {
            let (volume, _) = vtu::read_vtu(path)?;
            if volume.triangles.is_empty() && !volume.tets.tets.is_empty() {
                volume
                    .tets
                    .boundary(crate::mesh::tet::BoundaryOf::Whole)
                    .surface
            } else {
                crate::mesh::TriMesh {
                    vertices: volume.tets.nodes,
                    triangles: volume.triangles,
                }
            }
        }
        None => {
            return Err(MeshIoError::parse(
                path,
                "file extension",
                "a surface mesh: .ply, .stl, .obj or .vtu",
            ));
        }
    })
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
