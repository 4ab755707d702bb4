//! Importing an atlas from a tagged volume mesh (VTU or Gmsh MSH 2.2): every cell carries an
//! integer tag, and a mapping file ([`super::mapping`]) says what each tag is — a region with
//! its part, material and (for triangles) membrane thickness, a tag to drop, a node set or a
//! load surface. Tetrahedra are oriented positively, unused nodes are removed, and the three
//! landmarks (any file `register::landmarks` reads) are tied to the mesh; a landmark off the
//! mesh is rejected.
//!
//! What an imported atlas carries is what the mapping gives it: no node set or load surface
//! is invented, and the damping is the default atlas's.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::format::{AtlasError, LANDMARK_TOLERANCE_MM, default_atlas, validate};
use super::mapping::{Mapping, read_mapping, resolve_regions};
use super::model::{Atlas, MeshPoint, TiedLandmarks};
use crate::ear::read_landmarks;
use crate::ear::{LandmarkName, Landmarks, Side};
use crate::io_util::sha256_hex;
use crate::mesh::TetMesh;
use crate::mesh::io::gmsh::read_msh;
use crate::mesh::io::vtu::read_vtu;
use crate::mesh::io::{CellArray, VolumeMesh};

/// A mesh's cell tags (tetrahedra, then triangles).
struct Tagged {
    mesh: VolumeMesh,
    tet_tags: Vec<u16>,
    triangle_tags: Vec<u16>,
}

/// Reads the mesh and its tags: from `labels` (one integer per cell, tetrahedra first, then
/// triangles, each in file order) when given, else from the mapping's `tag_array` or the
/// mesh's own region tags.
fn read_tagged(mesh_path: &Path, labels: Option<&Path>, m: &Mapping) -> Result<Tagged, AtlasError> {
    let ext = mesh_path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let (mesh, arrays): (VolumeMesh, Vec<CellArray>) = match ext.as_str() {
        "vtu" => read_vtu(mesh_path)?,
        "msh" => (read_msh(mesh_path)?, Vec::new()),
        _ => {
            return Err(AtlasError::invalid(
                mesh_path,
                "file type",
                ".vtu (VTK XML) or .msh (Gmsh 2.2 ASCII)",
                format!("'.{ext}'"),
            ));
        }
    };
    let n_tets = mesh.tets.tets.len();
    let tags: Vec<u16> = if let Some(labels) = labels {
        let text = crate::io_util::read_text(labels).map_err(|source| AtlasError::Io {
            path: labels.to_path_buf(),
            source,
        })?;
        let tags = text
            .split_whitespace()
            .enumerate()
            .map(|(k, w)| {
                w.parse::<u16>().map_err(|_| {
                    AtlasError::invalid(labels, format!("label {k}"), "an integer 0-65535", w)
                })
            })
            .collect::<Result<Vec<u16>, _>>()?;
        if tags.len() != mesh.cell_count() {
            return Err(AtlasError::invalid(
                labels,
                "labels",
                format!(
                    "one per cell of {} ({})",
                    mesh_path.display(),
                    mesh.cell_count()
                ),
                tags.len().to_string(),
            ));
        }
        tags
    } else {
        match m.tag_array.as_deref() {
            None | Some("region") => mesh.cell_regions().collect(),
            Some(name) => {
                let a = arrays.iter().find(|a| a.name == name).ok_or_else(|| {
                    AtlasError::invalid(
                        mesh_path,
                        "CellData",
                        format!("a cell array named '{name}' (the mapping's tag_array)"),
                        "none",
                    )
                })?;
                a.values
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| {
                        if v.fract() == 0.0 && (0.0..=65535.0).contains(&v) {
                            Ok(v as u16)
                        } else {
                            Err(AtlasError::invalid(
                                mesh_path,
                                format!("{name}[{k}]"),
                                "an integer tag 0-65535",
                                v.to_string(),
                            ))
                        }
                    })
                    .collect::<Result<Vec<u16>, _>>()?
            }
        }
    };
    Ok(Tagged {
        triangle_tags: tags[n_tets..].to_vec(),
        tet_tags: tags[..n_tets].to_vec(),
        mesh,
    })
}

/// The atlas mesh, node sets and surfaces after the mapping.
struct Mapped {
    mesh: VolumeMesh,
    node_sets: BTreeMap<String, Vec<u32>>,
    surfaces: BTreeMap<String, Vec<[u32; 3]>>,
    dropped: usize,
    reoriented: usize,
}

fn centroid(nodes: &[Point3<f64>], cell: &[u32]) -> Point3<f64> {
    let s: Vector3<f64> = cell.iter().map(|&v| nodes[v as usize].coords).sum();
    Point3::from(s / cell.len() as f64)
}

