//! The package manifest (`manifest.json`, format `otoatlas-package` version 1; fields in
//! docs/package-format.md): what the package was made from (otoatlas version, atlas, hashed
//! series UID, hashed inputs, the whole configuration and its hash), its units, the
//! `atlas_to_patient` transform, a registration summary, the mesh counts, and the SHA-256 of
//! every other file. Nothing in it depends on the time, the machine or a path.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::ExportError;
use crate::atlas::Atlas;
use crate::atlas::format::manifest_string;
use crate::config::Config;
use crate::ear::Side;
use crate::image::dicom::patient::PatientIdentity;
use crate::io_util::sha256_hex;
use crate::mechanics::{Condition, Ossicles, Validation};
use crate::mesh::io::vtu::{VtuEncoding, vtu_string};
use crate::register::rigid::SimilarityTransform;

/// The format name in every package manifest.
pub const FORMAT: &str = "otoatlas-package";
/// The format version this build writes and verifies.
pub const VERSION: u32 = 1;
/// The manifest's file name in a package.
pub const MANIFEST: &str = "manifest.json";

/// The units of every number in the package.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Units {
    /// Positions and lengths (mm), in `coordinates`.
    pub length: String,
    pub coordinates: String,
    /// The scene's consistent system.
    pub scene: String,
    /// The materials of atlas.json and the cell arrays of mesh.vtu, as the atlas gives them.
    pub materials: String,
}

impl Units {
    pub fn ours() -> Units {
        Units {
            length: "mm".into(),
            coordinates: "DICOM patient space (LPS)".into(),
            scene: "mm-g-s: force uN, Young's modulus and pressure Pa, mass g, spring stiffness \
                    uN/mm, damping g/s, time s"
                .into(),
            materials: "SI as named: density kg/m^3, Young's modulus Pa, thickness mm".into(),
        }
    }
}

/// The atlas the package was registered from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AtlasRef {
    pub name: String,
    /// See [`atlas_sha256`].
    pub sha256: String,
}

/// How the registration went (deterministic facts only; timings are in the log).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Registration {
    /// Landmark RMS after the rigid (similarity) fit \[mm\].
    pub landmark_rms_mm: f64,
    pub landmark_residuals_mm: Vec<f64>,
    /// The isotropic scale of `atlas_to_patient`.
    pub scale: f64,
    /// The FEM levels of the deformable stage: "converged", "max_iterations" (expected when
    /// the surface level follows) or "inversion_guard".
    pub deform_status: String,
    pub deform_iterations: u64,
    /// Why the surface level stopped ("plateau", "rounds", "element_guard", "nothing_found",
    /// "factorisation"); absent when it was off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_stop: Option<String>,
    /// Its rounds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_rounds: Option<u64>,
}

/// Sizes of the registered mesh (equal in mesh.msh, mesh.vtu and the scene).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshCounts {
    pub nodes: usize,
    pub tetrahedra: usize,
    pub triangles: usize,
}

/// The mechanical verdict of a package against its atlas (docs/mechanics.md), with the
/// figures it was given on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicsSummary {
    /// Every gate passed.
    pub passed: bool,
    /// Gates checked.
    pub gates: usize,
    /// The failed gates, each "name = value unit, expected [low, high]".
    pub failed: Vec<String>,
    /// The stapes velocity transfer function: [Hz, µm/s/Pa, degrees] per frequency.
    pub transfer_function: Vec<[f64; 3]>,
    /// Umbo displacement under static pressure: [Pa, µm]; empty when not computed.
    pub static_pressure: Vec<[f64; 2]>,
    /// The ossicles' model of both checks (rigid bodies since 2026-11-28; elastic before,
    /// which a manifest without the field means).
    #[serde(default)]
    pub ossicles: Ossicles,
}

impl MechanicsSummary {
    pub fn of(v: &Validation) -> MechanicsSummary {
        let m = &v.mechanics;
        MechanicsSummary {
            passed: v.verdict.passed,
            gates: v.verdict.gates.len(),
            failed: v
                .verdict
                .failures()
                .map(|g| {
                    format!(
                        "{} = {:.3} {}, expected [{}, {}]",
                        g.name, g.value, g.unit, g.low, g.high
                    )
                })
                .collect(),
            transfer_function: m
                .transfer_function
                .points
                .iter()
                .map(|p| [p.frequency_hz, p.magnitude_um_s_per_pa, p.phase_deg])
                .collect(),
            static_pressure: m
                .udsp
                .points
                .iter()
                .map(|p| [p.pressure_pa, p.umbo_mm * 1e3])
                .collect(),
            ossicles: m.transfer_function.ossicles,
        }
    }
}

/// The manifest as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    pub version: u32,
    pub otoatlas_version: String,
    pub units: Units,
    /// The SOFA versions the scene is correct on (`sofa::SOFA_VERSIONS`).
    pub sofa_versions: String,
    pub side: Side,
    /// The atlas as the package holds it (`atlas.json`, the scene's materials): the source
    /// atlas under `condition`.
    pub atlas: AtlasRef,
    /// The ear's condition the package models (`run --condition`); absent for a normal ear.
    #[serde(default, skip_serializing_if = "Condition::is_normal")]
    pub condition: Condition,
    /// SHA-256 of the DICOM SeriesInstanceUID (None for NIfTI input); never the UID.
    pub series_uid_sha256: Option<String>,
    /// SHA-256 over the case's input files (image, landmark file, segmentation), as `run`
    /// computes it for batch resume.
    pub inputs_sha256: String,
    /// [`Config::sha256`] of `config`.
    pub config_sha256: String,
    pub config: Config,
    /// x_patient = scale · R · x_atlas + t (LPS mm).
    pub atlas_to_patient: SimilarityTransform,
    /// The same as a 4x4 matrix, row-major.
    pub atlas_to_patient_matrix4: Vec<f64>,
    pub registration: Registration,
    pub mesh: MeshCounts,
    /// The package's mechanical validation against its atlas, when `[validate]` ran it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mechanics: Option<MechanicsSummary>,
    /// The DICOM patient fields: only with `run --keep-phi`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patient: Option<PatientIdentity>,
    /// SHA-256 of every other file of the package, by path relative to it (`/` separated).
    pub files: BTreeMap<String, String>,
}

impl Manifest {
    /// The manifest text: pretty JSON, fields in declaration order, maps sorted.
    pub fn to_json(&self) -> Result<String, ExportError> {
        serde_json::to_string_pretty(self)
            .map(|s| s + "\n")
            .map_err(|e| ExportError::Serialise {
                path: MANIFEST.into(),
                message: e.to_string(),
            })
    }
}

/// SHA-256 of the atlas as the run used it (mirrored to the case's side), over its canonical
/// files: `atlas.json` and `mesh.vtu` exactly as `otoatlas atlas export`/`write_atlas` writes
/// them. The same atlas gives the same digest whatever folder it was read from.
pub fn atlas_sha256(atlas: &Atlas) -> Result<String, ExportError> {
    let manifest = manifest_string(atlas)?;
    let mesh =
        vtu_string(&atlas.mesh, &[], VtuEncoding::Base64).map_err(|e| ExportError::Materials {
            atlas: atlas.name.clone(),
            message: e.to_string(),
        })?;
    Ok(sha256_hex(format!("{manifest}{mesh}").as_bytes()))
}
