//! The top of the case report: the verdicts a reader checks first (did the deformable stage
//! converge, do the ossicles meet the registration targets of docs/metrics.md) and
//! the case summary: image geometry, side and its source, atlas, landmark residuals of the
//! rigid fit and the landmark checks' warnings, rigid scale, deformable status and the time of each stage.

use std::collections::BTreeMap;

use super::{CaseReportInput, mm};
use crate::atlas::Part;
use crate::ear::LandmarkName;
use crate::mechanics::Condition;
use crate::register::auto_landmarks::describe_poses_tried;
use crate::register::refine::{RefineStop, Refinement};
use crate::report::html::Page;
use crate::report::metrics::{DeformSummary, HD95_TARGET_MM, MASD_TARGET_MM, StructureMetrics};

/// The one-line verdicts a reader checks first.
pub(super) fn verdict(
    page: &mut Page,
    deform: &DeformSummary,
    scores: Option<&BTreeMap<String, StructureMetrics>>,
) {
    page.heading("Verdict");
    match &deform.refinement {
        Some(refinement) => refined_verdict(page, deform, refinement),
        None => fem_verdict(page, deform),
    }
    let Some(scores) = scores else {
        page.paragraph(
            "No manual segmentation: accuracy cannot be measured; judge the overlays.",
            Some("note"),
        );
        return;
    };
    let bones: Vec<(&str, &StructureMetrics)> = Part::BONES
        .iter()
        .filter_map(|p| scores.get(p.name()).map(|s| (p.name(), s)))
        .collect();
    let missed: Vec<&str> = bones
        .iter()
        .filter(|(_, s)| !s.meets_targets())
        .map(|(n, _)| *n)
        .collect();
    let targets = format!("MASD ≤ {MASD_TARGET_MM} mm and HD95 ≤ {HD95_TARGET_MM} mm");
    if missed.is_empty() {
        page.paragraph(
            &format!(
                "All {} scored ossicles meet the targets ({targets}).",
                bones.len()
            ),
            Some("ok"),
        );
    } else {
        page.paragraph(
            &format!("Missing the targets ({targets}): {}.", missed.join(", ")),
            Some("bad"),
        );
    }
}

/// The verdict on the FEM levels when they end the stage (the surface level off).
fn fem_verdict(page: &mut Page, deform: &DeformSummary) {
    match deform.status.as_str() {
        "converged" => {
            let why = match (deform.reason.as_deref(), deform.mean_offset_mm) {
                (Some("plateau"), Some(o)) => format!(
                    " (stop: the mean distance to the bone borders stopped falling, at {o:.3} mm)"
                ),
                (Some("balance"), Some(o)) => format!(
                    " (stop: the FEM and the springs balance, {o:.3} mm on average from the bone borders)"
                ),
                _ => String::new(),
            };
            page.paragraph(
                &format!("The deformable registration converged{why}."),
                Some("ok"),
            )
        }
        other => page.paragraph(
            &format!(
                "The deformable registration did not converge ({other}{}): check the overlays.",
                guard_message(deform)
            ),
            Some("bad"),
        ),
    };
}

/// The verdict when the surface level ends the stage: its stop decides; the FEM levels before
/// it are coarse by design (their iteration limit is no failure), but an element their guard
/// stopped at is worth a look.
fn refined_verdict(page: &mut Page, deform: &DeformSummary, r: &Refinement) {
    let offsets = match (r.mean_offset_first_mm, r.mean_offset_last_mm) {
        (Some(first), Some(last)) => {
            format!(", mean distance to the bone borders {first:.3} → {last:.3} mm")
        }
        _ => String::new(),
    };
    let levels = format!(
        "the FEM levels ({} iterations) then the surface level ({} rounds{offsets})",
        deform.history.len(),
        r.rounds
    );
    let (text, class) = match r.stop {
        RefineStop::Plateau => (
            format!(
                "The deformable registration converged: {levels}; stop: the distance stopped falling."
            ),
            "ok",
        ),
        RefineStop::Rounds => (
            format!(
                "The deformable registration reached the surface level's round limit: {levels}; the distance was still falling."
            ),
            "note",
        ),
        RefineStop::ElementGuard => (
            format!(
                "The deformable registration stopped where a further move would flatten an element: {levels}. Check the overlays."
            ),
            "note",
        ),
        RefineStop::NothingFound => (
            format!(
                "The surface level found no bone border around the registered atlas: {levels}. Check the overlays."
            ),
            "bad",
        ),
        RefineStop::Factorisation => (
            format!(
                "The surface level could not solve its smoothing system (out of memory?): {levels}. Check the overlays."
            ),
            "bad",
        ),
    };
    page.paragraph(&text, Some(class));
    if deform.status == "inversion_guard" {
        page.paragraph(
            &format!(
                "The FEM levels stopped at their last valid state{}.",
                guard_message(deform)
            ),
            Some("note"),
        );
    }
}

/// The FEM guard's message as ": message", or nothing.
fn guard_message(deform: &DeformSummary) -> String {
    deform
        .message
        .as_deref()
        .map(|m| format!(": {m}"))
        .unwrap_or_default()
}

