//! A case's `metrics.json`, typed: `run` writes it from these types and the reports (and
//! `--json`, and the cohort summary) read it through them. Also the registration targets the
//! reports compare against (the project's own targets, docs/metrics.md, "Registration
//! targets": MASD ≤ 0.2 mm and HD95 ≤ 0.5 mm per ossicle).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::atlas::Part;
use crate::ear::{Landmarks, Side};
use crate::image::ImageRecord;
use crate::mechanics::Condition;
use crate::meshdev::{LabelDeviation, SurfaceDistances};
use crate::register::atlas_fit::DeformRecord;
use crate::register::deform::{DeformStatus, IterationStats};
use crate::register::landmarks::LandmarkWarning;
use crate::register::refine::Refinement;
use crate::register::rigid::{RigidFit, SimilarityTransform};
use crate::register::support::EdgeSupport;

/// Target MASD per ossicle \[mm\], about one CBCT voxel (docs/metrics.md).
pub const MASD_TARGET_MM: f64 = 0.2;
/// Target HD95 per ossicle \[mm\] (docs/metrics.md).
pub const HD95_TARGET_MM: f64 = 0.5;

/// A case's `metrics.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseMetrics {
    pub case: String,
    pub side: Side,
    /// Where the side came from ("--side", "landmark file", "DICOM laterality").
    pub side_source: String,
    /// The atlas's name.
    pub atlas: String,
    /// The ear's condition the package models (`run --condition`); absent for a normal ear.
    #[serde(default, skip_serializing_if = "Condition::is_normal")]
    pub condition: Condition,
    pub image: ImageRecord,
    pub landmarks: LandmarkMetrics,
    /// What the landmark checks found unusual but possible.
    #[serde(default)]
    pub landmark_warnings: Vec<WarningRecord>,
    pub rigid: RigidMetrics,
    pub deform: DeformRecord,
    /// Per structure, when the case has a segmentation (the score stage's record).
    pub scores: Option<Scores>,
    /// The package's mechanics against the atlas, when validated.
    pub mechanics: Option<MechanicsOutcome>,
}

/// The score stage's record (`OUT/stages/score.json`, `metrics.json`'s `scores`): each
/// structure's distances by name.
pub type Scores = BTreeMap<String, StructureMetrics>;

/// The patient's landmarks and the registered atlas's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LandmarkMetrics {
    pub patient: LandmarkPoints,
    pub registered: LandmarkPoints,
    /// How the landmarks were proposed from the image (`run --auto-landmarks`, or a batch
    /// case without a landmark file): the chain search's figures and each landmark's support;
    /// absent for picked landmarks.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub proposal: Option<serde_json::Value>,
}

/// Three landmarks as `[x, y, z]` (LPS mm) by name.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LandmarkPoints {
    pub umbo: [f64; 3],
    pub incudomalleolar: [f64; 3],
    pub incudostapedial: [f64; 3],
}

impl From<&Landmarks> for LandmarkPoints {
    fn from(l: &Landmarks) -> LandmarkPoints {
        let xyz = |p: &nalgebra::Point3<f64>| [p.x, p.y, p.z];
        LandmarkPoints {
            umbo: xyz(&l.umbo),
            incudomalleolar: xyz(&l.incudomalleolar),
            incudostapedial: xyz(&l.incudostapedial),
        }
    }
}

/// A landmark warning (its `kind` and figures) with its message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WarningRecord {
    #[serde(flatten)]
    pub warning: LandmarkWarning,
    pub message: String,
}

impl From<&LandmarkWarning> for WarningRecord {
    fn from(w: &LandmarkWarning) -> WarningRecord {
        WarningRecord {
            warning: w.clone(),
            message: w.to_string(),
        }
    }
}

/// The rigid fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidMetrics {
    pub atlas_to_patient: SimilarityTransform,
    pub scale: f64,
    pub residuals_mm: Vec<f64>,
    pub rms_mm: f64,
}

impl From<&RigidFit> for RigidMetrics {
    fn from(fit: &RigidFit) -> RigidMetrics {
        RigidMetrics {
            atlas_to_patient: fit.transform,
            scale: fit.transform.scale,
            residuals_mm: fit.residuals_mm.clone(),
            rms_mm: fit.rms_mm,
        }
    }
}

