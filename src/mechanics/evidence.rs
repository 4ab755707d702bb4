//! The model against measurements it was not fitted to, source by source: at each measured
//! point the model's value and the residual, then the RMS and the worst residual, and whether
//! every point lies within the spread the source (or the nearest published spread) reports.
//! Where a figure of the model was fitted to a source, the entry says so and is not evidence.
//! The literature gates (`verdict`) are a wide sanity net; this is the comparison a reader
//! should judge the model on. Sources and conversions: docs/mechanics.md, "Evidence".

use serde::Serialize;

use super::tfa::TransferFunction;
use super::udsp::StaticCurve;

/// Goode et al. 1994 (Am J Otol 15:145), temporal-bone stapes displacement at 104 dB SPL as
/// the Auditory Modeling Toolbox tabulates it (`data_goode1994`), labelled peak-to-peak:
/// (Hz, velocity over pressure read as peak-to-peak, µm/s/Pa). Read as an amplitude it is
/// twice that; the comparison uses the geometric mean of the two readings.
const GOODE_1994: [(f64, f64); 7] = [
    (400.0, 56.0),
    (600.0, 96.0),
    (800.0, 123.0),
    (1000.0, 106.0),
    (2000.0, 46.0),
    (4000.0, 20.0),
    (6000.0, 13.0),
];
/// The inter-subject spread of the magnitude, ±dB: Whittemore et al. 2004 (Hear Res
/// 187:85; 56 live ears, umbo velocity), the nearest published spread, taken as ±2 SD.
const MAGNITUDE_SPREAD_DB: f64 = 10.0;
/// Where that spread comes from.
const MAGNITUDE_SPREAD_SOURCE: &str =
    "Whittemore et al. 2004, Hear Res 187:85: inter-subject spread of umbo velocity";
/// Aibara, Welsh, Puria & Goode 2001 (Hear Res 152:100; 12 fresh temporal bones): the mean
/// stapes footplate velocity over ear-canal pressure reached its maximum, 0.33 mm/s/Pa, at
/// 1.0 kHz: (Hz, µm/s/Pa).
const AIBARA_2001: (f64, f64) = (1000.0, 330.0);
/// Kringlebotn & Gundersen 1985 (J Acoust Soc Am 77:159; 68 temporal bones): the round
/// window's volume displacement per sound pressure at the eardrum, level-averaged, "approximately
/// flat below 1 kHz" at 6.8e-5 mm³/Pa: read at the one-third octaves below 1 kHz (Hz).
const KRINGLEBOTN_1985_MM3_PER_PA: f64 = 6.8e-5;
const KRINGLEBOTN_1985_HZ: [f64; 6] = [250.0, 315.0, 400.0, 500.0, 630.0, 800.0];
/// Chien et al. 2009 (14 live ears): stapes velocity leads the pressure by 0.2 cycles at
/// 0.3 kHz: (Hz, degrees).
const CHIEN_2009_PHASE: (f64, f64) = (300.0, 72.0);
/// The spread of that phase, ±degrees: Whittemore et al. 2004's ±15° at low frequencies (umbo
/// phase of live ears), the nearest published spread.
const PHASE_SPREAD_DEG: f64 = 15.0;
/// Gyo & Goode 1987 (Auris Nasus Larynx 14:131; 5 fresh temporal bones, the umbo's vibration
/// at 120 dB SPL at the eardrum): the loss of umbo vibration below 2 kHz when the middle
/// ear's pressure is lowered by 100, 200 and 300 mmH2O, mean and SD over the bones:
/// (mmH2O, loss dB, SD dB).
const GYO_GOODE_1987: [(f64, f64, f64); 3] =
    [(100.0, 5.0, 1.0), (200.0, 9.2, 1.3), (300.0, 13.1, 1.8)];
/// Pa per mmH2O (conventional, 4 °C water at standard gravity).
const PA_PER_MM_H2O: f64 = 9.80665;

/// One measured point against the model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvidencePoint {
    /// The sound's frequency, for a point of a frequency response.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frequency_hz: Option<f64>,
    /// The static pressure p = ear canal − middle ear (docs/mechanics.md, UDSP), for a point
    /// measured under one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pressure_pa: Option<f64>,
    pub measured: f64,
    pub model: f64,
    /// model against measured: dB for magnitudes, degrees for phases.
    pub residual: f64,
    /// The spread this residual is held to (±, in the residual's unit).
    pub spread: f64,
}

