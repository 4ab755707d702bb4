//! The per-case report `run` writes as `OUT/report.html`: the page a clinical engineer reads to
//! accept or reject a registration. One self-contained file (charts as inline SVG, slices as
//! inline PNG, no script, no network reference) with, in order: a verdict against the
//! registration targets (mechanics-metrics.md §0.2), the case summary (image geometry, side,
//! atlas, landmark residuals, rigid scale, deformable status, timings), the surface distances
//! per structure (rigid fit and registration, definitions of §0.2), the slice overlays, the
//! histograms of signed distances and the convergence curve of the deformable stage.

use std::collections::BTreeMap;

use nalgebra::Point3;
use plotters::style::RGBColor;
use serde_json::Value;

use super::error::ReportError;
use super::html::{Figure, FigureContent, Page};
use super::metrics::{
    DeformSummary, HD95_TARGET_MM, MASD_TARGET_MM, StructureMetrics, anatomical_order,
    parse_deform, parse_scores,
};
use super::plot::{Series, histogram_svg, line_chart_svg};
use super::slices::{
    OverlaySurfaces, REGISTERED_COLOUR, RIGID_COLOUR, SEGMENTATION_COLOUR, overlay_figures,
};
use crate::atlas::{Atlas, Part};
use crate::ear::{LandmarkName, Side};
use crate::image::{LoadedImage, Sampler};
use crate::mesh::TriMesh;
use crate::meshdev::ColourRange;
use crate::register::rigid::RigidFit;

/// Bins of the signed-distance histograms over the deviation maps' fixed colour range.
const HISTOGRAM_BINS: usize = 40;

/// What the accuracy sections can show.
pub enum Accuracy<'a> {
    /// The case has no manual segmentation.
    NoSegmentation,
    /// `run --from` started after the score stage: the scores come from the earlier run's
    /// artefact; the per-vertex deviations and the segmentation's surfaces are not in memory.
    Resumed { scores: &'a Value },
    /// Scored in this run.
    Scored {
        /// The `scores` object of `metrics.json`.
        scores: &'a Value,
        /// Per structure: the signed distance of each registered-surface vertex [mm], in the
        /// vertex order of `Atlas::part_surface`.
        deviation: BTreeMap<&'a str, &'a [f64]>,
        /// The segmentation's surfaces by structure name.
        reference: &'a BTreeMap<String, TriMesh>,
    },
}

/// Everything the case report shows.
pub struct CaseReportInput<'a> {
    pub case_id: &'a str,
    pub image: &'a LoadedImage,
    pub sampler: &'a Sampler<'a>,
    pub side: Side,
    /// Where the side came from ("--side", "landmark file", "DICOM laterality").
    pub side_source: &'a str,
    pub atlas: &'a Atlas,
    pub fit: &'a RigidFit,
    /// Atlas nodes after the rigid fit and after the deformable registration.
    pub rigid_nodes: &'a [Point3<f64>],
    pub registered_nodes: &'a [Point3<f64>],
    /// The deformable stage's record (`metrics.json`'s `deform`).
    pub deform: &'a Value,
    pub accuracy: Accuracy<'a>,
    /// Seconds per stage run, and the whole run so far.
    pub timings: &'a [(&'a str, f64)],
    pub total_seconds: f64,
}

fn mm(v: f64) -> String {
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
    let deform = parse_deform(input.deform, input.case_id)?;
    let scores = match &input.accuracy {
        Accuracy::NoSegmentation => None,
        Accuracy::Resumed { scores } | Accuracy::Scored { scores, .. } => {
            Some(parse_scores(scores, input.case_id)?)
        }
    };
    let rigid = surfaces(input.atlas, input.rigid_nodes);
    let registered = surfaces(input.atlas, input.registered_nodes);
    let mut page = Page::new(&format!("otoatlas case report: {}", input.case_id));
    verdict(&mut page, &deform, scores.as_ref());
    summary(&mut page, input, &deform);
    metrics_table(&mut page, input, scores.as_ref());

    page.heading("Slice overlays");
    let reference = match &input.accuracy {
        Accuracy::Scored { reference, .. } => Some(*reference),
        _ => None,
    };
    let mut legend = vec![
        ("atlas after the rigid fit", RIGID_COLOUR),
        ("atlas after the deformable registration", REGISTERED_COLOUR),
    ];
    if reference.is_some() {
        legend.push(("manual segmentation", SEGMENTATION_COLOUR));
    }
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
    };
    for (_, figures) in overlay_figures(input.sampler, &overlay)? {
        page.figures(&figures);
    }

    histograms(&mut page, input, &registered)?;
    convergence(&mut page, &deform)?;
    Ok(page.finish())
}

