//! The per-case report `run` writes as `OUT/report.html`: the page a clinical engineer reads to
//! accept or reject a registration. One self-contained file (charts as inline SVG, slices as
//! inline PNG, no script, no network reference) with, in order: a verdict against the
//! registration targets (docs/metrics.md), the case summary (image geometry, side,
//! atlas, landmark residuals and warnings, rigid scale, deformable status, timings), the surface distances
//! per structure (rigid fit and registration, definitions in docs/metrics.md), the slice overlays, the
//! histograms of signed distances, the convergence curve of the deformable stage, and the
//! package's mechanics against the atlas (verdict, transfer function and static-pressure charts).

use std::collections::BTreeMap;

use nalgebra::Point3;

mod accuracy;
mod mechanics;
mod summary;

use accuracy::{far_regions_table, histograms, metrics_table};
use mechanics::mechanics_section;
use summary::{summary, verdict};

use super::error::ReportError;
use super::html::{Figure, FigureContent, Page};
use super::metrics::{DeformSummary, Scores};
use super::overlay::OUTSIDE_IMAGE;
use super::plot::{AxisSpec, Series, line_chart_svg};
use super::slices::{
    LANDMARK_COLOUR, OverlaySurfaces, REGISTERED_COLOUR, RIGID_COLOUR, SEGMENTATION_COLOUR,
    overlay_figures,
};
use crate::atlas::{Atlas, Part};
use crate::ear::{Landmarks, Side};
use crate::image::{LoadedImage, Sampler};
use crate::mechanics::{Condition, Validation};
use crate::mesh::TriMesh;
use crate::register::atlas_fit::DeformRecord;
use crate::register::auto_landmarks::PoseTried;
use crate::register::landmarks::LandmarkWarning;
use crate::register::rigid::RigidFit;

/// What the accuracy sections can show.
pub enum Accuracy<'a> {
    /// The case has no manual segmentation.
    NoSegmentation,
    /// `run --from` started after the score stage: the scores come from the earlier run's
    /// artefact; the per-vertex deviations and the segmentation's surfaces are not in memory.
    Resumed { scores: &'a Scores },
    /// Scored in this run.
    Scored {
        /// The score stage's record.
        scores: &'a Scores,
        /// Per scored structure: the registered surface that was scored and the signed
        /// distance of each of its vertices \[mm\].
        deviation: BTreeMap<&'a str, (&'a TriMesh, &'a [f64])>,
        /// The segmentation's surfaces by structure name.
        reference: &'a BTreeMap<String, TriMesh>,
    },
}

/// Everything the case report shows.
/// Landmarks proposed from the image, as the report shows them.
pub struct Proposed {
    /// Each landmark's confidence (`LandmarkName::ALL` order).
    pub confidence: [f64; 3],
    /// The chain search's poses registered.
    pub poses_tried: Vec<PoseTried>,
}

pub struct CaseReportInput<'a> {
    pub case_id: &'a str,
    pub image: &'a LoadedImage,
    pub sampler: &'a Sampler<'a>,
    pub side: Side,
    /// Where the side came from ("--side", "landmark file", "DICOM laterality").
    pub side_source: &'a str,
    pub atlas: &'a Atlas,
    /// The ear's condition the package models (`run --condition`).
    pub condition: Condition,
    pub fit: &'a RigidFit,
    /// What the landmark checks found unusual but possible (shown with the landmarks).
    pub landmark_warnings: &'a [LandmarkWarning],
    /// The patient's landmarks (drawn on the overlays).
    pub landmarks: &'a Landmarks,
    /// What the proposal says when the landmarks were proposed from the image; `None` for
    /// picks.
    pub proposed: Option<Proposed>,
    /// Atlas nodes after the rigid fit and after the deformable registration.
    pub rigid_nodes: &'a [Point3<f64>],
    pub registered_nodes: &'a [Point3<f64>],
    /// The deformable stage's record.
    pub deform: &'a DeformRecord,
    pub accuracy: Accuracy<'a>,
    /// The package's mechanical validation against the atlas, when it ran.
    pub mechanics: Option<&'a Validation>,
    /// Seconds per stage run, and the whole run so far.
    pub timings: &'a [(&'a str, f64)],
    pub total_seconds: f64,
}

pub(super) fn mm(v: f64) -> String {
    format!("{v:.3}")
}

fn surfaces(atlas: &Atlas, nodes: &[Point3<f64>]) -> BTreeMap<String, TriMesh> {
    Part::STRUCTURES
        .into_iter()
        .filter(|p| !atlas.labels_of(*p).is_empty())
        .map(|p| (p.name().to_string(), atlas.part_surface(p, nodes)))
        .collect()
}