/// The mechanical verdict in brief (`mechanics.json` holds the whole validation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MechanicsOutcome {
    pub passed: bool,
    /// How many gates were checked.
    pub gates: usize,
    /// The names of the failed gates.
    pub failed: Vec<String>,
}

/// One structure's scores as `metrics.json` holds them under `scores.NAME`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StructureMetrics {
    pub registered: SurfaceDistances,
    /// The rigid fit alone (absent when only the registration was scored).
    pub rigid: Option<SurfaceDistances>,
    /// 1 − MASD registered / MASD rigid.
    pub masd_improvement: Option<f64>,
    /// Where the registered surface's distances lie: its deviation map summed per atlas region
    /// (docs/metrics.md, "Where the distances lie"); empty in records written before it.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub by_region: BTreeMap<String, LabelDeviation>,
    /// The distance beyond which `by_region` counts an area as far: two voxels, the HD95
    /// target \[mm\].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub far_mm: Option<f64>,
}

impl StructureMetrics {
    /// Whether the registered surface meets both targets.
    pub fn meets_targets(&self) -> bool {
        self.registered.masd <= MASD_TARGET_MM && self.registered.hd95 <= HD95_TARGET_MM
    }
}

/// The structures of `scores` in anatomical order (malleus, incus, stapes, eardrum), then any
/// other by name.
pub fn anatomical_order(
    scores: &BTreeMap<String, StructureMetrics>,
) -> Vec<(&str, &StructureMetrics)> {
    let mut out: Vec<(&str, &StructureMetrics)> =
        scores.iter().map(|(n, s)| (n.as_str(), s)).collect();
    out.sort_by_key(|(n, _)| {
        Part::STRUCTURES
            .iter()
            .position(|p| p.name() == *n)
            .unwrap_or(Part::STRUCTURES.len())
    });
    out
}

/// The deformable stage as the reports show it.
#[derive(Debug, Clone, PartialEq)]
pub struct DeformSummary {
    /// "converged", "max_iterations" or "inversion_guard", with the guard's message.
    pub status: String,
    pub message: Option<String>,
    /// Why a converged stage stopped ("plateau" or "balance") and its last mean border offset
    /// \[mm\] (absent in records made before the stop reason was recorded).
    pub reason: Option<String>,
    pub mean_offset_mm: Option<f64>,
    pub history: Vec<IterationStats>,
    /// The surface level after the FEM levels (absent when it was off, or in records made
    /// before it existed).
    pub refinement: Option<Refinement>,
    /// How much of each registered ossicle's surface lies on a bone edge (empty in records
    /// made before it was kept).
    pub edge_support: Vec<EdgeSupport>,
}

impl DeformSummary {
    /// The summary of `record`.
    pub fn of(record: &DeformRecord) -> DeformSummary {
        let (message, reason, mean_offset_mm) = match &record.status {
            DeformStatus::Converged {
                reason,
                mean_offset_mm,
            } => (None, Some(reason.name().to_string()), Some(*mean_offset_mm)),
            DeformStatus::MaxIterations => (None, None, None),
            DeformStatus::InversionGuard { message } => (Some(message.clone()), None, None),
        };
        DeformSummary {
            status: record.status.name().to_string(),
            message,
            reason,
            mean_offset_mm,
            history: record.history.clone(),
            refinement: record.refinement.clone(),
            edge_support: record.edge_support.clone(),
        }
    }
}

/// Hand-made surface distances for the reports' tests: every field a different number
/// (ASSD, RMS and the MeshDev mean are MASD + 0.001, 0.002, 0.003; HD and the MeshDev max are
/// HD95 + 0.3 and + 0.4).
#[cfg(test)]
pub(crate) fn distances_json(masd: f64, hd95: f64, bias: f64, dice: f64) -> serde_json::Value {
    let directed = serde_json::json!({"samples": 10, "area_mm2": 5.0, "mean": masd,
        "rms": masd, "max": hd95 + 0.3, "p95": hd95, "within_tolerance_mm2": 5.0 * dice});
    serde_json::json!({"masd": masd, "assd": masd + 0.001, "rms": masd + 0.002,
        "hd": hd95 + 0.3, "hd95": hd95, "bias": bias, "surface_dice": dice,
        "mean_test_to_ref": masd, "mean_ref_to_test": masd, "meshdev_mean": masd + 0.003,
        "meshdev_max": hd95 + 0.4, "tolerance_mm": 0.25, "test_to_ref": directed,
        "ref_to_test": directed})
}

