//! The accuracy sections of the case report: the surface distances per structure for the
//! rigid fit and the registration (definitions in docs/metrics.md, computed by
//! `meshdev`), and the histogram of the registered surface's signed distances per structure.

use std::collections::BTreeMap;

use super::{Accuracy, CaseReportInput, mm};
use crate::atlas::Part;
use crate::meshdev::ColourRange;
use crate::report::html::{Figure, FigureContent, Page};
use crate::report::metrics::{HD95_TARGET_MM, MASD_TARGET_MM, StructureMetrics, anatomical_order};
use crate::report::plot::histogram_svg;

/// Bins of the signed-distance histograms over the deviation maps' fixed colour range.
const HISTOGRAM_BINS: usize = 40;

pub(super) fn metrics_table(
    page: &mut Page,
    input: &CaseReportInput,
    scores: Option<&BTreeMap<String, StructureMetrics>>,
) {
    page.heading("Accuracy against the manual segmentation");
    let Some(scores) = scores else {
        page.paragraph(
            "The case has no manual segmentation: no surface distances.",
            Some("note"),
        );
        return;
    };
    if let Accuracy::Resumed { .. } = input.accuracy {
        page.paragraph(
            "This run resumed after the score stage: the distances below are the earlier \
             run's (stages/score.json).",
            Some("note"),
        );
    }
    let opt = |v: Option<f64>, f: fn(f64) -> String| v.map_or("–".to_string(), f);
    let rows: Vec<Vec<String>> = anatomical_order(scores)
        .into_iter()
        .map(|(name, s)| {
            let (r, g) = (s.rigid.as_ref(), &s.registered);
            let target = match Part::BONES.iter().any(|p| p.name() == name) {
                true if s.meets_targets() => "met",
                true => "missed",
                false => "–",
            };
            vec![
                name.to_string(),
                opt(r.map(|r| r.masd), mm),
                mm(g.masd),
                opt(s.masd_improvement, |i| format!("{:.0} %", 100.0 * i)),
                opt(r.map(|r| r.hd95), mm),
                mm(g.hd95),
                opt(r.map(|r| r.bias), mm),
                mm(g.bias),
                opt(r.map(|r| r.surface_dice), |d| format!("{d:.3}")),
                format!("{:.3}", g.surface_dice),
                mm(g.hd),
                target.to_string(),
            ]
        })
        .collect();
    page.table(
        &[
            "structure",
            "MASD rigid (mm)",
            "MASD registered (mm)",
            "MASD improvement",
            "HD95 rigid (mm)",
            "HD95 registered (mm)",
            "bias rigid (mm)",
            "bias registered (mm)",
            "surface Dice rigid",
            "surface Dice registered",
            "HD registered (mm)",
            "targets",
        ],
        &rows,
    );
    let tolerance = scores
        .values()
        .next()
        .map_or(0.0, |s| s.registered.tolerance_mm);
    page.paragraph(
        &format!(
            "MASD: mean absolute surface distance, both directions; HD95: 95th percentile \
             Hausdorff distance; bias: area-weighted mean signed distance of the atlas surface \
             (positive = atlas outside the segmentation); surface Dice at τ = {tolerance:.3} mm \
             (one voxel). Targets per ossicle: MASD ≤ {MASD_TARGET_MM} mm, HD95 ≤ \
             {HD95_TARGET_MM} mm."
        ),
        Some("note"),
    );
}

pub(super) fn histograms(page: &mut Page, input: &CaseReportInput) {
    page.heading("Signed distances of the registered surfaces");
    let deviation = match &input.accuracy {
        Accuracy::NoSegmentation => {
            page.paragraph(
                "The case has no manual segmentation: no distances.",
                Some("note"),
            );
            return;
        }
        Accuracy::Resumed { .. } => {
            page.paragraph(
                "This run resumed after the score stage: the per-vertex distances are not in \
                 memory; rerun from score to plot them.",
                Some("note"),
            );
            return;
        }
        Accuracy::Scored { deviation, .. } => deviation,
    };
    let range = ColourRange::default();
    let mut figures = Vec::new();
    for (name, (mesh, values)) in deviation {
        if mesh.vertices.len() != values.len() {
            page.paragraph(
                &format!("{name}: the deviation map does not match the registered surface."),
                Some("bad"),
            );
            continue;
        }
        // each triangle corner carries a third of the triangle's area
        let mut corner_values = Vec::with_capacity(3 * mesh.triangles.len());
        let mut weights = Vec::with_capacity(3 * mesh.triangles.len());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let third = mesh.triangle_area(t) / 3.0;
            for &v in tri {
                corner_values.push(values[v as usize]);
                weights.push(third);
            }
        }
        let svg = histogram_svg(
            name,
            "signed distance (mm), + = atlas outside",
            &corner_values,
            Some(&weights),
            (range.min_mm, range.max_mm),
            HISTOGRAM_BINS,
        );
        figures.push(Figure {
            caption: format!(
                "{name}: area-weighted signed distance of the registered surface's vertices to \
                 the segmentation (values beyond ±{} mm in the end bins)",
                range.max_mm
            ),
            content: FigureContent::Svg(svg),
        });
    }
    page.figures(&figures);
}
