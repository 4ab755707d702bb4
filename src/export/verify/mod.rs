//! `verify`: checks that a package is whole and consistent — every file re-hashed against the
//! manifest (none missing, none unlisted), the manifest's fields (format, version, units,
//! configuration hash, mesh counts), mesh.msh and mesh.vtu read back and equal, no inverted,
//! flattened or collapsed tetrahedron (`elements`), atlas.json valid over mesh.vtu, and the
//! SOFA scene's components and vectors against the mesh (`verify_scene`). Every fault is
//! collected, not just the first.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

mod bending;
mod elements;
mod faults;
mod scene;
mod xml;

use super::ExportError;
use super::digest::package_listing;
use super::manifest::{FORMAT, MANIFEST, Manifest, MeshCounts, Units, VERSION, atlas_sha256};
use super::scene::{SCENE, SCENE_MESH};
use super::sofa::SOFA_VERSIONS;
use crate::atlas::Atlas;
use crate::atlas::format::{
    MANIFEST as ATLAS_MANIFEST, MESH as ATLAS_MESH, default_atlas, read_atlas,
};
use crate::io_util::read_text;
use crate::mesh::io::VolumeMesh;
use crate::mesh::io::gmsh::read_msh;
use crate::mesh::io::vtu::read_vtu;
pub use elements::{ElementQuality, MIN_SHAPE_QUALITY, MIN_VOLUME_RATIO};
use elements::{Reference, check_orientation, check_quality};
pub use faults::Fault;
use faults::Faults;
use scene::check_scene;

/// Files every package has (besides the manifest).
pub const REQUIRED_FILES: [&str; 7] = [
    SCENE,
    SCENE_MESH,
    ATLAS_MESH,
    ATLAS_MANIFEST,
    "landmarks.fcsv",
    "landmarks.mrk.json",
    "landmarks.json",
];

/// What `verify` found.
#[derive(Debug, Clone, PartialEq)]
pub struct VerifyReport {
    pub package: PathBuf,
    /// The manifest, when it could be read.
    pub manifest: Option<Manifest>,
    /// The package's atlas (atlas.json with mesh.vtu), when it could be read.
    pub atlas: Option<Atlas>,
    /// Files whose hash was compared.
    pub files_checked: usize,
    /// The worst tetrahedra of mesh.msh, when it could be read.
    pub elements: Option<ElementQuality>,
    pub faults: Vec<Fault>,
}

impl VerifyReport {
    /// No fault found.
    pub fn passed(&self) -> bool {
        self.faults.is_empty()
    }

    pub fn to_json(&self) -> Value {
        json!({
            "package": self.package,
            "passed": self.passed(),
            "files_checked": self.files_checked,
            "elements": self.elements,
            "mesh": self.manifest.as_ref().map(|m| m.mesh),
            "inputs_sha256": self.manifest.as_ref().map(|m| &m.inputs_sha256),
            "config_sha256": self.manifest.as_ref().map(|m| &m.config_sha256),
            "faults": self.faults,
        })
    }

    pub fn text(&self) -> String {
        let mut s = format!("package {}: ", self.package.display());
        if self.passed() {
            let m = self.manifest.as_ref().map(|m| m.mesh);
            s.push_str(&format!(
                "ok: {} files match their SHA-256; {} nodes, {} tetrahedra (none inverted), {} \
                 triangles; the scene's vectors match the mesh\n",
                self.files_checked,
                m.map_or(0, |m| m.nodes),
                m.map_or(0, |m| m.tetrahedra),
                m.map_or(0, |m| m.triangles)
            ));
            if let Some(e) = &self.elements {
                s.push_str(&format!(
                    "  least shape quality {:.3} (bound {MIN_SHAPE_QUALITY}); ",
                    e.min_shape_quality
                ));
                s.push_str(&e.min_volume_ratio.map_or_else(
                    || {
                        "volume ratios to the atlas not checked: the manifest's atlas is not the \
                         embedded one (give it with --atlas)\n"
                            .to_string()
                    },
                    |r| {
                        format!(
                            "least volume ratio to the atlas {r:.3} (bound {MIN_VOLUME_RATIO})\n"
                        )
                    },
                ));
            }
        } else {
            s.push_str(&format!("{} fault(s)\n", self.faults.len()));
            for f in &self.faults {
                s.push_str(&format!("  {:<12} {}: {}\n", f.check, f.file, f.message));
            }
        }
        s
    }
}

/// Verifies the package at `dir`, comparing its tetrahedra's volumes with the embedded atlas's
/// when the package was registered from it. `Err` only when `dir` is not a readable folder;
/// every problem inside it is a fault of the report.
pub fn verify_package(dir: &Path) -> Result<VerifyReport, ExportError> {
    verify_package_against(dir, None)
}

