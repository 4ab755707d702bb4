//! The atlas on disk (format `otoatlas-atlas`, version 1; documented in docs/atlas-format.md):
//! a folder with `atlas.json` (the manifest: regions, materials in SI as their sources give
//! them, damping, boundary node sets, load surfaces, landmarks tied to tetrahedra, provenance)
//! and the mesh it names (VTU: tetrahedra and membrane triangles on one node set, the region
//! label as cell data). Everything read is validated before use; every error names the file,
//! the field and what was expected.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::model::{
    Atlas, Damping, MaterialInfo, MeshPoint, Part, RegionInfo, Supports, TiedLandmarks,
    bad_bending_thickness,
};
use crate::ear::{LandmarkName, Side};
use crate::io_util::write_atomic;
use crate::mesh::io::vtu::{VtuEncoding, parse_vtu, vtu_string};
use crate::mesh::io::{MeshIoError, VolumeMesh};
use crate::mesh::tet::signed_volume;

/// The format name in every manifest.
pub const FORMAT: &str = "otoatlas-atlas";
/// The format version this build reads and writes.
pub const VERSION: u32 = 1;
/// The manifest's file name in an atlas folder.
pub const MANIFEST: &str = "atlas.json";
/// The mesh's file name in atlases this build writes.
pub const MESH: &str = "mesh.vtu";

/// Farthest a landmark may lie outside the tetrahedron it is tied to \[mm\].
pub const LANDMARK_TOLERANCE_MM: f64 = 0.5;

/// The embedded default atlas (built by `otoatlas atlas build`, see docs/atlas-format.md).
const DEFAULT_MANIFEST: &str = include_str!("../../assets/atlas/atlas.json");
const DEFAULT_MESH: &str = include_str!("../../assets/atlas/mesh.vtu");