/// One source's comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evidence {
    pub source: &'static str,
    /// What was measured, on what, and how it is compared.
    pub quantity: &'static str,
    /// The unit of `measured`, `model` and of the residuals (`dB`, `deg`).
    pub unit: &'static str,
    pub residual_unit: &'static str,
    pub points: Vec<EvidencePoint>,
    pub rms_residual: f64,
    /// The residual largest in size, with its sign.
    pub worst_residual: f64,
    /// Where the points' spreads come from.
    pub spread_source: &'static str,
    pub within_spread: bool,
    /// Set when the model was fitted to this source: then this entry is not evidence.
    pub fitted: Option<&'static str>,
}

impl Evidence {
    fn new(
        source: &'static str,
        quantity: &'static str,
        (unit, residual_unit): (&'static str, &'static str),
        points: Vec<EvidencePoint>,
        spread_source: &'static str,
    ) -> Evidence {
        let n = points.len().max(1) as f64;
        let rms_residual = (points.iter().map(|p| p.residual.powi(2)).sum::<f64>() / n).sqrt();
        let worst_residual = points
            .iter()
            .map(|p| p.residual)
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(f64::NAN);
        let within_spread =
            !points.is_empty() && points.iter().all(|p| p.residual.abs() <= p.spread);
        Evidence {
            source,
            quantity,
            unit,
            residual_unit,
            points,
            rms_residual,
            worst_residual,
            spread_source,
            within_spread,
            fitted: None,
        }
    }
}

impl Evidence {
    /// The smallest and largest of the points' spreads.
    pub fn spread_range(&self) -> (f64, f64) {
        self.points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.spread), hi.max(p.spread))
            })
    }
}