/// The direction each voxel axis points to, as LPS letters (e.g. "LPS"), "oblique" marked.
fn orientation_code(direction: &nalgebra::Matrix3<f64>) -> String {
    let mut code = String::new();
    let mut oblique = false;
    for col in direction.column_iter() {
        let (axis, v) = (0..3)
            .map(|a| (a, col[a]))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap_or((0, 0.0));
        oblique |= v.abs() < 0.999;
        let letters = [("L", "R"), ("P", "A"), ("S", "I")][axis];
        code.push_str(if v >= 0.0 { letters.0 } else { letters.1 });
    }
    if oblique {
        code.push_str(" (oblique)");
    }
    code
}

pub(super) fn summary(page: &mut Page, input: &CaseReportInput, deform: &DeformSummary) {
    let v = &input.image.volume;
    let [nx, ny, nz] = v.dims;
    let [sx, sy, sz] = v.spacing;
    let d = v.direction_row_major();
    let rows = [
        (
            "image",
            format!(
                "{} ({})",
                input.image.info.format, input.image.info.modality
            ),
        ),
        ("voxels", format!("{nx} × {ny} × {nz}")),
        ("spacing (mm)", format!("{sx:.3} × {sy:.3} × {sz:.3}")),
        (
            "field of view (mm)",
            format!(
                "{:.1} × {:.1} × {:.1}",
                nx as f64 * sx,
                ny as f64 * sy,
                nz as f64 * sz
            ),
        ),
        (
            "voxel axes i, j, k point to",
            orientation_code(&v.direction),
        ),
        (
            "direction (rows, LPS)",
            format!(
                "[{:.3} {:.3} {:.3}; {:.3} {:.3} {:.3}; {:.3} {:.3} {:.3}]",
                d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8]
            ),
        ),
        (
            "origin (LPS mm)",
            format!("{:.2}, {:.2}, {:.2}", v.origin.x, v.origin.y, v.origin.z),
        ),
        (
            "side",
            format!("{} (from the {})", input.side.as_str(), input.side_source),
        ),
        (
            "atlas",
            match input.condition {
                Condition::Normal => input.atlas.name.clone(),
                c => format!(
                    "{}, materials of {} (run --condition)",
                    input.atlas.name,
                    c.name()
                ),
            },
        ),
        ("rigid scale", format!("{:.4}", input.fit.transform.scale)),
        (
            "deformable stage",
            match &deform.refinement {
                Some(r) => format!(
                    "FEM levels {}, {} iterations; surface level {} rounds, stop {}{}",
                    deform.status,
                    deform.history.len(),
                    r.rounds,
                    r.stop.name(),
                    r.mean_offset_last_mm
                        .map(|o| format!(", {o:.3} mm from the bone borders"))
                        .unwrap_or_default()
                ),
                None => format!("{}, {} iterations", deform.status, deform.history.len()),
            },
        ),
        (
            "surface on a bone edge",
            match deform.edge_support.as_slice() {
                [] => "not recorded".into(),
                supports => supports
                    .iter()
                    .map(|s| format!("{} {:.0} %", s.part.name(), 100.0 * s.share))
                    .collect::<Vec<_>>()
                    .join(", "),
            },
        ),
    ];
    page.heading("Case summary").table(
        &["item", "value"],
        &rows.map(|(k, v)| vec![k.to_string(), v]),
    );
    for warning in &input.image.info.warnings {
        page.paragraph(&format!("ingest: {warning}"), Some("note"));
    }
    let mut landmarks: Vec<Vec<String>> = LandmarkName::ALL
        .iter()
        .zip(&input.fit.residuals_mm)
        .enumerate()
        .map(|(k, (n, r))| {
            let mut row = vec![n.key().to_string(), mm(*r)];
            if let Some(proposed) = &input.proposed {
                row.push(format!("{:.2}", proposed.confidence[k]));
            }
            row
        })
        .collect();
    match &input.proposed {
        None => {
            landmarks.push(vec!["RMS".into(), mm(input.fit.rms_mm)]);
            page.table(&["landmark", "rigid-fit residual (mm)"], &landmarks);
        }
        Some(proposed) => {
            landmarks.push(vec!["RMS".into(), mm(input.fit.rms_mm), String::new()]);
            page.paragraph(
                "The landmarks were proposed from the image, not picked: the atlas chain was \
                 searched for over every orientation and both sides, registered, and the \
                 landmarks read off it. A landmark's confidence is the share of the bone \
                 surface within 2 mm of it whose edge the image confirms within a voxel; check \
                 the crosses on the overlays.",
                Some("note"),
            );
            page.table(
                &[
                    "landmark",
                    "rigid-fit residual (mm)",
                    "confidence (proposed)",
                ],
                &landmarks,
            );
            if let Some(line) = describe_poses_tried(&proposed.poses_tried) {
                page.paragraph(&format!("Landmark proposal: {line}."), Some("note"));
            }
        }
    }
    for warning in input.landmark_warnings {
        page.paragraph(
            &format!("{} warning: {warning}", warning.subject()),
            Some("warn"),
        );
    }
    let mut timings: Vec<Vec<String>> = input
        .timings
        .iter()
        .map(|(stage, s)| vec![stage.to_string(), format!("{s:.2}")])
        .collect();
    timings.push(vec!["total".into(), format!("{:.2}", input.total_seconds)]);
    page.table(&["stage", "time (s)"], &timings);
}
