//! The parts of a case's `metrics.json` (as `run` writes it) that the reports read, typed:
//! the per-structure surface distances of the rigid fit and of the registration, the
//! deformable stage's status and convergence history, and the landmark checks' warnings. Also the registration targets the
//! reports compare against (mechanics-metrics.md §0.2, "proposed registration targets":
//! MASD ≤ 0.2 mm and HD95 ≤ 0.5 mm per ossicle).

use std::collections::BTreeMap;

use serde::Deserialize;
use serde_json::Value;

use super::error::ReportError;
use crate::atlas::Part;
use crate::meshdev::SurfaceDistances;
use crate::register::landmarks::LandmarkWarning;
use crate::register::refine::Refinement;

/// Target MASD per ossicle \[mm\] (mechanics-metrics.md §0.2).
pub const MASD_TARGET_MM: f64 = 0.2;
/// Target HD95 per ossicle \[mm\] (mechanics-metrics.md §0.2).
pub const HD95_TARGET_MM: f64 = 0.5;

/// One structure's scores as `metrics.json` holds them under `scores.NAME`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct StructureMetrics {
    pub registered: SurfaceDistances,
    /// The rigid fit alone (absent when only the registration was scored).
    pub rigid: Option<SurfaceDistances>,
    /// 1 − MASD registered / MASD rigid.
    pub masd_improvement: Option<f64>,
}

impl StructureMetrics {
    /// Whether the registered surface meets both targets.
    pub fn meets_targets(&self) -> bool {
        self.registered.masd <= MASD_TARGET_MM && self.registered.hd95 <= HD95_TARGET_MM
    }
}

fn parse<T: serde::de::DeserializeOwned>(
    value: &Value,
    case: &str,
    field: &str,
    expected: &'static str,
) -> Result<T, ReportError> {
    T::deserialize(value).map_err(|e| ReportError::Metrics {
        case: case.to_string(),
        field: field.to_string(),
        expected,
        message: e.to_string(),
    })
}

/// The `scores` object of `metrics.json` (also the score stage's artefact), by structure.
pub fn parse_scores(
    scores: &Value,
    case: &str,
) -> Result<BTreeMap<String, StructureMetrics>, ReportError> {
    parse(
        scores,
        case,
        "scores",
        "an object of per-structure {registered, rigid, masd_improvement} surface distances",
    )
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

/// One iteration of the deformable stage's history.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct Iteration {
    pub iteration: usize,
    pub mean_offset_mm: f64,
    pub p99_update_mm: f64,
}

#[derive(Deserialize)]
struct Status {
    status: String,
    message: Option<String>,
    reason: Option<String>,
    mean_offset_mm: Option<f64>,
}

#[derive(Deserialize)]
struct DeformDocument {
    status: Status,
    history: Vec<Iteration>,
    #[serde(default)]
    refinement: Option<Refinement>,
}

/// The deformable stage as its artefact (and `metrics.json`'s `deform`) records it.
#[derive(Debug, Clone, PartialEq)]
pub struct DeformSummary {
    /// "converged", "max_iterations" or "inversion_guard", with the guard's message.
    pub status: String,
    pub message: Option<String>,
    /// Why a converged stage stopped ("plateau" or "balance") and its last mean border offset
    /// \[mm\] (absent in records made before the stop reason was recorded).
    pub reason: Option<String>,
    pub mean_offset_mm: Option<f64>,
    pub history: Vec<Iteration>,
    /// The surface level after the FEM levels (absent when it was off, or in records made
    /// before it existed).
    pub refinement: Option<Refinement>,
}

/// Reads the deformable stage's record.
pub fn parse_deform(deform: &Value, case: &str) -> Result<DeformSummary, ReportError> {
    let doc: DeformDocument = parse(
        deform,
        case,
        "deform",
        "the deformable stage's record {status: {status}, history: [...]}",
    )?;
    Ok(DeformSummary {
        status: doc.status.status,
        message: doc.status.message,
        reason: doc.status.reason,
        mean_offset_mm: doc.status.mean_offset_mm,
        history: doc.history,
        refinement: doc.refinement,
    })
}

/// The landmark checks' warnings as `metrics.json` holds them under `landmark_warnings` (each
/// with its `kind`, its figures and a `message`); none when the field is absent (a run before
/// the checks warned).
pub fn parse_landmark_warnings(
    metrics: &Value,
    case: &str,
) -> Result<Vec<LandmarkWarning>, ReportError> {
    match metrics.get("landmark_warnings") {
        None | Some(Value::Null) => Ok(Vec::new()),
        Some(w) => parse(
            w,
            case,
            "landmark_warnings",
            "a list of {kind, ...figures, message} landmark warnings",
        ),
    }
}

/// Hand-made surface distances for the reports' tests: every field a different number
/// (ASSD, RMS and the MeshDev mean are MASD + 0.001, 0.002, 0.003; HD and the MeshDev max are
/// HD95 + 0.3 and + 0.4).
#[cfg(test)]
pub(crate) fn distances_json(masd: f64, hd95: f64, bias: f64, dice: f64) -> Value {
    let directed = serde_json::json!({"samples": 10, "area_mm2": 5.0, "mean": masd,
        "rms": masd, "max": hd95 + 0.3, "p95": hd95, "within_tolerance_mm2": 5.0 * dice});
    serde_json::json!({"masd": masd, "assd": masd + 0.001, "rms": masd + 0.002,
        "hd": hd95 + 0.3, "hd95": hd95, "bias": bias, "surface_dice": dice,
        "mean_test_to_ref": masd, "mean_ref_to_test": masd, "meshdev_mean": masd + 0.003,
        "meshdev_max": hd95 + 0.4, "tolerance_mm": 0.25, "test_to_ref": directed,
        "ref_to_test": directed})
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn reads_the_deform_record_and_names_a_bad_scores_field() {
        let deform = json!({
            "status": {"status": "inversion_guard", "message": "step refused"},
            "iterations": 1,
            "history": [{"iteration": 1, "mean_offset_mm": 0.2, "p99_update_mm": 0.1,
                         "borders_found": 3, "max_update_mm": 0.3}],
        });
        let d = parse_deform(&deform, "c1").unwrap();
        assert_eq!(d.status, "inversion_guard");
        assert_eq!(d.message.as_deref(), Some("step refused"));
        assert_eq!(d.history[0].p99_update_mm, 0.1);
        let warnings = json!({"landmark_warnings": [{"kind": "flat_triangle", "height_mm": 1.2,
            "typical_min_mm": 1.5, "atlas_height_mm": 3.27, "message": "flat"}]});
        assert_eq!(
            parse_landmark_warnings(&warnings, "c1").unwrap(),
            [LandmarkWarning::FlatTriangle {
                height_mm: 1.2,
                typical_min_mm: 1.5,
                atlas_height_mm: Some(3.27)
            }]
        );
        assert_eq!(parse_landmark_warnings(&json!({}), "c1").unwrap(), []);
        let bad = json!({"landmark_warnings": [{"kind": "no_such_warning"}]});
        let text = parse_landmark_warnings(&bad, "c1").unwrap_err().to_string();
        assert!(text.contains("landmark_warnings"), "{text}");
        let err = parse_scores(&json!({"malleus": {"registered": 3}}), "c1").unwrap_err();
        let text = err.to_string();
        assert!(text.contains("c1") && text.contains("scores"), "{text}");
    }
}