/// The page as one HTML document.
pub fn case_report_html(input: &CaseReportInput) -> Result<String, ReportError> {
    let deform = DeformSummary::of(input.deform);
    let scores = match &input.accuracy {
        Accuracy::NoSegmentation => None,
        Accuracy::Resumed { scores } | Accuracy::Scored { scores, .. } => Some(*scores),
    };
    let rigid = surfaces(input.atlas, input.rigid_nodes);
    let registered = surfaces(input.atlas, input.registered_nodes);
    let mut page = Page::new(&format!("otoatlas case report: {}", input.case_id));
    verdict(&mut page, &deform, scores);
    let weak_pose = input
        .landmark_warnings
        .iter()
        .filter(|w| w.subject() == "registration")
        .count();
    match (input.landmark_warnings.len() - weak_pose, weak_pose) {
        (0, 0) => &mut page,
        (n, 0) => page.paragraph(
            &format!(
                "The landmarks are unusual but possible ({n} warning{}): see the landmarks in \
                 the case summary and check the picks on the overlays.",
                if n == 1 { "" } else { "s" }
            ),
            Some("warn"),
        ),
        (n, _) => page.paragraph(
            &format!(
                "The registered pose may be wrong ({} warning{}): see the case summary and \
                 check the ossicles on the overlays.",
                n + weak_pose,
                if n + weak_pose == 1 { "" } else { "s" }
            ),
            Some("warn"),
        ),
    };
    if let Some(v) = input.mechanics {
        let failed = v.verdict.failures().count();
        match failed {
            0 => page.paragraph(
                "The package keeps the atlas's mechanics (every gate passes; see the last section).",
                Some("ok"),
            ),
            n => page.paragraph(
                &format!(
                    "{n} mechanical gate{} against the atlas fail{} (see the last section).",
                    if n == 1 { "" } else { "s" },
                    if n == 1 { "s" } else { "" }
                ),
                Some("bad"),
            ),
        };
    }
    summary(&mut page, input, &deform);
    metrics_table(&mut page, input, scores);
    far_regions_table(&mut page, scores);

    page.heading("Slice overlays");
    let reference = match &input.accuracy {
        Accuracy::Scored { reference, .. } => Some(*reference),
        _ => None,
    };
    let mut legend = vec![
        ("atlas after the rigid fit", RIGID_COLOUR),
        ("atlas after the deformable registration", REGISTERED_COLOUR),
        (
            match input.proposed {
                Some(_) => "landmarks proposed from the image (within 1 mm of the slice)",
                None => "landmarks picked (within 1 mm of the slice)",
            },
            LANDMARK_COLOUR,
        ),
    ];
    if reference.is_some() {
        legend.push(("manual segmentation", SEGMENTATION_COLOUR));
    }
    legend.push(("beyond the image (hatched)", OUTSIDE_IMAGE[0]));
    page.legend(&legend);
    match &input.accuracy {
        Accuracy::NoSegmentation => page.paragraph(
            "The case has no manual segmentation: the overlays show the two atlas contours.",
            Some("note"),
        ),
        Accuracy::Resumed { .. } => page.paragraph(
            "This run resumed after the score stage: the segmentation's contours are not \
             drawn (rerun from score to see them).",
            Some("note"),
        ),
        Accuracy::Scored { .. } => &mut page,
    };
    let overlay = OverlaySurfaces {
        rigid: &rigid,
        registered: &registered,
        segmentation: reference,
        landmarks: &input.landmarks.points(),
    };
    for (_, figures) in overlay_figures(input.sampler, &overlay)? {
        page.figures(&figures);
    }

    histograms(&mut page, input);
    convergence(&mut page, &deform);
    mechanics_section(&mut page, input.mechanics);
    Ok(page.finish())
}

fn convergence(page: &mut Page, deform: &DeformSummary) {
    page.heading("Convergence of the deformable registration");
    let offset: Vec<(f64, f64)> = deform
        .history
        .iter()
        .map(|i| (i.iteration as f64, i.mean_offset_mm))
        .collect();
    let update: Vec<(f64, f64)> = deform
        .history
        .iter()
        .map(|i| (i.iteration as f64, i.p99_update_mm))
        .collect();
    let svg = line_chart_svg(
        "deformable registration",
        AxisSpec::counts("iteration"),
        AxisSpec::log("mm"),
        &[
            Series {
                name: "mean border offset",
                points: &offset,
                colour: [200, 30, 30],
            },
            Series {
                name: "99th percentile nodal update",
                points: &update,
                colour: [30, 90, 200],
            },
        ],
    );
    page.figures(&[Figure {
        caption: format!(
            "mean distance from the atlas surface to the image border found by the probes, and \
             the 99th percentile of the nodal updates, per iteration ({}, {} iterations)",
            deform.status,
            deform.history.len()
        ),
        content: FigureContent::Svg(svg),
    }]);
}

#[cfg(test)]
mod tests;