/// A whole `metrics.json` for the reports' tests: a left ear whose rigid fit is the identity,
/// a deformable stage that converged on a plateau, with `scores` and `mechanics` as given.
#[cfg(test)]
pub(crate) fn case_metrics(
    case: &str,
    scores: serde_json::Value,
    mechanics: serde_json::Value,
) -> CaseMetrics {
    let points = serde_json::json!({"umbo": [0.0, 0.0, 0.0], "incudomalleolar": [1.0, 0.0, 0.0],
        "incudostapedial": [0.0, 1.0, 0.0]});
    serde_json::from_value(serde_json::json!({
        "case": case, "side": "left", "side_source": "landmark file", "atlas": "test",
        "image": {"image": "x", "format": "dicom", "dims": [2, 2, 2], "spacing": [0.2, 0.2, 0.2],
            "origin": [0.0, 0.0, 0.0], "direction": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "laterality": null, "series_uid_sha256": null},
        "landmarks": {"patient": points, "registered": points},
        "landmark_warnings": [],
        "rigid": {"atlas_to_patient": {"rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0]], "translation": [0.0, 0.0, 0.0], "scale": 1.0},
            "scale": 1.0, "residuals_mm": [0.0, 0.0, 0.0], "rms_mm": 0.0},
        "deform": {"articulation": null,
            "status": {"status": "converged", "reason": "plateau", "mean_offset_mm": 0.05},
            "iterations": 1,
            "history": [{"iteration": 1, "borders_found": 3, "borders_used": 3,
                "mean_offset_mm": 0.05, "max_update_mm": 0.01, "p99_update_mm": 0.01,
                "spring_scale": 1.0}],
            "refinement": null,
            "eardrum": {"free_nodes": 0, "found_last_round": 0, "mean_offset_mm": 0.0},
            "probe_step_mm": 0.2},
        "scores": scores,
        "mechanics": mechanics,
    }))
    .unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_warning_record_reads_back_with_its_kind_figures_and_message_in_order() {
        let warning = LandmarkWarning::FlatTriangle {
            height_mm: 1.2,
            typical_min_mm: 1.5,
            atlas_height_mm: Some(3.27),
        };
        let record = WarningRecord::from(&warning);
        let text = serde_json::to_string(&record).unwrap();
        assert!(
            text.starts_with(r#"{"kind":"flat_triangle","height_mm":1.2"#),
            "{text}"
        );
        assert!(
            text.contains(r#","message":""#) && text.ends_with(r#""}"#),
            "{text}"
        );
        let back: WarningRecord = serde_json::from_str(&text).unwrap();
        assert_eq!(back, record);
        let bad = json!({"kind": "no_such_warning", "message": "?"});
        assert!(serde_json::from_value::<WarningRecord>(bad).is_err());
    }

    #[test]
    fn the_summary_of_a_guarded_deform_record_names_the_guard_and_its_message() {
        let deform: DeformRecord = serde_json::from_value(json!({
            "articulation": null,
            "status": {"status": "inversion_guard", "message": "step refused"},
            "iterations": 1,
            "history": [{"iteration": 1, "borders_found": 3, "borders_used": 3,
                         "mean_offset_mm": 0.2, "max_update_mm": 0.3, "p99_update_mm": 0.1,
                         "spring_scale": 1.0}],
            "eardrum": {"free_nodes": 0, "found_last_round": 0, "mean_offset_mm": 0.0},
            "probe_step_mm": 0.2,
        }))
        .unwrap();
        let d = DeformSummary::of(&deform);
        assert_eq!(d.status, "inversion_guard");
        assert_eq!(d.message.as_deref(), Some("step refused"));
        assert_eq!(d.history[0].p99_update_mm, 0.1);
        assert_eq!(d.refinement, None);
    }
}