fn apply_mapping(t: Tagged, m: &Mapping, mesh_path: &Path) -> Result<Mapped, AtlasError> {
    let Tagged {
        mesh,
        tet_tags,
        triangle_tags,
    } = t;
    let nodes = &mesh.tets.nodes;
    let unclaimed = |what: &str, k: usize, tag: u16| {
        let expected = if m.regions.iter().any(|r| r.tag == tag) {
            format!("a cell inside the `within` half-spaces of a region of tag {tag}")
        } else {
            format!("tag {tag} declared by a [[region]], a [[surface]] or drop in the mapping")
        };
        AtlasError::invalid(
            mesh_path,
            format!("{what} {k} tag"),
            expected,
            format!("tag {tag} (a cell label not declared)"),
        )
    };
    let mut out = TetMesh::default();
    let mut dropped = 0;
    for (k, (tet, &tag)) in mesh.tets.tets.iter().zip(&tet_tags).enumerate() {
        if m.drop.contains(&tag) {
            dropped += 1;
            continue;
        }
        let r = m
            .region_of(tag, &centroid(nodes, tet))
            .ok_or_else(|| unclaimed("tetrahedron", k, tag))?;
        if m.regions[r].thickness_mm.is_some() {
            return Err(AtlasError::invalid(
                mesh_path,
                format!("tetrahedron {k} tag"),
                "a volumetric region (no thickness_mm) for a tetrahedron",
                format!(
                    "tag {tag} mapped to membrane region '{}'",
                    m.regions[r].name
                ),
            ));
        }
        out.tets.push(*tet);
        out.regions.push(r as u16 + 1);
    }
    let mut triangles = Vec::new();
    let mut triangle_regions = Vec::new();
    let mut surfaces: BTreeMap<String, Vec<[u32; 3]>> = BTreeMap::new();
    for (k, (tri, &tag)) in mesh.triangles.iter().zip(&triangle_tags).enumerate() {
        let mut claimed = false;
        for s in m.surfaces.iter().filter(|s| s.tags.contains(&tag)) {
            surfaces.entry(s.name.clone()).or_default().push(*tri);
            claimed = true;
        }
        if m.drop.contains(&tag) {
            dropped += 1;
            continue;
        }
        match m.region_of(tag, &centroid(nodes, tri)) {
            // a load-surface triangle on a volumetric region's tag is no element
            Some(r) if m.regions[r].thickness_mm.is_none() && claimed => {}
            Some(r) if m.regions[r].thickness_mm.is_none() => {
                return Err(AtlasError::invalid(
                    mesh_path,
                    format!("triangle {k} tag"),
                    "a membrane region (with thickness_mm) for a triangle",
                    format!(
                        "tag {tag} mapped to volumetric region '{}'",
                        m.regions[r].name
                    ),
                ));
            }
            Some(r) => {
                triangles.push(*tri);
                triangle_regions.push(r as u16 + 1);
            }
            None if claimed => {}
            None => return Err(unclaimed("triangle", k, tag)),
        }
    }
    // keep the nodes the kept cells use, in their old order
    let mut new_index = vec![u32::MAX; nodes.len()];
    for &v in out.tets.iter().flatten().chain(triangles.iter().flatten()) {
        new_index[v as usize] = 0;
    }
    for (old, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = out.nodes.len() as u32;
            out.nodes.push(nodes[old]);
        }
    }
    let remap = |v: u32| new_index[v as usize];
    for t in &mut out.tets {
        *t = t.map(remap);
    }
    for t in &mut triangles {
        *t = t.map(remap);
    }
    let mut node_sets = BTreeMap::new();
    for s in &m.node_sets {
        let cells = mesh
            .tets
            .tets
            .iter()
            .zip(&tet_tags)
            .map(|(t, g)| (&t[..], g))
            .chain(
                mesh.triangles
                    .iter()
                    .zip(&triangle_tags)
                    .map(|(t, g)| (&t[..], g)),
            );
        let set: BTreeSet<u32> = cells
            .filter(|(_, g)| s.tags.contains(g))
            .flat_map(|(c, _)| c.iter().map(|&v| remap(v)))
            .filter(|&v| v != u32::MAX)
            .collect();
        if set.is_empty() {
            return Err(AtlasError::invalid(
                mesh_path,
                format!("node_set '{}'", s.name),
                "nodes of its tags that the atlas's cells use",
                "none",
            ));
        }
        node_sets.insert(s.name.clone(), set.into_iter().collect());
    }
    for s in &m.surfaces {
        let tris = surfaces.entry(s.name.clone()).or_default();
        for t in tris.iter_mut() {
            *t = t.map(remap);
        }
        if tris.is_empty() || tris.iter().flatten().any(|&v| v == u32::MAX) {
            return Err(AtlasError::invalid(
                mesh_path,
                format!("surface '{}'", s.name),
                "triangles of its tags on nodes of the atlas's cells",
                format!("{} triangles, some off the kept cells or none", tris.len()),
            ));
        }
    }
    let before: Vec<[u32; 4]> = out.tets.clone();
    out.orient_positive();
    let reoriented = before.iter().zip(&out.tets).filter(|(a, b)| a != b).count();
    Ok(Mapped {
        mesh: VolumeMesh {
            tets: out,
            triangles,
            triangle_regions,
        },
        node_sets,
        surfaces,
        dropped,
        reoriented,
    })
}

