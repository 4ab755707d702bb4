//! SVG charts of a validation: the TF magnitude against the Goode band (and the atlas, for a
//! package), the TF phase, and the UDSP curve. Frequencies run on a log axis labelled in Hz.

use super::plot::{AxisSpec, Colour, Series, line_chart_svg};
use crate::mechanics::verdict::GOODE_BAND;
use crate::mechanics::{StaticCurve, TransferFunction, Validation};

const MODEL: Colour = [200, 60, 40];
const ATLAS: Colour = [60, 90, 180];
const BAND: Colour = [150, 150, 150];
/// The name of both edges of the band (one legend entry).
const BAND_NAME: &str = "Goode et al. 1994 band";

/// (file name, SVG) of every chart of `v` (no UDSP chart when the curve was not computed).
pub fn validation_plots(v: &Validation) -> Vec<(&'static str, String)> {
    let tf = &v.mechanics.transfer_function;
    let mag = |t: &TransferFunction| -> Vec<(f64, f64)> {
        t.points
            .iter()
            .map(|p| (p.frequency_hz, p.magnitude_um_s_per_pa))
            .collect()
    };
    let phase = |t: &TransferFunction| -> Vec<(f64, f64)> {
        t.points
            .iter()
            .map(|p| (p.frequency_hz, p.phase_deg))
            .collect()
    };
    let umbo = |c: &StaticCurve| -> Vec<(f64, f64)> {
        c.points
            .iter()
            .map(|p| (p.pressure_pa, p.umbo_mm * 1e3))
            .collect()
    };
    let low: Vec<(f64, f64)> = GOODE_BAND.iter().map(|b| (b.0, b.1)).collect();
    let high: Vec<(f64, f64)> = GOODE_BAND.iter().map(|b| (b.0, b.2)).collect();
    let (m, p, u) = (mag(tf), phase(tf), umbo(&v.mechanics.udsp));
    let reference = v.reference.as_ref();
    let (rm, rp, ru) = reference.map_or((vec![], vec![], vec![]), |r| {
        (
            mag(&r.transfer_function),
            phase(&r.transfer_function),
            umbo(&r.udsp),
        )
    });
    let mut mag_series = vec![
        Series {
            name: "model",
            points: &m,
            colour: MODEL,
        },
        Series {
            name: BAND_NAME,
            points: &low,
            colour: BAND,
        },
        Series {
            name: BAND_NAME,
            points: &high,
            colour: BAND,
        },
    ];
    let mut phase_series = vec![Series {
        name: "model",
        points: &p,
        colour: MODEL,
    }];
    let mut udsp_series = vec![Series {
        name: "model",
        points: &u,
        colour: MODEL,
    }];
    if reference.is_some() {
        mag_series.push(Series {
            name: "atlas",
            points: &rm,
            colour: ATLAS,
        });
        phase_series.push(Series {
            name: "atlas",
            points: &rp,
            colour: ATLAS,
        });
        udsp_series.push(Series {
            name: "atlas",
            points: &ru,
            colour: ATLAS,
        });
    }
    let frequency = AxisSpec::hertz("frequency (Hz)");
    let mut charts = vec![
        (
            "tf_magnitude.svg",
            line_chart_svg(
                "Stapes velocity / ear-canal pressure",
                frequency,
                AxisSpec::log("|H_V| (um/s/Pa)"),
                &mag_series,
            ),
        ),
        (
            "tf_phase.svg",
            line_chart_svg(
                "Stapes velocity phase",
                frequency,
                AxisSpec::linear("phase (degrees)"),
                &phase_series,
            ),
        ),
    ];
    if !u.is_empty() {
        charts.push((
            "udsp.svg",
            line_chart_svg(
                "Umbo displacement under static pressure (+ = medial)",
                AxisSpec::linear("pressure, ear canal - middle ear (Pa)"),
                AxisSpec::linear("umbo displacement (um)"),
                &udsp_series,
            ),
        ));
    }
    charts
}