/// [`verify_package`], with the atlas the package was registered from (either side: it is
/// mirrored to the package's). An atlas that is not the one the manifest names is a fault.
pub fn verify_package_against(
    dir: &Path,
    atlas: Option<&Atlas>,
) -> Result<VerifyReport, ExportError> {
    if !dir.is_dir() {
        return Err(ExportError::NotAPackage {
            path: dir.to_path_buf(),
            manifest: MANIFEST,
        });
    }
    let listing = package_listing(dir)?;
    let actual = listing.files;
    let mut faults = Faults::default();
    for (name, kind) in &listing.others {
        let target = std::fs::read_link(dir.join(name))
            .map(|t| format!(" to {}", t.display()))
            .unwrap_or_default();
        faults.add(
            "special",
            name,
            format!("a {kind}{target}, not a regular file: a package holds only files and folders"),
        );
    }
    let manifest = if actual.contains_key(MANIFEST) {
        read_manifest(dir, &mut faults)
    } else {
        faults.add("manifest", MANIFEST, "absent, or not a regular file");
        None
    };
    let mut report = VerifyReport {
        package: dir.to_path_buf(),
        manifest: manifest.clone(),
        atlas: None,
        files_checked: 0,
        elements: None,
        faults: Vec::new(),
    };
    if let Some(m) = &manifest {
        report.files_checked = check_files(m, &actual, &mut faults);
        check_fields(m, &mut faults);
        let source = source_atlas(m, atlas, &mut faults);
        let reference = source.as_ref().map(|atlas| Reference {
            atlas,
            scale: m.atlas_to_patient.scale,
        });
        (report.atlas, report.elements) =
            check_content(dir, m, &actual, reference.as_ref(), &mut faults);
    }
    report.faults = faults.0;
    Ok(report)
}

fn read_manifest(dir: &Path, faults: &mut Faults) -> Option<Manifest> {
    let text = match read_text(&dir.join(MANIFEST)) {
        Ok(t) => t,
        Err(e) => {
            faults.add("manifest", MANIFEST, format!("cannot be read: {e}"));
            return None;
        }
    };
    let value: Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => {
            faults.add("manifest", MANIFEST, format!("not JSON: {e}"));
            return None;
        }
    };
    let (format, version) = (&value["format"], &value["version"]);
    if format != FORMAT || version != VERSION {
        faults.add(
            "manifest",
            MANIFEST,
            format!("format {format} version {version}, expected \"{FORMAT}\" version {VERSION}"),
        );
        return None;
    }
    serde_json::from_value(value)
        .map_err(|e| faults.add("manifest", MANIFEST, format!("not a package manifest: {e}")))
        .ok()
}

/// Re-hashes the files; returns how many listed files were compared.
fn check_files(m: &Manifest, actual: &Files, faults: &mut Faults) -> usize {
    let mut checked = 0;
    for (name, want) in &m.files {
        match actual.get(name) {
            None => faults.add("missing", name, "listed in the manifest but absent"),
            Some(got) if got != want => faults.add(
                "hash",
                name,
                format!("SHA-256 {got} differs from the manifest's {want}: the file changed"),
            ),
            Some(_) => {}
        }
        checked += 1;
    }
    for name in actual.keys() {
        if name != MANIFEST && !m.files.contains_key(name) {
            faults.add("unlisted", name, "not listed in the manifest");
        }
    }
    for name in REQUIRED_FILES {
        if !m.files.contains_key(name) {
            faults.add(
                "manifest",
                name,
                "a package file the manifest does not list",
            );
        }
    }
    checked
}

fn check_fields(m: &Manifest, faults: &mut Faults) {
    if m.sofa_versions != SOFA_VERSIONS {
        faults.add(
            "manifest",
            MANIFEST,
            format!(
                "sofa_versions '{}', expected '{SOFA_VERSIONS}'",
                m.sofa_versions
            ),
        );
    }
    if m.units != Units::ours() {
        faults.add(
            "manifest",
            MANIFEST,
            format!("units {:?}, expected {:?}", m.units, Units::ours()),
        );
    }
    if m.config.sha256() != m.config_sha256 {
        faults.add(
            "manifest",
            MANIFEST,
            format!(
                "config_sha256 {} is not the hash of its config ({})",
                m.config_sha256,
                m.config.sha256()
            ),
        );
    }
    let hex64 = |s: &str| s.len() == 64 && s.bytes().all(|b| b.is_ascii_hexdigit());
    let digests = [
        ("inputs_sha256", Some(m.inputs_sha256.as_str())),
        ("atlas.sha256", Some(m.atlas.sha256.as_str())),
        ("series_uid_sha256", m.series_uid_sha256.as_deref()),
    ];
    for (field, value) in digests {
        if let Some(v) = value.filter(|v| !hex64(v)) {
            faults.add(
                "manifest",
                MANIFEST,
                format!("{field} '{v}' is not a SHA-256"),
            );
        }
    }
    if m.atlas_to_patient_matrix4.len() != 16
        || !m.atlas_to_patient.scale.is_finite()
        || m.atlas_to_patient.scale <= 0.0
    {
        faults.add(
            "manifest",
            MANIFEST,
            "atlas_to_patient: expected a positive scale and a 4x4 matrix (16 numbers)",
        );
    }
}

