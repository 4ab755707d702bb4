//! The cohort report `batch` writes: one HTML page (summary counts, per-structure box plots of
//! the registered MASD and HD95 across cases, the worst cases by their worst ossicle's MASD
//! with links to their reports, the cases `run` warned about with each warning, the failed
//! cases with their errors) and a CSV of every metric, one row per case and structure, with
//! the kinds of the case's warnings. Metric definitions: docs/metrics.md.

use std::collections::BTreeMap;

use super::error::ReportError;
use super::html::{Cell, Figure, FigureContent, Page};
use super::metrics::{
    CaseMetrics, HD95_TARGET_MM, MASD_TARGET_MM, StructureMetrics, WarningRecord, anatomical_order,
};
use super::plot::{SMALL_N, Target, box_plot_svg};
use crate::atlas::Part;
use crate::meshdev::SurfaceDistances;
use crate::meshdev::structures::FUSED_NAMES;

/// Most cases listed as the worst.
const WORST_LISTED: usize = 10;

/// One case of the cohort as `batch` saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct CohortEntry {
    pub case: String,
    /// The case's `metrics.json` as `run` wrote it (`None` when the case failed).
    pub metrics: Option<CaseMetrics>,
    /// The case's `report.html`, relative to the cohort report.
    pub report_link: String,
    /// Why the case failed.
    pub error: Option<String>,
}

/// The cohort report's two files.
#[derive(Debug, Clone, PartialEq)]
pub struct CohortReport {
    pub html: String,
    pub csv: String,
}

/// How a case ended.
enum Outcome<'a> {
    Scored(&'a BTreeMap<String, StructureMetrics>),
    /// Registered, but without a segmentation to score against.
    Unscored,
    Failed(&'a str),
}

impl Outcome<'_> {
    fn status(&self) -> &'static str {
        match self {
            Outcome::Scored(_) => "ok",
            Outcome::Unscored => "unscored",
            Outcome::Failed(_) => "failed",
        }
    }
}

fn outcome(entry: &CohortEntry) -> Outcome<'_> {
    match (&entry.error, &entry.metrics) {
        (Some(error), _) => Outcome::Failed(error),
        (None, None) => Outcome::Failed("no metrics.json"),
        (None, Some(metrics)) => match &metrics.scores {
            None => Outcome::Unscored,
            Some(scores) => Outcome::Scored(scores),
        },
    }
}

/// The worst ossicle of a scored case: (name, its registered distances), highest MASD.
fn worst_ossicle(scores: &BTreeMap<String, StructureMetrics>) -> Option<(&str, &SurfaceDistances)> {
    Part::BONES
        .iter()
        .filter_map(|p| scores.get(p.name()).map(|s| (p.name(), &s.registered)))
        .max_by(|a, b| a.1.masd.total_cmp(&b.1.masd))
}

/// The report of `entries`, in their order.
pub fn cohort_report(entries: &[CohortEntry]) -> Result<CohortReport, ReportError> {
    let outcomes: Vec<Outcome> = entries.iter().map(outcome).collect();
    Ok(CohortReport {
        html: html(entries, &outcomes),
        csv: csv(entries, &outcomes),
    })
}

/// The CSV's metrics per stage: fields of `SurfaceDistances`, named as in `metrics.json`.
const METRICS: [&str; 9] = [
    "masd",
    "assd",
    "rms",
    "hd",
    "hd95",
    "bias",
    "surface_dice",
    "meshdev_mean",
    "meshdev_max",
];

/// The `METRICS` of `d` as CSV fields (empty for a missing or non-finite value).
fn metric_fields(d: Option<&SurfaceDistances>) -> Vec<String> {
    let value = d.and_then(|d| serde_json::to_value(d).ok());
    METRICS
        .iter()
        .map(|m| {
            value
                .as_ref()
                .and_then(|v| v[m].as_f64())
                .map_or(String::new(), |x| x.to_string())
        })
        .collect()
}

/// A CSV field (RFC 4180): quoted when it holds a comma, a quote or a line break.
fn field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// Whether the case's package passed its mechanical gates (`metrics.json` `mechanics`), when
/// it was validated.
fn mechanics_passed(entry: &CohortEntry) -> Option<bool> {
    Some(entry.metrics.as_ref()?.mechanics.as_ref()?.passed)
}

/// The warnings `run` gave the case (landmarks, side, the registered pose).
fn warnings(entry: &CohortEntry) -> &[WarningRecord] {
    entry
        .metrics
        .as_ref()
        .map_or(&[], |m| m.landmark_warnings.as_slice())
}

/// A warning's `kind`, as `metrics.json` names it.
fn kind(warning: &WarningRecord) -> String {
    serde_json::to_value(&warning.warning)
        .ok()
        .and_then(|v| v["kind"].as_str().map(str::to_string))
        .unwrap_or_default()
}

