//! Building an atlas from closed surfaces, one per ossicle (files named for the `malleus`,
//! `incus` and `stapes`: `.ply`, `.stl`, `.obj` or `.vtu`), with the same multi-domain mesher as the default atlas (through
//! [`SurfaceDomain`]). Such an atlas has the three bones only: no eardrum membrane (an eardrum
//! surface is open, so it bounds no volume), no joints, ligaments or tendons, and no node sets
//! or load surfaces; each bone gets one whole-bone material (see
//! [`super::mapping::material_library`]) and the landmarks come from a landmark file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::format::{AtlasError, default_atlas, validate};
use super::import::{landmarks_and_side, tie_landmarks};
use super::mapping::material_library;
use super::mass::{record_shape_volumes, restore_shape_masses};
use super::model::{Atlas, Part, RegionInfo};
use crate::ear::{CHAIN_SPAN_MM, Side, is_chain_span, span_mm, structure_names};
use crate::io_util::sha256_hex;
use crate::mesh::io::{read_surface, surface_files};
use crate::mesh::mesher::{MesherParams, SurfaceDomain, mesh_domain};

/// What to build from.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceBuild<'a> {
    /// The folder with `malleus`, `incus` and `stapes` surfaces.
    pub dir: &'a Path,
    /// The three landmarks, in the surfaces' frame.
    pub landmarks: &'a Path,
    /// The ear; default: the landmark file's.
    pub side: Option<Side>,
    pub name: &'a str,
    /// Target tetrahedron edge \[mm\].
    pub edge_mm: f64,
}

/// The one surface file in `dir` whose name names `bone` (`malleus.ply`, `01_Malleus.stl`;
/// [`structure_names`]).
fn surface_file(dir: &Path, bone: Part) -> Result<PathBuf, AtlasError> {
    let files = surface_files(dir)?;
    let names = structure_names(&files);
    let found: Vec<PathBuf> = files
        .into_iter()
        .zip(names)
        .filter(|(_, name)| name == bone.name())
        .map(|(path, _)| path)
        .collect();
    match found.as_slice() {
        [one] => Ok(one.clone()),
        _ => Err(AtlasError::invalid(
            dir,
            bone.name(),
            format!(
                "exactly one closed surface named for the {0} (.ply, .stl, .obj or .vtu: {0}.ply, 01_{0}.stl)",
                bone.name()
            ),
            format!("{} files", found.len()),
        )),
    }
}

/// Meshes the three bone surfaces into an atlas.
pub fn build_from_surfaces(req: &SurfaceBuild<'_>) -> Result<Atlas, AtlasError> {
    let files = Part::BONES
        .iter()
        .map(|&b| surface_file(req.dir, b))
        .collect::<Result<Vec<_>, _>>()?;
    let surfaces = files
        .iter()
        .map(|f| read_surface(f))
        .collect::<Result<Vec<_>, _>>()?;
    let span = span_mm(surfaces.iter().flat_map(|m| &m.vertices));
    if !is_chain_span(span) {
        return Err(AtlasError::invalid(
            req.dir,
            "surfaces",
            format!(
                "a chain spanning {} to {} mm (its bounding box's diagonal; a real chain about 13): coordinates in mm, not µm, cm, m or voxel indices",
                CHAIN_SPAN_MM.0, CHAIN_SPAN_MM.1
            ),
            format!("{span:.4}"),
        ));
    }
    let domain = SurfaceDomain::new(&surfaces).map_err(|e| {
        let file = match &e {
            crate::mesh::mesher::SurfaceDomainError::NotClosed { region, .. }
            | crate::mesh::mesher::SurfaceDomainError::InsideOut { region, .. }
            | crate::mesh::mesher::SurfaceDomainError::Invalid { region, .. } => files
                .get(usize::from(*region).wrapping_sub(1))
                .cloned()
                .unwrap_or_else(|| req.dir.to_path_buf()),
            _ => req.dir.to_path_buf(),
        };
        AtlasError::invalid(
            &file,
            "surface",
            "a closed, manifold, outward-oriented triangle surface",
            e.to_string(),
        )
    })?;
    let params = MesherParams {
        target_edge_mm: req.edge_mm,
        // the stapes crura are about 0.3 mm thick
        thin_regions: vec![3],
        // the chain's boundary a manifold where two bones touch along an edge
        manifold_groups: vec![vec![1, 2, 3]],
        ..MesherParams::default()
    };
    let mut tets = mesh_domain(&domain, &params)
        .map_err(|e| AtlasError::from(super::build::BuildError::from(e)))?
        .mesh;
    tets.orient_positive();
    let (landmarks, side) = landmarks_and_side(req.landmarks, req.side)?;
    let tied = tie_landmarks(&tets, &landmarks, req.landmarks)?;
    let library = material_library()?;
    let mut materials = BTreeMap::new();
    let mut regions = Vec::new();
    for (k, bone) in Part::BONES.iter().enumerate() {
        if let Some(m) = library.get(bone.name()) {
            materials.insert(bone.name().to_string(), m.clone());
        }
        regions.push(RegionInfo {
            label: k as u16 + 1,
            name: bone.name().to_string(),
            part: *bone,
            material: bone.name().to_string(),
            thickness_mm: None,
            bending_thickness_mm: None,
            shape_volume_mm3: None,
        });
    }
    record_shape_volumes(&domain, &mut regions);
    restore_shape_masses(&mut materials, &regions, &tets);
    let mut provenance = BTreeMap::new();
    provenance.insert("builder".into(), "otoatlas atlas build --surfaces".into());
    provenance.insert("tet_edge_mm".into(), req.edge_mm.to_string());
    for (bone, file) in Part::BONES.iter().zip(&files) {
        let bytes = std::fs::read(file).map_err(|source| AtlasError::Io {
            path: file.clone(),
            source,
        })?;
        let name = file
            .file_name()
            .map_or(String::new(), |f| f.to_string_lossy().into_owned());
        provenance.insert(format!("{}_surface", bone.name()), name);
        provenance.insert(format!("{}_sha256", bone.name()), sha256_hex(&bytes));
    }
    // damping and supports are not in the source files: the default atlas's
    let default = default_atlas()?;
    let atlas = Atlas {
        name: req.name.to_string(),
        side,
        mesh: crate::mesh::io::VolumeMesh::from_tets(tets),
        regions,
        materials,
        damping: default.damping,
        supports: default.supports,
        node_sets: BTreeMap::new(),
        surfaces: BTreeMap::new(),
        landmarks: tied,
        provenance,
    };
    validate(&atlas, req.dir)?;
    Ok(atlas)
}
