//! Named structures to compare: the surfaces of a label map (one per label, in world LPS mm),
//! the label numbering the project writes, and the pairing of reference and test structures
//! by name, including a reference that fuses several ossicles into one surface (then the test
//! side is the union of its parts).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::ear::{file_stem, structure_names};
use crate::image::nifti::is_nifti_path;
use crate::image::{ImageError, IngestConfig};
use crate::mesh::TriMesh;
use crate::mesh::io::{read_surface, surface_extension};
use crate::mesh::isosurface::label_surface;
use crate::mesh::union::outer_surface;

/// The label numbers of the project's label maps (phantom segmentations).
pub const DEFAULT_LABELS: [(u16, &str); 4] =
    [(1, "malleus"), (2, "incus"), (3, "stapes"), (4, "eardrum")];

/// Names that stand for several structures fused into one surface.
pub const FUSED_NAMES: [(&str, &[&str]); 2] = [
    ("ossicles", &["malleus", "incus", "stapes"]),
    ("chain", &["malleus", "incus", "stapes"]),
];

/// A set of structures could not be read.
#[derive(Debug, thiserror::Error)]
pub enum StructuresError {
    #[error("{path}: no such file or folder")]
    NotFound { path: PathBuf },
    #[error("{path}: no surface mesh (.ply, .stl, .obj, .vtu) or label map (.nii, .nii.gz) found")]
    NothingToCompare { path: PathBuf },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Mesh(#[from] crate::mesh::io::MeshIoError),
    #[error(transparent)]
    Image(#[from] ImageError),
}

/// A named surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Structure {
    pub name: String,
    pub mesh: TriMesh,
}

/// One surface per label of `table` present in the label map, via [`label_surface`].
pub fn structures_from_labels(
    volume: &crate::image::Volume,
    table: &[(u16, String)],
) -> Vec<Structure> {
    let labels: Vec<u16> = volume
        .data
        .iter()
        .map(|v| v.round().max(0.0) as u16)
        .collect();
    table
        .iter()
        .filter(|(label, _)| labels.contains(label))
        .map(|(label, name)| Structure {
            name: name.clone(),
            mesh: label_surface(
                volume.dims,
                &labels,
                &[*label],
                volume.origin,
                volume.index_to_world_matrix(),
            ),
        })
        .collect()
}

/// Mesh file extensions read as one structure each (named by the file stem).
/// The structures at `path`: a mesh file (one structure), a label map (one per label of
/// `labels`), or a folder of such files (meshes preferred; a label map is used when the
/// folder holds no mesh). A mesh is named by the structure its file name names
/// ([`structure_names`]: `Malleus.stl`, `01_Malleus.ply` and `Segmentation_Malleus.obj` are
/// the malleus), else by its stem.
pub fn load_structures(
    path: &Path,
    labels: &[(u16, String)],
    ingest: &IngestConfig,
) -> Result<Vec<Structure>, StructuresError> {
    if !path.exists() {
        return Err(StructuresError::NotFound {
            path: path.to_path_buf(),
        });
    }
    if path.is_file() {
        if is_nifti_path(path) {
            let image = crate::image::load(path, None, ingest)?;
            return Ok(structures_from_labels(&image.volume, labels));
        }
        let names = structure_names(&[path.to_path_buf()]);
        return Ok(vec![Structure {
            name: names.into_iter().next().unwrap_or_else(|| file_stem(path)),
            mesh: read_surface(path)?,
        }]);
    }
    let mut entries: Vec<_> = std::fs::read_dir(path)
        .map_err(|source| StructuresError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    entries.sort();
    let meshes: Vec<PathBuf> = entries
        .iter()
        .filter(|p| surface_extension(p).is_some())
        .cloned()
        .collect();
    if !meshes.is_empty() {
        let names = structure_names(&meshes);
        // each file parsed on its own thread: a segmentation's surfaces are a few MB each
        return meshes
            .into_par_iter()
            .zip(names)
            .map(|(p, name)| {
                Ok(Structure {
                    name,
                    mesh: read_surface(&p)?,
                })
            })
            .collect();
    }
    match entries.iter().find(|p| is_nifti_path(p)) {
        Some(map) => load_structures(map, labels, ingest),
        None => Err(StructuresError::NothingToCompare {
            path: path.to_path_buf(),
        }),
    }
}

/// Parses a label table such as "1=malleus,2=incus".
pub fn parse_label_table(text: &str) -> Result<Vec<(u16, String)>, String> {
    text.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|item| {
            let (label, name) = item
                .split_once('=')
                .ok_or_else(|| format!("{item:?}: expected LABEL=NAME"))?;
            let label = label.trim().parse::<u16>().map_err(|_| {
                format!("{item:?}: the label must be a whole number from 0 to 65535")
            })?;
            Ok((label, name.trim().to_string()))
        })
        .collect()
}

/// The default label table as owned pairs.
pub fn default_label_table() -> Vec<(u16, String)> {
    DEFAULT_LABELS
        .iter()
        .map(|(l, n)| (*l, n.to_string()))
        .collect()
}

/// A reference structure and the test surface to compare with it.
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    pub name: String,
    pub reference: TriMesh,
    pub test: TriMesh,
    /// How the test surface was made, when a user should know: several test parts that could
    /// not be united (one not closed) are all their faces, joint facets included.
    pub note: Option<String>,
}

