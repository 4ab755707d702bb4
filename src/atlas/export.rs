//! Writing an atlas (at its rest shape or registered onto a patient) in the formats viewers
//! and checkers read: one PLY surface per structure, the whole FEM mesh as VTU with region and
//! material per cell, and the landmarks as JSON and 3D Slicer markups. All positions in LPS mm.

use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::AtlasError;
use super::model::{Atlas, Part};
use crate::ear::Landmarks;
use crate::ear::{write_fcsv, write_json};
use crate::io_util::write_atomic;
use crate::mesh::io::ply::{VertexAttributes, write_ply};
use crate::mesh::io::vtu::{VtuEncoding, write_vtu};
use crate::mesh::io::{CellArray, VolumeMesh};

/// The files an export wrote, for reports.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Exported {
    pub files: Vec<PathBuf>,
}

/// Writes `surfaces/{malleus,incus,stapes,eardrum}.ply`, `volume.vtu`, `landmarks.json` and
/// `landmarks.fcsv` under `out`, with the atlas's nodes at `nodes`.
pub fn export_atlas(
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    out: &Path,
) -> Result<Exported, AtlasError> {
    let surfaces = out.join("surfaces");
    std::fs::create_dir_all(&surfaces).map_err(crate::io_util::io_err(&surfaces))?;
    let mut files = Vec::new();
    for part in Part::STRUCTURES {
        if atlas.labels_of(part).is_empty() {
            continue;
        }
        let path = surfaces.join(format!("{}.ply", part.name()));
        write_ply(
            &path,
            &atlas.part_surface(part, nodes),
            &VertexAttributes::default(),
        )?;
        files.push(path);
    }
    let volume = out.join("volume.vtu");
    let mesh = VolumeMesh {
        tets: crate::mesh::TetMesh {
            nodes: nodes.to_vec(),
            ..atlas.mesh.tets.clone()
        },
        ..atlas.mesh.clone()
    };
    write_vtu(&volume, &mesh, &material_arrays(atlas), VtuEncoding::Base64)?;
    files.push(volume);
    let landmarks: Landmarks = atlas.landmark_positions(nodes);
    for (name, text) in [
        ("landmarks.json", write_json(&landmarks, Some(atlas.side))),
        ("landmarks.fcsv", write_fcsv(&landmarks)),
    ] {
        let path = out.join(name);
        write_atomic(&path, text.as_bytes())?;
        files.push(path);
    }
    Ok(Exported { files })
}

/// Per-cell material arrays (tetrahedra, then triangles): Young's modulus, density,
/// Poisson's ratio and membrane thickness (0 for tetrahedra), SI as in the atlas.
pub fn material_arrays(atlas: &Atlas) -> Vec<CellArray> {
    let cells: Vec<u16> = atlas.mesh.cell_regions().collect();
    let column = |name: &str, f: &dyn Fn(u16) -> f64| CellArray {
        name: name.into(),
        values: cells.iter().map(|&l| f(l)).collect(),
    };
    let material = |l: u16| {
        atlas
            .region(l)
            .and_then(|r| atlas.materials.get(&r.material))
    };
    vec![
        column("youngs_modulus_pa", &|l| {
            material(l).map_or(f64::NAN, |m| m.youngs_modulus_pa)
        }),
        column("density_kg_m3", &|l| {
            material(l).map_or(f64::NAN, |m| m.density_kg_m3)
        }),
        column("poisson_ratio", &|l| {
            material(l).map_or(f64::NAN, |m| m.poisson_ratio)
        }),
        column("thickness_mm", &|l| {
            atlas.region(l).and_then(|r| r.thickness_mm).unwrap_or(0.0)
        }),
    ]
}