/// The one-line verdicts a reader checks first.
fn verdict(
    page: &mut Page,
    deform: &DeformSummary,
    scores: Option<&BTreeMap<String, StructureMetrics>>,
) {
    page.heading("Verdict");
    match deform.status.as_str() {
        "converged" => page.paragraph("The deformable registration converged.", Some("ok")),
        other => page.paragraph(
            &format!(
                "The deformable registration did not converge ({other}{}): check the overlays.",
                deform
                    .message
                    .as_deref()
                    .map(|m| format!(": {m}"))
                    .unwrap_or_default()
            ),
            Some("bad"),
        ),
    };
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

fn summary(page: &mut Page, input: &CaseReportInput, deform: &DeformSummary) {
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
        ("atlas", input.atlas.name.clone()),
        ("rigid scale", format!("{:.4}", input.fit.transform.scale)),
        (
            "deformable stage",
            format!("{}, {} iterations", deform.status, deform.history.len()),
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
        .map(|(n, r)| vec![n.key().to_string(), mm(*r)])
        .collect();
    landmarks.push(vec!["RMS".into(), mm(input.fit.rms_mm)]);
    page.table(&["landmark", "rigid-fit residual (mm)"], &landmarks);
    let mut timings: Vec<Vec<String>> = input
        .timings
        .iter()
        .map(|(stage, s)| vec![stage.to_string(), format!("{s:.2}")])
        .collect();
    timings.push(vec!["total".into(), format!("{:.2}", input.total_seconds)]);
    page.table(&["stage", "time (s)"], &timings);
}

fn metrics_table(
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

fn histograms(
    page: &mut Page,
    input: &CaseReportInput,
    registered: &BTreeMap<String, TriMesh>,
) -> Result<(), ReportError> {
    page.heading("Signed distances of the registered surfaces");
    let deviation = match &input.accuracy {
        Accuracy::NoSegmentation => {
            page.paragraph(
                "The case has no manual segmentation: no distances.",
                Some("note"),
            );
            return Ok(());
        }
        Accuracy::Resumed { .. } => {
            page.paragraph(
                "This run resumed after the score stage: the per-vertex distances are not in \
                 memory (they are in registered/deviation/*.ply); rerun from score to plot them.",
                Some("note"),
            );
            return Ok(());
        }
        Accuracy::Scored { deviation, .. } => deviation,
    };
    let range = ColourRange::default();
    let mut figures = Vec::new();
    for (name, values) in deviation {
        let Some(mesh) = registered
            .get(*name)
            .filter(|m| m.vertices.len() == values.len())
        else {
            page.paragraph(
                &format!("{name}: the deviation map does not match the registered surface."),
                Some("bad"),
            );
            continue;
        };
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
        )?;
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
    Ok(())
}

fn convergence(page: &mut Page, deform: &DeformSummary) -> Result<(), ReportError> {
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
        "iteration",
        "mm",
        &[
            Series {
                name: "mean border offset",
                points: &offset,
                color: RGBColor(200, 30, 30),
            },
            Series {
                name: "99th percentile nodal update",
                points: &update,
                color: RGBColor(30, 90, 200),
            },
        ],
        true,
    )?;
    page.figures(&[Figure {
        caption: format!(
            "mean distance from the atlas surface to the image border found by the probes, and \
             the 99th percentile of the nodal updates, per iteration ({}, {} iterations)",
            deform.status,
            deform.history.len()
        ),
        content: FigureContent::Svg(svg),
    }]);
    Ok(())
}
