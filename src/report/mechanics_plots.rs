//! SVG charts of a validation: the TF magnitude against the Goode band (and the atlas, for a
//! package), the TF phase, and the UDSP curve.

use plotters::style::RGBColor;

use super::plot::{PlotError, Series, line_chart_svg};
use crate::mechanics::verdict::GOODE_BAND;
use crate::mechanics::{StaticCurve, TransferFunction, Validation};

const MODEL: RGBColor = RGBColor(200, 60, 40);
const ATLAS: RGBColor = RGBColor(60, 90, 180);
const BAND: RGBColor = RGBColor(150, 150, 150);

/// (file name, SVG) of every chart of `v` (no UDSP chart when the curve was not computed).
pub fn validation_plots(v: &Validation) -> Result<Vec<(&'static str, String)>, PlotError> {
    let tf = &v.mechanics.transfer_function;
    let mag = |t: &TransferFunction| -> Vec<(f64, f64)> {
        t.points
            .iter()
            .map(|p| (p.frequency_hz.log10(), p.magnitude_um_s_per_pa))
            .collect()
    };
    let phase = |t: &TransferFunction| -> Vec<(f64, f64)> {
        t.points
            .iter()
            .map(|p| (p.frequency_hz.log10(), p.phase_deg))
            .collect()
    };
    let umbo = |c: &StaticCurve| -> Vec<(f64, f64)> {
        c.points
            .iter()
            .map(|p| (p.pressure_pa, p.umbo_mm * 1e3))
            .collect()
    };
    let low: Vec<(f64, f64)> = GOODE_BAND.iter().map(|b| (b.0.log10(), b.1)).collect();
    let high: Vec<(f64, f64)> = GOODE_BAND.iter().map(|b| (b.0.log10(), b.2)).collect();
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
            color: MODEL,
        },
        Series {
            name: "Goode band low",
            points: &low,
            color: BAND,
        },
        Series {
            name: "Goode band high",
            points: &high,
            color: BAND,
        },
    ];
    let mut phase_series = vec![Series {
        name: "model",
        points: &p,
        color: MODEL,
    }];
    let mut udsp_series = vec![Series {
        name: "model",
        points: &u,
        color: MODEL,
    }];
    if reference.is_some() {
        mag_series.push(Series {
            name: "atlas",
            points: &rm,
            color: ATLAS,
        });
        phase_series.push(Series {
            name: "atlas",
            points: &rp,
            color: ATLAS,
        });
        udsp_series.push(Series {
            name: "atlas",
            points: &ru,
            color: ATLAS,
        });
    }
    let mut charts = vec![
        (
            "tf_magnitude.svg",
            line_chart_svg(
                "Stapes velocity / ear-canal pressure",
                "log10 frequency (Hz)",
                "|H_V| (um/s/Pa)",
                &mag_series,
                true,
            )?,
        ),
        (
            "tf_phase.svg",
            line_chart_svg(
                "Stapes velocity phase",
                "log10 frequency (Hz)",
                "phase (degrees)",
                &phase_series,
                false,
            )?,
        ),
    ];
    if !u.is_empty() {
        charts.push((
            "udsp.svg",
            line_chart_svg(
                "Umbo displacement under static pressure (+ = medial)",
                "pressure, ear canal - middle ear (Pa)",
                "umbo displacement (um)",
                &udsp_series,
                false,
            )?,
        ));
    }
    Ok(charts)
}