/// Ties the landmarks to the tetrahedra; a landmark farther than
/// [`LANDMARK_TOLERANCE_MM`] from every tetrahedron is an error naming `path`.
pub fn tie_landmarks(
    mesh: &TetMesh,
    landmarks: &Landmarks,
    path: &Path,
) -> Result<TiedLandmarks, AtlasError> {
    let tie = |name: LandmarkName| {
        let p = landmarks.get(name);
        match MeshPoint::locate(mesh, &p) {
            Some((mp, d)) if d <= LANDMARK_TOLERANCE_MM => Ok(mp),
            found => Err(AtlasError::invalid(
                path,
                name.key(),
                format!("a point on the mesh (within {LANDMARK_TOLERANCE_MM} mm)"),
                format!(
                    "({:.3}, {:.3}, {:.3}) mm, {} off the mesh",
                    p.x,
                    p.y,
                    p.z,
                    found.map_or("all tetrahedra degenerate, so".into(), |(_, d)| format!(
                        "{d:.2} mm"
                    ))
                ),
            )),
        }
    };
    Ok(TiedLandmarks {
        umbo: tie(LandmarkName::Umbo)?,
        incudomalleolar: tie(LandmarkName::Incudomalleolar)?,
        incudostapedial: tie(LandmarkName::Incudostapedial)?,
    })
}

/// The landmarks of `path` and the side: `side` if given, else the file's.
pub(crate) fn landmarks_and_side(
    path: &Path,
    side: Option<Side>,
) -> Result<(Landmarks, Side), AtlasError> {
    let file = read_landmarks(path)?;
    let side = side.or(file.side).ok_or_else(|| {
        AtlasError::invalid(
            path,
            "side",
            "--side left|right, or a landmark file that states the side",
            "no side",
        )
    })?;
    Ok((file.landmarks, side))
}

/// The files of an import.
#[derive(Debug, Clone, Copy)]
pub struct ImportRequest<'a> {
    /// The tagged volume mesh (.vtu or .msh).
    pub mesh: &'a Path,
    /// The mapping file (TOML).
    pub mapping: &'a Path,
    /// The three landmarks, in the mesh's frame.
    pub landmarks: &'a Path,
    /// One tag per cell, overriding the mesh's own tags.
    pub labels: Option<&'a Path>,
    /// The ear; default: the landmark file's.
    pub side: Option<Side>,
    /// The atlas's name.
    pub name: &'a str,
}

/// Imports and validates an atlas.
pub fn import_atlas(req: &ImportRequest<'_>) -> Result<Atlas, AtlasError> {
    let mapping = read_mapping(req.mapping)?;
    let (regions, materials) = resolve_regions(&mapping, req.mapping)?;
    let tagged = read_tagged(req.mesh, req.labels, &mapping)?;
    let mapped = apply_mapping(tagged, &mapping, req.mesh)?;
    let (landmarks, side) = landmarks_and_side(req.landmarks, req.side)?;
    let tied = tie_landmarks(&mapped.mesh.tets, &landmarks, req.landmarks)?;
    let mut provenance = BTreeMap::new();
    provenance.insert("builder".into(), "otoatlas atlas import".into());
    let mut inputs = vec![
        ("mesh", req.mesh),
        ("mapping", req.mapping),
        ("landmarks", req.landmarks),
    ];
    if let Some(l) = req.labels {
        inputs.push(("labels", l));
    }
    for (key, path) in inputs {
        let bytes = std::fs::read(path).map_err(|source| AtlasError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file = path
            .file_name()
            .map_or(String::new(), |f| f.to_string_lossy().into_owned());
        provenance.insert(key.to_string(), file);
        provenance.insert(format!("{key}_sha256"), sha256_hex(&bytes));
    }
    provenance.insert("dropped_cells".into(), mapped.dropped.to_string());
    provenance.insert(
        "reoriented_tetrahedra".into(),
        mapped.reoriented.to_string(),
    );
    // damping and supports are not in the source files: the default atlas's
    let default = default_atlas()?;
    let atlas = Atlas {
        name: req.name.to_string(),
        side,
        mesh: mapped.mesh,
        regions,
        materials,
        damping: default.damping,
        supports: default.supports,
        node_sets: mapped.node_sets,
        surfaces: mapped.surfaces,
        landmarks: tied,
        provenance,
    };
    validate(&atlas, req.mesh)?;
    Ok(atlas)
}