/// Pairs structures by (case-insensitive) name. `aliases` maps a reference name to test names
/// (the `--pair` option); a fused reference name (e.g. "ossicles") pairs with the union of its
/// parts (their outer surface, `mesh::union`, when they are closed surfaces, else all their
/// faces, with a note). Returns the pairs and the names left unpaired on either side.
pub fn pair_structures(
    reference: &[Structure],
    test: &[Structure],
    aliases: &BTreeMap<String, Vec<String>>,
) -> (Vec<Pair>, Vec<String>) {
    let key = |s: &str| s.trim().to_ascii_lowercase();
    let by_name: BTreeMap<String, &TriMesh> =
        test.iter().map(|s| (key(&s.name), &s.mesh)).collect();
    let mut pairs = Vec::new();
    let mut unpaired = Vec::new();
    let mut used = Vec::new();
    for r in reference {
        let name = key(&r.name);
        let wanted: Vec<String> = match aliases.get(&name) {
            Some(list) => list.iter().map(|s| key(s)).collect(),
            None if by_name.contains_key(&name) => vec![name.clone()],
            None => FUSED_NAMES
                .iter()
                .find(|(fused, _)| *fused == name)
                .map(|(_, parts)| parts.iter().map(|p| p.to_string()).collect())
                .unwrap_or_default(),
        };
        let parts: Vec<&TriMesh> = wanted
            .iter()
            .filter_map(|w| by_name.get(w).copied())
            .collect();
        if parts.is_empty() || parts.len() != wanted.len() {
            unpaired.push(format!("reference {}", r.name));
            continue;
        }
        used.extend(wanted.iter().cloned());
        // one part is itself; several are the outer surface of their union when they are
        // closed, else (no inside to decide what hides what) all their faces
        let (test, note) = match parts.as_slice() {
            [one] => ((*one).clone(), None),
            _ => match outer_surface(&parts, "test") {
                Ok(union) => (union, None),
                Err(e) => (
                    TriMesh::concatenated(&parts),
                    Some(format!(
                        "{}: the test's {} compared with all their faces, facets where they \
                         meet included, as they could not be united ({e})",
                        r.name,
                        wanted.join(", ")
                    )),
                ),
            },
        };
        pairs.push(Pair {
            name: r.name.clone(),
            reference: r.mesh.clone(),
            test,
            note,
        });
    }
    unpaired.extend(
        test.iter()
            .filter(|s| !used.contains(&key(&s.name)))
            .map(|s| format!("test {}", s.name)),
    );
    (pairs, unpaired)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Volume;
    use crate::mesh::shapes;
    use nalgebra::{Matrix3, Point3, Vector3};

    fn named(name: &str, r: f64) -> Structure {
        Structure {
            name: name.into(),
            mesh: shapes::icosphere(Point3::new(r * 3.0, 0.0, 0.0), r, 1),
        }
    }

    fn parts_triangles(parts: &[Structure]) -> usize {
        parts.iter().map(|s| s.mesh.triangles.len()).sum()
    }

    #[test]
    fn pairs_by_name_alias_and_fused_reference() {
        let test = [
            named("Malleus", 1.0),
            named("incus", 1.1),
            named("stapes", 0.5),
            named("eardrum", 2.0),
        ];
        let reference = [
            named("malleus", 1.0),
            named("ossicles", 3.0),
            named("TM", 2.0),
        ];
        let aliases = BTreeMap::from([("tm".to_string(), vec!["eardrum".to_string()])]);
        let (pairs, unpaired) = pair_structures(&reference, &test, &aliases);
        assert_eq!(pairs.len(), 3);
        let fused = &pairs[1];
        assert_eq!(fused.name, "ossicles");
        // the malleus and incus spheres overlap: their union hides part of each
        let parts: f64 = test[..3].iter().map(|s| s.mesh.area()).sum();
        let (area, stapes) = (fused.test.area(), test[2].mesh.area());
        assert!(
            area > stapes + test[1].mesh.area() && area < parts - 1.0,
            "{area} of {parts}"
        );
        assert!(unpaired.is_empty(), "{unpaired:?}");
        assert!(pairs.iter().all(|p| p.note.is_none()));
        // an open stapes: no inside, so all the faces, and a note saying so
        let mut open = test.clone();
        open[2].mesh.triangles.pop();
        let (pairs, _) = pair_structures(&reference, &open, &aliases);
        assert_eq!(pairs[1].test.triangles.len(), parts_triangles(&open[..3]));
        let note = pairs[1].note.as_deref().unwrap_or_default();
        assert!(
            note.contains("malleus, incus, stapes") && note.contains("not a closed"),
            "{note}"
        );
        let (_, unpaired) = pair_structures(&[named("cochlea", 1.0)], &test, &BTreeMap::new());
        assert_eq!(unpaired.len(), 5);
    }

    #[test]
    fn label_tables_parse_with_clear_errors() {
        assert_eq!(
            parse_label_table("1=malleus, 7 = TM").unwrap(),
            vec![(1, "malleus".into()), (7, "TM".into())]
        );
        assert!(
            parse_label_table("x=malleus")
                .unwrap_err()
                .contains("whole number")
        );
        assert!(parse_label_table("3").unwrap_err().contains("LABEL=NAME"));
    }

    /// A segmentation exported by another tool: each mesh is the structure its file name
    /// names, a name that names none keeps its stem, and a single file is named alike.
    #[test]
    fn a_segmentation_folder_names_its_structures_by_their_file_names() {
        let tmp = tempfile::tempdir().unwrap();
        let ball = |r| shapes::icosphere(Point3::origin(), r, 1);
        let files = [
            ("Segmentation_Malleus.stl", 1.0),
            ("Incus.ply", 1.1),
            ("Segment_3.obj", 0.5),
            ("Segmentation_Tympanic membrane.ply", 2.0),
        ];
        for (file, r) in files {
            let path = tmp.path().join(file);
            let mesh = ball(r);
            match surface_extension(&path).as_deref() {
                Some("stl") => crate::mesh::io::stl::write_stl(
                    &path,
                    &mesh,
                    crate::mesh::io::stl::StlEncoding::Ascii,
                ),
                Some("ply") => crate::mesh::io::ply::write_ply(&path, &mesh, &Default::default()),
                _ => crate::mesh::io::obj::write_obj(&path, &mesh),
            }
            .unwrap();
        }
        let ingest = IngestConfig {
            max_file_mib: 64.0,
            max_volume_mib: 64.0,
            slice_gap_tolerance: 0.2,
            orientation_tolerance: 1e-3,
        };
        let mut found: Vec<(String, usize)> = load_structures(tmp.path(), &[], &ingest)
            .unwrap()
            .into_iter()
            .map(|s| (s.name, s.mesh.triangles.len()))
            .collect();
        found.sort();
        let names: Vec<&str> = found.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["Segment_3", "eardrum", "incus", "malleus"]);
        assert!(found.iter().all(|(_, t)| *t == 80));
        let one = load_structures(&tmp.path().join("Incus.ply"), &[], &ingest).unwrap();
        assert_eq!(one[0].name, "incus");
    }

    #[test]
    fn label_map_gives_one_surface_per_present_label() {
        let mut v = Volume {
            dims: [10, 10, 10],
            spacing: [0.5; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data: vec![0.0; 1000],
        };
        for idx in [v.index(2, 2, 2), v.index(3, 2, 2)] {
            v.data[idx] = 1.0;
        }
        let idx = v.index(7, 7, 7);
        v.data[idx] = 3.0;
        let table: Vec<(u16, String)> = DEFAULT_LABELS
            .iter()
            .map(|(l, n)| (*l, n.to_string()))
            .collect();
        let s = structures_from_labels(&v, &table);
        let names: Vec<&str> = s.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["malleus", "stapes"]);
        // two voxels enclose more than one
        assert!(s[0].mesh.signed_volume() > s[1].mesh.signed_volume());
    }
}