/// An atlas could not be read, written or accepted.
#[derive(Debug, thiserror::Error)]
pub enum AtlasError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {field}: expected {expected}, found {found}")]
    Invalid {
        path: PathBuf,
        field: String,
        expected: String,
        found: String,
    },
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
    #[error(transparent)]
    Build(#[from] super::build::BuildError),
    #[error(transparent)]
    Landmarks(#[from] crate::ear::LandmarkFileError),
}

impl From<crate::io_util::FileError> for AtlasError {
    fn from(crate::io_util::FileError { path, source }: crate::io_util::FileError) -> AtlasError {
        AtlasError::Io { path, source }
    }
}

impl AtlasError {
    pub(crate) fn invalid(
        path: &Path,
        field: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> AtlasError {
        AtlasError::Invalid {
            path: path.to_path_buf(),
            field: field.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
}

/// Units of every number in the atlas.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Units {
    length: String,
    density: String,
    modulus: String,
}

impl Units {
    fn ours() -> Units {
        Units {
            length: "mm".into(),
            density: "kg/m^3".into(),
            modulus: "Pa".into(),
        }
    }
}

/// The manifest as stored.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    format: String,
    version: u32,
    name: String,
    side: Side,
    units: Units,
    /// The mesh file, relative to the manifest.
    mesh: String,
    regions: Vec<RegionInfo>,
    materials: BTreeMap<String, MaterialInfo>,
    damping: Damping,
    supports: Supports,
    node_sets: BTreeMap<String, Vec<u32>>,
    surfaces: BTreeMap<String, Vec<[u32; 3]>>,
    landmarks: TiedLandmarks,
    #[serde(default)]
    provenance: BTreeMap<String, String>,
}

/// The embedded default atlas (a right ear).
pub fn default_atlas() -> Result<Atlas, AtlasError> {
    parse_atlas(
        DEFAULT_MANIFEST,
        Path::new("<embedded atlas>/atlas.json"),
        |_| Ok(DEFAULT_MESH.to_string()),
    )
}

/// The atlas in `dir` (default: the embedded one), mirrored to `side` if it is the other ear.
pub fn load_atlas(dir: Option<&Path>, side: Option<Side>) -> Result<Atlas, AtlasError> {
    let atlas = match dir {
        Some(d) => read_atlas(d)?,
        None => default_atlas()?,
    };
    Ok(match side {
        Some(s) if s != atlas.side => atlas.mirrored(),
        _ => atlas,
    })
}

/// Reads and validates the atlas in folder `dir` (or the manifest file itself).
pub fn read_atlas(dir: &Path) -> Result<Atlas, AtlasError> {
    let manifest_path = if dir.is_dir() {
        dir.join(MANIFEST)
    } else {
        dir.to_path_buf()
    };
    let text = read(&manifest_path)?;
    let folder = manifest_path
        .parent()
        .unwrap_or(Path::new("."))
        .to_path_buf();
    parse_atlas(&text, &manifest_path, |mesh| read(&folder.join(mesh)))
}

fn read(path: &Path) -> Result<String, AtlasError> {
    std::fs::read_to_string(path).map_err(|source| AtlasError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn parse_atlas(
    text: &str,
    path: &Path,
    load_mesh: impl Fn(&str) -> Result<String, AtlasError>,
) -> Result<Atlas, AtlasError> {
    let value: serde_json::Value = serde_json::from_str(text)
        .map_err(|e| AtlasError::invalid(path, "document", "JSON", e.to_string()))?;
    let format = value.get("format").and_then(|v| v.as_str()).unwrap_or("");
    if format != FORMAT {
        return Err(AtlasError::invalid(path, "format", FORMAT, format));
    }
    let version = value.get("version").and_then(|v| v.as_u64()).unwrap_or(0);
    if version != u64::from(VERSION) {
        return Err(AtlasError::invalid(
            path,
            "version",
            format!("{VERSION} (the version this build reads)"),
            version.to_string(),
        ));
    }
    let m: Manifest = serde_json::from_value(value).map_err(|e| {
        AtlasError::invalid(
            path,
            "manifest",
            "an otoatlas atlas manifest",
            e.to_string(),
        )
    })?;
    if m.units != Units::ours() {
        return Err(AtlasError::invalid(
            path,
            "units",
            "length mm, density kg/m^3, modulus Pa",
            format!("{:?}", m.units),
        ));
    }
    let mesh_path = path.parent().unwrap_or(Path::new(".")).join(&m.mesh);
    let (mesh, _) = parse_vtu(&load_mesh(&m.mesh)?, &mesh_path)?;
    let atlas = Atlas {
        name: m.name,
        side: m.side,
        mesh,
        regions: m.regions,
        materials: m.materials,
        damping: m.damping,
        supports: m.supports,
        node_sets: m.node_sets,
        surfaces: m.surfaces,
        landmarks: m.landmarks,
        provenance: m.provenance,
    };
    validate(&atlas, path)?;
    Ok(atlas)
}

/// The manifest text of `atlas` (pretty JSON, keys in a fixed order: deterministic).
pub fn manifest_string(atlas: &Atlas) -> Result<String, AtlasError> {
    let m = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        name: atlas.name.clone(),
        side: atlas.side,
        units: Units::ours(),
        mesh: MESH.into(),
        regions: atlas.regions.clone(),
        materials: atlas.materials.clone(),
        damping: atlas.damping.clone(),
        supports: atlas.supports.clone(),
        node_sets: atlas.node_sets.clone(),
        surfaces: atlas.surfaces.clone(),
        landmarks: atlas.landmarks,
        provenance: atlas.provenance.clone(),
    };
    serde_json::to_string_pretty(&m)
        .map(|s| s + "\n")
        .map_err(|e| {
            AtlasError::invalid(
                Path::new(MANIFEST),
                "manifest",
                "serialisable",
                e.to_string(),
            )
        })
}

/// Writes `atlas` into folder `dir` (created if needed): the mesh first, then the manifest,
/// each atomically, so a reader never sees a manifest without its mesh.
pub fn write_atlas(dir: &Path, atlas: &Atlas) -> Result<(), AtlasError> {
    let path = dir.join(MANIFEST);
    validate(atlas, &path)?;
    std::fs::create_dir_all(dir).map_err(|source| AtlasError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let vtu = vtu_string(&atlas.mesh, &[], VtuEncoding::Base64)
        .map_err(|e| AtlasError::invalid(&dir.join(MESH), "mesh", "a consistent mesh", e))?;
    write_atomic(&dir.join(MESH), vtu.as_bytes())?;
    Ok(write_atomic(&path, manifest_string(atlas)?.as_bytes())?)
}

/// Checks everything a simulation and the registration rely on.
pub fn validate(atlas: &Atlas, path: &Path) -> Result<(), AtlasError> {
    let bad = |field: String, expected: &str, found: String| {
        Err(AtlasError::invalid(path, field, expected, found))
    };
    let mesh: &VolumeMesh = &atlas.mesh;
    if let Err(e) = mesh.check(&[]) {
        return bad("mesh".into(), "a consistent mesh", e);
    }
    let n = mesh.tets.nodes.len();
    // regions: declared once, known material, the right kind of cell, at least one cell
    let mut seen = BTreeMap::new();
    for (k, r) in atlas.regions.iter().enumerate() {
        if seen.insert(r.label, k).is_some() {
            return bad(
                format!("regions[{k}].label"),
                "a label used once",
                r.label.to_string(),
            );
        }
        if !atlas.materials.contains_key(&r.material) {
            return bad(
                format!("regions[{k}].material"),
                "one of the atlas's materials",
                format!("unknown material '{}'", r.material),
            );
        }
        if let Some(h) = r.thickness_mm.filter(|h| !(h.is_finite() && *h > 0.0)) {
            return bad(
                format!("regions[{k}].thickness_mm"),
                "a positive thickness",
                h.to_string(),
            );
        }
        if let Some(h) = bad_bending_thickness(r.bending_thickness_mm, r.thickness_mm) {
            return bad(
                format!("regions[{k}].bending_thickness_mm"),
                "a positive thickness, on a membrane region (one with thickness_mm)",
                h.to_string(),
            );
        }
        if let Some(v) = r
            .shape_volume_mm3
            .filter(|v| !(v.is_finite() && *v > 0.0 && r.thickness_mm.is_none()))
        {
            return bad(
                format!("regions[{k}].shape_volume_mm3"),
                "a positive volume, on a volumetric region (one without thickness_mm)",
                v.to_string(),
            );
        }
    }
    let kind_of =
        |label: u16, membrane: bool, what: &str, index: usize| -> Result<(), AtlasError> {
            match atlas.region(label) {
                None => bad(
                    format!("mesh {what} {index} region"),
                    "a label declared in regions",
                    label.to_string(),
                ),
                Some(r) if r.thickness_mm.is_some() != membrane => bad(
                    format!("mesh {what} {index} region"),
                    if membrane {
                        "a membrane region (with thickness_mm) for a triangle"
                    } else {
                        "a volumetric region (no thickness_mm) for a tetrahedron"
                    },
                    r.name.clone(),
                ),
                Some(_) => Ok(()),
            }
        };
    let mut cells = BTreeMap::<u16, usize>::new();
    for (t, &label) in mesh.tets.regions.iter().enumerate() {
        kind_of(label, false, "tetrahedron", t)?;
        *cells.entry(label).or_default() += 1;
    }
    for (t, &label) in mesh.triangle_regions.iter().enumerate() {
        kind_of(label, true, "triangle", t)?;
        *cells.entry(label).or_default() += 1;
    }
    for r in &atlas.regions {
        if !cells.contains_key(&r.label) {
            return bad(
                format!("region '{}' (label {})", r.name, r.label),
                "at least one element",
                "none in the mesh (missing region)".into(),
            );
        }
    }
    for part in Part::BONES {
        if atlas.labels_of(part).is_empty() {
            return bad(
                "regions".into(),
                "regions for the malleus, the incus and the stapes",
                format!("no region of the {}", part.name()),
            );
        }
    }
    for (name, m) in &atlas.materials {
        let ok = m.density_kg_m3.is_finite()
            && m.density_kg_m3 > 0.0
            && m.youngs_modulus_pa.is_finite()
            && m.youngs_modulus_pa > 0.0
            && m.poisson_ratio > -1.0
            && m.poisson_ratio < 0.5;
        if !ok {
            return bad(
                format!("materials.{name}"),
                "density > 0, Young's modulus > 0, Poisson's ratio in (-1, 0.5)",
                format!("{m:?}"),
            );
        }
    }
    for t in 0..mesh.tets.tets.len() {
        let [a, b, c, d] = mesh.tets.corners(t);
        let v = signed_volume(&a, &b, &c, &d);
        if v.is_nan() || v <= 1e-12 {
            return bad(
                format!("mesh tetrahedron {t}"),
                "a positive volume (no inverted or degenerate element)",
                format!("{v:.3e} mm^3"),
            );
        }
    }
    for (name, set) in &atlas.node_sets {
        if let Some(v) = set.iter().find(|&&v| v as usize >= n) {
            return bad(
                format!("node_sets.{name}"),
                &format!("node indices below {n}"),
                v.to_string(),
            );
        }
    }
    for (name, tris) in &atlas.surfaces {
        if let Some(v) = tris.iter().flatten().find(|&&v| v as usize >= n) {
            return bad(
                format!("surfaces.{name}"),
                &format!("node indices below {n}"),
                v.to_string(),
            );
        }
    }
    for name in LandmarkName::ALL {
        let mp: MeshPoint = atlas.landmarks.get(name);
        let field = format!("landmarks.{}", name.key());
        if mp.tet as usize >= mesh.tets.tets.len() {
            return bad(field, "a tetrahedron of the mesh", mp.tet.to_string());
        }
        let sum: f64 = mp.barycentric.iter().sum();
        if !mp.barycentric.iter().all(|b| b.is_finite()) || (sum - 1.0).abs() > 1e-6 {
            return bad(
                field,
                "barycentric coordinates summing to 1",
                format!("{:?}", mp.barycentric),
            );
        }
        let p = mp.position(&mesh.tets.tets, &mesh.tets.nodes);
        let off = MeshPoint::locate(&mesh.tets, &p).map_or(f64::INFINITY, |(_, d)| d);
        if off > LANDMARK_TOLERANCE_MM {
            return bad(
                field,
                &format!("a point on the mesh (within {LANDMARK_TOLERANCE_MM} mm)"),
                format!("a point {off:.2} mm off the mesh"),
            );
        }
    }
    Ok(())
}