/// The model's transfer function `tf` and static curve `udsp` against every source; the
/// footplate's area (mm²) turns its piston velocity into the volume the cochlea takes.
pub fn evidence(
    tf: &TransferFunction,
    udsp: &StaticCurve,
    footplate_area_mm2: f64,
) -> Vec<Evidence> {
    let mut all = Vec::new();
    let goode: Vec<EvidencePoint> = GOODE_1994
        .iter()
        .filter_map(|&(f, peak_to_peak)| {
            let model = magnitude_at(tf, f)?;
            Some(magnitude_point(
                f,
                peak_to_peak * std::f64::consts::SQRT_2,
                model,
            ))
        })
        .collect();
    all.push(Evidence::new(
        "Goode et al. 1994, Am J Otol 15:145",
        "stapes velocity over ear-canal pressure, temporal bones (the geometric mean of the \
         peak-to-peak and amplitude readings, which differ by 6 dB)",
        ("um/s/Pa", "dB"),
        goode,
        MAGNITUDE_SPREAD_SOURCE,
    ));
    let (f, measured) = AIBARA_2001;
    let peak: Vec<EvidencePoint> = magnitude_at(tf, f)
        .map(|model| magnitude_point(f, measured, model))
        .into_iter()
        .collect();
    all.push(Evidence::new(
        "Aibara et al. 2001, Hear Res 152:100",
        "stapes velocity over ear-canal pressure at 1.0 kHz, where the mean of 12 temporal \
         bones peaks (0.33 mm/s/Pa)",
        ("um/s/Pa", "dB"),
        peak,
        MAGNITUDE_SPREAD_SOURCE,
    ));
    // the cochlear fluid is incompressible: the round window moves the volume the footplate
    // does, |H_V| / (2π f) times its area (µm · mm² = 1e-3 mm³)
    let volume: Vec<EvidencePoint> = KRINGLEBOTN_1985_HZ
        .iter()
        .filter_map(|&f| {
            let velocity = magnitude_at(tf, f)?;
            let model = velocity / (2.0 * std::f64::consts::PI * f) * footplate_area_mm2 * 1e-3;
            Some(magnitude_point(f, KRINGLEBOTN_1985_MM3_PER_PA, model))
        })
        .filter(|p| p.model > 0.0)
        .collect();
    all.push(Evidence::new(
        "Kringlebotn & Gundersen 1985, J Acoust Soc Am 77:159",
        "round-window volume displacement over eardrum pressure below 1 kHz, 68 temporal \
         bones (level-averaged, flat at 6.8e-5 mm3/Pa); the model's footplate volume \
         displacement",
        ("mm3/Pa", "dB"),
        volume,
        MAGNITUDE_SPREAD_SOURCE,
    ));
    let (f, measured) = CHIEN_2009_PHASE;
    let phase: Vec<EvidencePoint> = log_interpolate(tf, f, |p| p.phase_deg)
        .map(|model| EvidencePoint {
            frequency_hz: Some(f),
            pressure_pa: None,
            measured,
            model,
            residual: model - measured,
            spread: PHASE_SPREAD_DEG,
        })
        .into_iter()
        .collect();
    all.push(Evidence::new(
        "Chien et al. 2009, Hear Res 249:54 (PMC2874870)",
        "phase of stapes velocity over ear-canal pressure, live ears",
        ("deg", "deg"),
        phase,
        "Whittemore et al. 2004: spread of umbo phase at low frequencies",
    ));
    if let Some(at_rest) = udsp.compliance_at(0.0) {
        let loss: Vec<EvidencePoint> = GYO_GOODE_1987
            .iter()
            .filter_map(|&(mm_h2o, loss_db, sd_db)| {
                // the middle ear below the canal pushes the eardrum medially: p > 0
                let p = mm_h2o * PA_PER_MM_H2O;
                let model = 20.0 * (udsp.compliance_at(p)? / at_rest).log10();
                Some(EvidencePoint {
                    frequency_hz: None,
                    pressure_pa: Some(p),
                    measured: -loss_db,
                    model,
                    residual: model + loss_db,
                    spread: 2.0 * sd_db,
                })
            })
            .collect();
        all.push(Evidence::new(
            "Gyo & Goode 1987, Auris Nasus Larynx 14:131",
            "change of the umbo's vibration below 2 kHz with the middle ear's pressure 100, \
             200 and 300 mmH2O below the canal's, temporal bones; the model's low-frequency \
             limit: its static compliance du/dp there against at rest (the curve whose \
             asymmetry the eardrum's bow was fitted to)",
            ("dB", "dB"),
            loss,
            "the source's SD over 5 bones, ±2 SD",
        ));
    }
    if let Some(a) = udsp.asymmetry() {
        let mut asymmetry = Evidence::new(
            "the source study's atlas (1.76 ± 0.31)",
            "umbo displacement asymmetry |u(-4 kPa)|/|u(+4 kPa)| under static pressure",
            ("ratio", "ratio"),
            vec![EvidencePoint {
                frequency_hz: None,
                pressure_pa: None,
                measured: 1.76,
                model: a,
                residual: a - 1.76,
                spread: 0.31,
            }],
            "the source study's ± 1 SD",
        );
        asymmetry.fitted = Some(
            "the eardrum's radial bow was calibrated to this figure (docs/mechanics.md): \
             not evidence",
        );
        all.push(asymmetry);
    }
    all
}

/// |H_V| (µm/s/Pa) at `f` Hz, interpolated linearly in log-log between the computed points.
fn magnitude_at(tf: &TransferFunction, f: f64) -> Option<f64> {
    log_interpolate(tf, f, |p| p.magnitude_um_s_per_pa.ln()).map(f64::exp)
}

/// A magnitude measured at `f` Hz against the model's, the residual in dB, held to the
/// inter-subject spread.
fn magnitude_point(f: f64, measured: f64, model: f64) -> EvidencePoint {
    EvidencePoint {
        frequency_hz: Some(f),
        pressure_pa: None,
        measured,
        model,
        residual: 20.0 * (model / measured).log10(),
        spread: MAGNITUDE_SPREAD_DB,
    }
}

