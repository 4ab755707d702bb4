//! The accuracy sections of the case report: the surface distances per structure for the
//! rigid fit and the registration (definitions in docs/metrics.md, computed by
//! `meshdev`), and the histogram of the registered surface's signed distances per structure.

use std::collections::BTreeMap;

use super::{Accuracy, CaseReportInput, mm};
use crate::atlas::Part;
use crate::meshdev::{ColourRange, LabelDeviation};
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

/// Where the registered surfaces' distances lie: per structure, the atlas regions holding area
/// farther than two voxels from the segmentation, most first (all regions of a structure
/// with none far are summed in one line).
pub(super) fn far_regions_table(
    page: &mut Page,
    scores: Option<&BTreeMap<String, StructureMetrics>>,
) {
    let Some(scores) = scores else {
        return;
    };
    let mut rows = Vec::new();
    for (name, s) in anatomical_order(scores) {
        let Some(far) = s.far_mm else {
            continue;
        };
        let mut regions: Vec<_> = s.by_region.iter().collect();
        let far_area = |d: &LabelDeviation| d.area_mm2 * (d.far_outside_share + d.far_inside_share);
        regions.sort_by(|a, b| far_area(b.1).total_cmp(&far_area(a.1)).then(a.0.cmp(b.0)));
        let total: f64 = regions.iter().map(|(_, d)| d.area_mm2).sum();
        for (region, d) in regions.iter().filter(|(_, d)| far_area(d) > 0.0) {
            rows.push(vec![
                name.to_string(),
                region.to_string(),
                format!("{:.2}", d.area_mm2),
                mm(d.mean_signed_mm),
                mm(d.max_abs_mm),
                format!("{:.1} %", 100.0 * d.far_outside_share),
                format!("{:.1} %", 100.0 * d.far_inside_share),
                format!("{:.1} %", 100.0 * far_area(d) / total),
            ]);
        }
        if regions.iter().all(|(_, d)| far_area(d) == 0.0) && !regions.is_empty() {
            rows.push(vec![
                name.to_string(),
                format!("none beyond {} mm", mm(far)),
                format!("{total:.2}"),
                "–".into(),
                "–".into(),
                "0 %".into(),
                "0 %".into(),
                "0 %".into(),
            ]);
        }
    }
    if rows.is_empty() {
        return;
    }
    page.heading("Where the distances lie");
    page.table(
        &[
            "structure",
            "atlas region",
            "area (mm²)",
            "mean signed (mm)",
            "max |d| (mm)",
            "far outside",
            "far inside",
            "of the structure's area",
        ],
        &rows,
    );
    page.paragraph(
        "Each registered surface's signed distances summed over the atlas region each triangle \
         bounds (docs/metrics.md, \"Where the distances lie\"): far is beyond two voxels, the \
         HD95 target; outside = atlas surface outside the segmentation. A region far outside \
         is atlas shape the image does not show; far inside, segmentation the atlas does not \
         reach.",
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