/// The kinds of the case's warnings, space-separated.
fn warnings_field(entry: &CohortEntry) -> String {
    field(
        &warnings(entry)
            .iter()
            .map(kind)
            .collect::<Vec<_>>()
            .join(" "),
    )
}

fn mechanics_field(entry: &CohortEntry) -> String {
    match mechanics_passed(entry) {
        Some(true) => "pass".into(),
        Some(false) => "fail".into(),
        None => String::new(),
    }
}

fn csv(entries: &[CohortEntry], outcomes: &[Outcome]) -> String {
    let mut header = vec!["case".to_string(), "status".into(), "structure".into()];
    for stage in ["rigid", "registered"] {
        header.extend(METRICS.iter().map(|m| format!("{stage}_{m}")));
    }
    header.extend([
        "masd_improvement".into(),
        "mechanics".into(),
        "warnings".into(),
        "error".into(),
    ]);
    let blank = vec![String::new(); 2 * METRICS.len() + 1];
    let mut out = header.join(",") + "\n";
    for (entry, outcome) in entries.iter().zip(outcomes) {
        let lead = [field(&entry.case), outcome.status().to_string()];
        match outcome {
            Outcome::Scored(scores) => {
                for (name, s) in anatomical_order(scores) {
                    let mut row = lead.to_vec();
                    row.push(field(name));
                    row.extend(metric_fields(s.rigid.as_ref()));
                    row.extend(metric_fields(Some(&s.registered)));
                    row.push(s.masd_improvement.map_or(String::new(), |i| i.to_string()));
                    row.push(mechanics_field(entry));
                    row.push(warnings_field(entry));
                    row.push(String::new());
                    out += &(row.join(",") + "\n");
                }
            }
            Outcome::Unscored | Outcome::Failed(_) => {
                let error = match outcome {
                    Outcome::Failed(e) => field(e),
                    _ => String::new(),
                };
                let mut row = lead.to_vec();
                row.push(String::new());
                row.extend(blank.iter().cloned());
                row.push(mechanics_field(entry));
                row.push(warnings_field(entry));
                row.push(error);
                out += &(row.join(",") + "\n");
            }
        }
    }
    out
}

fn html(entries: &[CohortEntry], outcomes: &[Outcome]) -> String {
    let mut page = Page::new("otoatlas cohort report");
    let count = |status: &str| outcomes.iter().filter(|o| o.status() == status).count();
    page.heading("Summary").table(
        &[
            "cases",
            "scored",
            "registered without segmentation",
            "failed",
            "with warnings",
            "packages passing the mechanical gates",
        ],
        &[vec![
            entries.len().to_string(),
            count("ok").to_string(),
            count("unscored").to_string(),
            count("failed").to_string(),
            entries
                .iter()
                .filter(|e| !warnings(e).is_empty())
                .count()
                .to_string(),
            {
                let validated: Vec<bool> = entries.iter().filter_map(mechanics_passed).collect();
                format!(
                    "{} of {} validated",
                    validated.iter().filter(|p| **p).count(),
                    validated.len()
                )
            },
        ]],
    );
    let scored: Vec<(&CohortEntry, &BTreeMap<String, StructureMetrics>)> = entries
        .iter()
        .zip(outcomes)
        .filter_map(|(e, o)| match o {
            Outcome::Scored(s) => Some((e, *s)),
            _ => None,
        })
        .collect();

    page.heading("Registered surface distances across cases");
    if scored.is_empty() {
        page.paragraph("No case was scored against a segmentation.", Some("note"));
    } else {
        let mut masd: Vec<(String, Vec<f64>)> = Vec::new();
        let mut hd95: Vec<(String, Vec<f64>)> = Vec::new();
        // each structure, then the chain as one solid (fused or united, docs/metrics.md)
        let names = Part::STRUCTURES
            .iter()
            .map(|p| p.name())
            .chain(FUSED_NAMES.iter().map(|(name, _)| *name));
        for name in names {
            let values = |f: fn(&SurfaceDistances) -> f64| -> Vec<f64> {
                scored
                    .iter()
                    .filter_map(|(_, s)| s.get(name).map(|m| f(&m.registered)))
                    .collect()
            };
            if scored.iter().any(|(_, s)| s.contains_key(name)) {
                masd.push((name.to_string(), values(|d| d.masd)));
                hd95.push((name.to_string(), values(|d| d.hd95)));
            }
        }
        let figures: Vec<Figure> = [
            ("MASD", masd, MASD_TARGET_MM),
            ("HD95", hd95, HD95_TARGET_MM),
        ]
        .into_iter()
        .map(|(metric, groups, target)| Figure {
            caption: format!(
                "{metric} per structure across cases (box: quartiles and median; whiskers: the \
                 furthest cases within 1.5 interquartile ranges; every case a point when fewer \
                 than {SMALL_N})"
            ),
            content: FigureContent::Svg(box_plot_svg(
                metric,
                &format!("{metric} (mm)"),
                &groups,
                Some(&Target {
                    value: target,
                    label: format!("target ≤ {target} mm (ossicles)"),
                }),
            )),
        })
        .collect();
        page.figures(&figures);
        worst_cases(&mut page, &scored);
    }

    page.heading("Cases with warnings");
    let warned: Vec<Vec<Cell>> = entries
        .iter()
        .flat_map(|e| {
            warnings(e).iter().map(|w| {
                vec![
                    Cell::Link {
                        href: e.report_link.clone(),
                        text: e.case.clone(),
                    },
                    Cell::Text(kind(w)),
                    Cell::Text(w.message.clone()),
                ]
            })
        })
        .collect();
    if warned.is_empty() {
        page.paragraph("No case has a warning.", Some("ok"));
    } else {
        page.table_cells(&["case", "warning", "what it says"], &warned);
    }

    page.heading("Failed cases");
    let failed: Vec<Vec<Cell>> = entries
        .iter()
        .zip(outcomes)
        .filter_map(|(e, o)| match o {
            Outcome::Failed(error) => Some(vec![
                Cell::Text(e.case.clone()),
                Cell::Text(error.to_string()),
            ]),
            _ => None,
        })
        .collect();
    if failed.is_empty() {
        page.paragraph("No case failed.", Some("ok"));
    } else {
        page.table_cells(&["case", "error"], &failed);
    }
    page.finish()
}