/// `value` of the transfer function at `f` Hz, interpolated linearly in log frequency
/// between the computed points around it; `None` outside them.
fn log_interpolate(
    tf: &TransferFunction,
    f: f64,
    value: impl Fn(&super::tfa::TfPoint) -> f64,
) -> Option<f64> {
    let points = &tf.points;
    let i = points.windows(2).position(|w| {
        w[0].frequency_hz <= f && f <= w[1].frequency_hz && w[1].frequency_hz > w[0].frequency_hz
    })?;
    let (a, b) = (&points[i], &points[i + 1]);
    let t = (f / a.frequency_hz).ln() / (b.frequency_hz / a.frequency_hz).ln();
    Some(value(a) + t * (value(b) - value(a)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mechanics::Ossicles;
    use crate::mechanics::tfa::{Drive, TfPoint};
    use crate::mechanics::udsp::UdspPoint;

    /// A transfer function that is Goode's geometric-mean curve times `gain`, with a phase of
    /// 72° + `phase` at every frequency.
    fn goode_like(gain: f64, phase: f64) -> TransferFunction {
        let mut points: Vec<TfPoint> = GOODE_1994
            .iter()
            .map(|&(f, v)| TfPoint {
                frequency_hz: f,
                magnitude_um_s_per_pa: v * std::f64::consts::SQRT_2 * gain,
                phase_deg: 72.0 + phase,
                umbo_um_s_per_pa: 0.0,
            })
            .collect();
        points.insert(
            0,
            TfPoint {
                frequency_hz: 250.0,
                magnitude_um_s_per_pa: 50.0,
                phase_deg: 72.0 + phase,
                umbo_um_s_per_pa: 0.0,
            },
        );
        TransferFunction {
            drive: Drive::Eardrum,
            drive_pa: 1.0,
            ossicles: Ossicles::Elastic,
            points,
        }
    }

    /// The entry of the source whose name starts with `name`.
    fn entry<'e>(all: &'e [Evidence], name: &str) -> &'e Evidence {
        all.iter().find(|e| e.source.starts_with(name)).unwrap()
    }

    #[test]
    fn a_model_on_the_measurements_has_no_residual_and_one_off_by_a_factor_has_its_decibels() {
        let exact = evidence(&goode_like(1.0, 0.0), &StaticCurve::default(), 3.0);
        assert_eq!(exact.len(), 4, "no static curve, no static entries");
        // Goode's 1 kHz (106 µm/s/Pa peak-to-peak, √2 times as the geometric mean) against
        // Aibara's 330 µm/s/Pa
        let aibara = entry(&exact, "Aibara");
        let want = 20.0 * (106.0 * std::f64::consts::SQRT_2 / 330.0).log10();
        assert!((aibara.worst_residual - want).abs() < 1e-9, "{aibara:?}");
        let goode = entry(&exact, "Goode");
        assert_eq!(goode.points.len(), 7);
        assert!(
            goode.rms_residual < 1e-9 && goode.within_spread,
            "{goode:?}"
        );
        let chien = entry(&exact, "Chien");
        assert!(chien.rms_residual < 1e-9, "{chien:?}");

        // 4x is +12.04 dB at every point: outside the ±10 dB spread; 20° of phase is outside
        // ±15°
        let off = evidence(&goode_like(4.0, -20.0), &StaticCurve::default(), 3.0);
        let want = 20.0 * 4f64.log10();
        let goode = entry(&off, "Goode");
        assert!((goode.rms_residual - want).abs() < 1e-9);
        assert!((goode.worst_residual - want).abs() < 1e-9);
        assert!(!goode.within_spread);
        let chien = entry(&off, "Chien");
        assert!((chien.worst_residual + 20.0).abs() < 1e-9 && !chien.within_spread);
    }

    #[test]
    fn the_volume_displacement_is_the_piston_velocity_over_omega_times_the_footplate_area() {
        // a stapes moving 6.8e-5 mm³/Pa over 2 mm² at every frequency: velocity
        // 2π f · 3.4e-5 mm/Pa = 2π f · 0.034 µm/Pa
        let area = 2.0;
        let tf = TransferFunction {
            drive: Drive::Eardrum,
            drive_pa: 1.0,
            ossicles: Ossicles::Elastic,
            points: [200.0, 400.0, 800.0, 1000.0]
                .iter()
                .map(|&f| TfPoint {
                    frequency_hz: f,
                    magnitude_um_s_per_pa: 2.0 * std::f64::consts::PI * f * 0.034,
                    phase_deg: 0.0,
                    umbo_um_s_per_pa: 0.0,
                })
                .collect(),
        };
        let on = evidence(&tf, &StaticCurve::default(), area);
        let volume = entry(&on, "Kringlebotn");
        assert_eq!(volume.points.len(), 6);
        // a velocity proportional to f is a line in log-log, which the interpolation between
        // the computed points keeps exactly
        assert!(
            volume.rms_residual < 1e-9 && volume.within_spread,
            "{volume:?}"
        );
        // the same stapes on a footplate 4 times larger moves 4 times the volume: +12 dB
        let large = evidence(&tf, &StaticCurve::default(), 4.0 * area);
        let volume_large = entry(&large, "Kringlebotn");
        for (a, b) in volume.points.iter().zip(&volume_large.points) {
            assert!((b.residual - a.residual - 20.0 * 4f64.log10()).abs() < 1e-9);
        }
        assert!(!volume_large.within_spread);
    }

    /// A static curve u(p) on the default sweep whose compliance falls by `db_per_pa` dB per
    /// Pa (rises for p < 0).
    fn stiffening_curve(db_per_pa: f64) -> StaticCurve {
        // du/dp = c0·10^(−k p / 20) = c0·e^(−s p): u = c0·(1 − e^(−s p))/s
        let (c0, s) = (1e-4, db_per_pa * std::f64::consts::LN_10 / 20.0);
        let u = |p: f64| {
            if s == 0.0 {
                c0 * p
            } else {
                c0 * (1.0 - (-s * p).exp()) / s
            }
        };
        StaticCurve {
            points: (-16..=16)
                .map(|k| {
                    let p = 250.0 * k as f64;
                    UdspPoint {
                        pressure_pa: p,
                        umbo_mm: u(p),
                        iterations: 1,
                        relative_residual: 0.0,
                    }
                })
                .collect(),
            ..StaticCurve::default()
        }
    }

    #[test]
    fn the_static_pressure_losses_are_read_from_the_compliance_and_a_linear_ear_has_none() {
        let tf = goode_like(1.0, 0.0);
        let gyo = |curve: &StaticCurve| {
            evidence(&tf, curve, 3.0)
                .into_iter()
                .find(|e| e.source.starts_with("Gyo & Goode"))
                .unwrap()
        };
        // a linear ear loses nothing: its residuals are the measured losses, 13.1 dB at
        // 300 mmH2O outside 2 SD (3.6 dB)
        let linear = gyo(&stiffening_curve(0.0));
        assert_eq!(linear.points.len(), 3);
        for (point, (mm, loss, sd)) in linear.points.iter().zip(GYO_GOODE_1987) {
            assert!((point.pressure_pa.unwrap() - mm * PA_PER_MM_H2O).abs() < 1e-9);
            assert!(point.model.abs() < 1e-6 && (point.residual - loss).abs() < 1e-6);
            assert_eq!(point.spread, 2.0 * sd);
        }
        assert!(!linear.within_spread);
        // an ear losing k dB per Pa: k·p at each pressure (the curve's own interpolation
        // error under 0.01 dB); 5 dB at 100 mmH2O fits the first point
        let k = 5.0 / (100.0 * PA_PER_MM_H2O);
        let stiffening = gyo(&stiffening_curve(k));
        for point in &stiffening.points {
            let want = -k * point.pressure_pa.unwrap();
            assert!(
                (point.model - want).abs() < 0.01,
                "{point:?} against {want}"
            );
        }
        assert!(stiffening.points[0].residual.abs() < 0.01);
        // no static curve, no entry
        assert!(
            !evidence(&tf, &StaticCurve::default(), 3.0)
                .iter()
                .any(|e| e.source.starts_with("Gyo"))
        );
    }

    #[test]
    fn interpolation_is_linear_in_log_frequency_and_refuses_outside_the_points() {
        let tf = goode_like(1.0, 0.0);
        // half-way in log frequency between 400 and 1600 is 800
        let mid = log_interpolate(&tf, 800.0, |p| p.frequency_hz.ln()).unwrap();
        assert!((mid - 800f64.ln()).abs() < 1e-12);
        assert!(log_interpolate(&tf, 100.0, |p| p.phase_deg).is_none());
        assert!(log_interpolate(&tf, 7000.0, |p| p.phase_deg).is_none());
    }
}