/// Counts of a mesh against the manifest.
fn check_counts(mesh: &VolumeMesh, want: MeshCounts, file: &str, faults: &mut Faults) {
    let got = MeshCounts {
        nodes: mesh.tets.nodes.len(),
        tetrahedra: mesh.tets.tets.len(),
        triangles: mesh.triangles.len(),
    };
    if got != want {
        faults.add("mesh", file, format!("{got:?}, the manifest says {want:?}"));
    }
}

/// The atlas the package was registered from, mirrored to its side and under the manifest's
/// condition: `given`, which must then be the one the manifest names (a fault otherwise), or
/// the embedded atlas when it is that one.
fn source_atlas(m: &Manifest, given: Option<&Atlas>, faults: &mut Faults) -> Option<Atlas> {
    let atlas = match given {
        Some(a) => a.clone(),
        None => default_atlas().ok()?,
    };
    let atlas = if atlas.side == m.side {
        atlas
    } else {
        atlas.mirrored()
    };
    // a package of a pathology holds the source atlas under its condition
    let atlas = m.condition.apply(&atlas).ok()?;
    let digest = atlas_sha256(&atlas).ok()?;
    if digest == m.atlas.sha256 {
        return Some(atlas);
    }
    if given.is_some() {
        faults.add(
            "quality",
            MANIFEST,
            format!(
                "the package was registered from atlas '{}' (SHA-256 {}), the atlas given is \
                 '{}' (SHA-256 {digest})",
                m.atlas.name, m.atlas.sha256, atlas.name
            ),
        );
    }
    None
}

/// Bytes a file read whole may have per node and element the manifest counts, and besides.
const BYTES_PER_ITEM: u64 = 256;
const BYTES_BESIDES: u64 = 1 << 20;

/// Whether the package file `name` may be read whole: a regular file (links and special
/// files are faults of their own and never opened) no larger than its manifest's counts
/// allow, so that a huge or endless file is refused before it is read.
fn readable(dir: &Path, name: &str, m: &Manifest, files: &Files, faults: &mut Faults) -> bool {
    if !files.contains_key(name) {
        return false;
    }
    let counts = (m.mesh.nodes + m.mesh.tetrahedra + m.mesh.triangles) as u64;
    let limit = counts
        .saturating_mul(BYTES_PER_ITEM)
        .saturating_add(BYTES_BESIDES);
    match std::fs::symlink_metadata(dir.join(name)) {
        Ok(meta) if meta.len() <= limit => true,
        Ok(meta) => {
            faults.add(
                "mesh",
                name,
                format!(
                    "{} bytes, more than the {limit} its manifest's counts allow ({} bytes per \
                     node and element, and 1 MiB); not read",
                    meta.len(),
                    BYTES_PER_ITEM
                ),
            );
            false
        }
        Err(_) => false,
    }
}

/// The package's regular files with their SHA-256.
type Files = BTreeMap<String, String>;

/// Checks the meshes, atlas.json and the scene; returns the atlas when it could be read and
/// the worst tetrahedra of the scene's mesh.
fn check_content(
    dir: &Path,
    m: &Manifest,
    files: &Files,
    reference: Option<&Reference>,
    faults: &mut Faults,
) -> (Option<Atlas>, Option<ElementQuality>) {
    let msh = readable(dir, SCENE_MESH, m, files, faults)
        .then(|| read_msh(&dir.join(SCENE_MESH)))
        .and_then(|r| {
            r.map_err(|e| faults.add("mesh", SCENE_MESH, e.to_string()))
                .ok()
        });
    let vtu_ok = readable(dir, ATLAS_MESH, m, files, faults);
    let vtu = vtu_ok
        .then(|| read_vtu(&dir.join(ATLAS_MESH)))
        .and_then(|r| {
            r.map_err(|e| faults.add("mesh", ATLAS_MESH, e.to_string()))
                .ok()
        })
        .map(|(mesh, _)| mesh);
    for (mesh, file) in [(&msh, SCENE_MESH), (&vtu, ATLAS_MESH)] {
        if let Some(mesh) = mesh {
            check_counts(mesh, m.mesh, file, faults);
            check_orientation(mesh, file, faults);
        }
    }
    let elements = msh
        .as_ref()
        .and_then(|mesh| check_quality(mesh, reference, SCENE_MESH, faults));
    if let (Some(a), Some(b)) = (&msh, &vtu)
        && a != b
    {
        faults.add(
            "mesh",
            SCENE_MESH,
            format!("differs from {ATLAS_MESH} (nodes, cells or region labels)"),
        );
    }
    let atlas = (vtu_ok && readable(dir, ATLAS_MANIFEST, m, files, faults))
        .then(|| read_atlas(dir))
        .and_then(|r| {
            r.map_err(|e| faults.add("atlas", ATLAS_MANIFEST, e.to_string()))
                .ok()
        });
    if !readable(dir, SCENE, m, files, faults) {
        return (atlas, elements);
    }
    match std::fs::read_to_string(dir.join(SCENE)) {
        Err(e) => faults.add("scene", SCENE, format!("cannot be read: {e}")),
        Ok(text) => check_scene(&text, msh.as_ref(), atlas.as_ref(), &m.files, faults),
    }
    (atlas, elements)
}
