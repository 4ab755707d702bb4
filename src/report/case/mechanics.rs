//! The report's mechanics section: the package's verdict against its atlas (each gate with
//! its value and band) and the charts of the transfer function (magnitude against the Goode
//! band and the atlas, phase) and, when computed, of the static-pressure curve.

use super::super::html::{Figure, FigureContent, Page};
use super::super::mechanics_plots::validation_plots;
use crate::mechanics::{Ossicles, Validation};

pub(super) fn mechanics_section(page: &mut Page, v: Option<&Validation>) {
    page.heading("Mechanics: consistency with the atlas");
    let Some(v) = v else {
        page.paragraph(
            "Not validated (`[validate] enabled = false` in the configuration).",
            Some("note"),
        );
        return;
    };
    let condition = match v.condition {
        crate::mechanics::Condition::Normal => String::new(),
        c => format!(", both under the condition {}", c.name()),
    };
    let ossicles = match v.mechanics.transfer_function.ossicles {
        Ossicles::Rigid => {
            " Both are computed with each ossicle as one rigid body (half the unknowns; the \
             same verdicts as elastic bone on the sample cases, docs/mechanics.md)."
        }
        Ossicles::Elastic => " Both are computed with elastic ossicles (the full model).",
    };
    page.paragraph(
        &format!(
            "These gates compare the package with the atlas it was registered from{condition}: \
             they show that the registration kept the atlas's behaviour, not that the model is \
             right. The atlas's evidence against measurements is in `otoatlas validate` \
             (docs/mechanics.md, \"Evidence\").{ossicles}"
        ),
        Some("note"),
    );
    let failed = v.verdict.failures().count();
    if v.verdict.passed {
        page.paragraph(
            &format!(
                "All {} gates pass: the package keeps the atlas's mechanics.",
                v.verdict.gates.len()
            ),
            Some("ok"),
        );
    } else {
        page.paragraph(
            &format!(
                "{failed} of {} gates fail: the package's mechanics leave the atlas's bands \
                 (a patient's size alone shifts the transfer function: an ear s times larger \
                 has its frequencies divided by about s). Check the charts before simulating.",
                v.verdict.gates.len()
            ),
            Some("bad"),
        );
    }
    let rows: Vec<Vec<String>> = v
        .verdict
        .gates
        .iter()
        .map(|g| {
            vec![
                g.name.clone(),
                format!("{:.3} {}", g.value, g.unit),
                format!("[{}, {}]", g.low, g.high),
                if g.passed { "pass" } else { "FAIL" }.to_string(),
            ]
        })
        .collect();
    page.table(&["gate", "value", "band", ""], &rows);
    let captions = |name: &str| match name {
        "tf_magnitude.svg" => {
            "stapes footplate piston velocity per ear-canal pressure (|H_V|, eardrum drive): the \
             package (model), the atlas, and the Goode et al. 1994 band"
        }
        "tf_phase.svg" => "phase of H_V: the package and the atlas",
        _ => "umbo displacement under static pressure: the package and the atlas",
    };
    let charts = validation_plots(v);
    let figures: Vec<Figure> = charts
        .into_iter()
        .map(|(name, svg)| Figure {
            caption: captions(name).to_string(),
            content: FigureContent::Svg(svg),
        })
        .collect();
    page.figures(&figures);
}