fn worst_cases(page: &mut Page, scored: &[(&CohortEntry, &BTreeMap<String, StructureMetrics>)]) {
    let mut ranked: Vec<(&CohortEntry, &str, &SurfaceDistances, bool)> = scored
        .iter()
        .filter_map(|(e, s)| {
            let all_met = Part::BONES
                .iter()
                .filter_map(|p| s.get(p.name()))
                .all(StructureMetrics::meets_targets);
            worst_ossicle(s).map(|(name, d)| (*e, name, d, all_met))
        })
        .collect();
    ranked.sort_by(|a, b| b.2.masd.total_cmp(&a.2.masd));
    let rows: Vec<Vec<Cell>> = ranked
        .iter()
        .take(WORST_LISTED)
        .map(|(e, name, d, met)| {
            vec![
                Cell::Link {
                    href: e.report_link.clone(),
                    text: e.case.clone(),
                },
                Cell::Text(name.to_string()),
                Cell::Text(format!("{:.3}", d.masd)),
                Cell::Text(format!("{:.3}", d.hd95)),
                Cell::Text(if *met { "met" } else { "missed" }.into()),
            ]
        })
        .collect();
    page.heading(&format!(
        "Worst cases ({} of {} scored, by their worst ossicle's MASD)",
        rows.len(),
        ranked.len()
    ))
    .table_cells(
        &[
            "case",
            "worst ossicle",
            "MASD (mm)",
            "HD95 (mm)",
            "ossicle targets",
        ],
        &rows,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::metrics::{case_metrics, distances_json};
    use serde_json::json;

    fn scored(case: &str, malleus_masd: f64) -> CohortEntry {
        CohortEntry {
            case: case.into(),
            metrics: Some(case_metrics(
                case,
                json!({
                    "incus": {"registered": distances_json(0.03, 0.1, 0.002, 0.99),
                              "rigid": null, "masd_improvement": null},
                    "malleus": {"registered": distances_json(malleus_masd, 0.14, -0.012, 0.978),
                                "rigid": distances_json(0.15, 0.35, 0.084, 0.648),
                                "masd_improvement": 1.0 - malleus_masd / 0.15},
                }),
                json!({"passed": malleus_masd < 0.1, "gates": 30, "failed": []}),
            )),
            report_link: format!("{case}/report.html"),
            error: None,
        }
    }

    fn entries() -> Vec<CohortEntry> {
        let mut b = scored("case-b", 0.25);
        if let Some(m) = b.metrics.as_mut() {
            m.landmark_warnings.push(WarningRecord::from(
                &crate::register::landmarks::LandmarkWarning::WeakEdgeSupport {
                    ossicle: "stapes".into(),
                    share: 0.2,
                    limit: 0.4,
                },
            ));
        }
        vec![
            scored("case-a", 0.045),
            b,
            CohortEntry {
                case: "case-c".into(),
                metrics: None,
                report_link: "case-c/report.html".into(),
                error: Some("landmarks: \"umbo\" missing, line 3".into()),
            },
            CohortEntry {
                case: "case-d".into(),
                metrics: Some(case_metrics("case-d", json!(null), json!(null))),
                report_link: "case-d/report.html".into(),
                error: None,
            },
        ]
    }

    #[test]
    fn csv_holds_every_metric_per_case_and_structure() {
        let report = cohort_report(&entries()).unwrap();
        let lines: Vec<&str> = report.csv.lines().collect();
        let header: Vec<&str> = lines[0].split(',').collect();
        assert_eq!(header.len(), 25);
        let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
        let rows: Vec<Vec<&str>> = lines[1..5].iter().map(|l| l.split(',').collect()).collect();
        // case-a: malleus (anatomical order) before incus
        let malleus = &rows[0];
        assert_eq!(&malleus[..3], ["case-a", "ok", "malleus"]);
        let value = |row: &[&str], name: &str| row[col(name)].parse::<f64>().unwrap();
        assert_eq!(value(malleus, "rigid_masd"), 0.15);
        assert_eq!(value(malleus, "rigid_assd"), 0.15 + 0.001);
        assert_eq!(value(malleus, "rigid_hd"), 0.35 + 0.3);
        assert_eq!(value(malleus, "rigid_bias"), 0.084);
        assert_eq!(value(malleus, "rigid_surface_dice"), 0.648);
        assert_eq!(value(malleus, "registered_masd"), 0.045);
        assert_eq!(value(malleus, "registered_rms"), 0.045 + 0.002);
        assert_eq!(value(malleus, "registered_hd95"), 0.14);
        assert_eq!(value(malleus, "registered_bias"), -0.012);
        assert_eq!(value(malleus, "registered_meshdev_mean"), 0.045 + 0.003);
        assert_eq!(value(malleus, "registered_meshdev_max"), 0.14 + 0.4);
        assert_eq!(value(malleus, "masd_improvement"), 1.0 - 0.045 / 0.15);
        assert_eq!(malleus[col("error")], "");
        assert_eq!(malleus[col("mechanics")], "pass");
        assert!(report.html.contains("<td>1 of 2 validated</td>"));
        // no rigid score: empty cells
        let incus = &rows[1];
        assert_eq!(&incus[..3], ["case-a", "ok", "incus"]);
        assert_eq!(incus[col("rigid_masd")], "");
        assert_eq!(incus[col("masd_improvement")], "");
        assert_eq!(value(incus, "registered_surface_dice"), 0.99);
        assert_eq!(&rows[2][..3], ["case-b", "ok", "malleus"]);
        assert_eq!(rows[2][col("mechanics")], "fail");
        assert_eq!(rows[2][col("warnings")], "weak_edge_support");
        assert_eq!(malleus[col("warnings")], "");
        // the failed case: one row, its error quoted; the unscored case: one row
        assert_eq!(
            lines[5],
            format!(
                "case-c,failed,{}\"landmarks: \"\"umbo\"\" missing, line 3\"",
                ",".repeat(22)
            )
        );
        assert_eq!(lines[6], format!("case-d,unscored{}", ",".repeat(23)));
        assert_eq!(lines.len(), 7);
    }

    #[test]
    fn html_counts_plots_links_the_worst_cases_and_lists_the_failed() {
        let html = cohort_report(&entries()).unwrap().html;
        assert!(html.contains(
            "<tr><td>4</td><td>2</td><td>1</td><td>1</td><td>1</td><td>1 of 2 validated</td></tr>"
        ));
        assert!(html.contains(
            "<tr><td><a href=\"case-b/report.html\">case-b</a></td><td>weak_edge_support</td><td>only 20 % of the registered stapes"
        ));
        assert_eq!(html.matches("<svg").count(), 2, "MASD and HD95 box plots");
        let b = html
            .find("<tr><td><a href=\"case-b/report.html\">case-b</a></td><td>malleus</td><td>0.250</td><td>0.140</td><td>missed</td></tr>")
            .unwrap();
        let a = html
            .find("<tr><td><a href=\"case-a/report.html\">case-a</a></td><td>malleus</td><td>0.045</td><td>0.140</td><td>met</td></tr>")
            .unwrap();
        assert!(b < a, "worst first");
        assert!(html.contains(
            "<tr><td>case-c</td><td>landmarks: &quot;umbo&quot; missing, line 3</td></tr>"
        ));
        assert!(
            !html.contains("case-d/report.html"),
            "only scored cases are ranked"
        );
    }

    #[test]
    fn a_cohort_without_scores_or_failures_says_so() {
        let html = cohort_report(&entries()[3..]).unwrap().html;
        assert!(html.contains("No case was scored against a segmentation."));
        assert!(html.contains("No case has a warning."));
        assert!(html.contains("No case failed."));
    }
}
