//! Verdicts: each gate with its measured value, its band and the outcome.
//!
//! Where the bands come from: docs/mechanics.md, "Where the gates come from".
//!
//! Literature gates (an atlas; bands from Goode et al. 1994
//! temporal-bone data widened by the ±10 dB inter-subject spread of Whittemore et al. 2004):
//! |H_V| inside the band at 250, 500, 1k, 2k, 4k, 8k Hz; slope +3…+9 dB/octave from 250 to
//! 500 Hz; maximum between 0.6 and 1.5 kHz; |H_V(4 kHz)| 8…25 dB below the maximum; UDSP
//! asymmetry |u(−4 kPa)|/|u(+4 kPa)| in [1.45, 2.07] (the study's 1.76 ± 0.31) and a
//! monotonic, sign-preserving response.
//!
//! Consistency with the atlas (a package against the atlas it came from; these show the
//! registration kept the atlas's behaviour, not that the model is right, which is the
//! evidence's subject, `evidence`): |ΔdB| ≤ 3 at every
//! frequency, the centre of the band within 1 dB of the maximum in [0.8, 1.25] times the
//! atlas's (not the maximum's own frequency, which a flat top lets jump between samples for a
//! fraction of a dB), |Δphase| ≤ 45° up to 4 kHz, umbo
//! displacement within ±25 % at ±1, ±2, ±4 kPa, asymmetry in band and on the same side.

use serde::Serialize;

use super::tfa::TransferFunction;
use super::udsp::{GATE_PRESSURES_PA, StaticCurve};

/// Goode-band edges (µm/s/Pa) at the gate frequencies: (Hz, low, high); their derivation is
/// in docs/mechanics.md.
pub const GOODE_BAND: [(f64, f64, f64); 6] = [
    (250.0, 11.5, 229.0),
    (500.0, 24.0, 477.0),
    (1000.0, 33.5, 671.0),
    (2000.0, 14.7, 294.0),
    (4000.0, 6.2, 124.0),
    (8000.0, 3.0, 60.0),
];
/// Low-frequency slope from 250 to 500 Hz (dB/octave).
pub const SLOPE_DB_PER_OCTAVE: (f64, f64) = (3.0, 9.0);
/// Frequency of the maximum of |H_V| (Hz).
pub const PEAK_HZ: (f64, f64) = (600.0, 1500.0);
/// Drop from the maximum to 4 kHz (dB).
pub const ROLL_OFF_DB: (f64, f64) = (8.0, 25.0);
/// UDSP asymmetry ratio |u(−4 kPa)|/|u(+4 kPa)|.
pub const ASYMMETRY: (f64, f64) = (1.45, 2.07);
/// Package vs atlas: TF magnitude (dB), ratio of the maximum's band centres (the band within
/// `MAXIMUM_BAND_DB` of the maximum), phase (degrees, up to `PHASE_UP_TO_HZ`), umbo
/// displacement ratio.
pub const RELATIVE_DB: f64 = 3.0;
pub const MAXIMUM_BAND_DB: f64 = 1.0;
pub const RELATIVE_BAND_CENTRE: (f64, f64) = (0.8, 1.25);
pub const RELATIVE_PHASE_DEG: f64 = 45.0;
pub const PHASE_UP_TO_HZ: f64 = 4000.0;
pub const RELATIVE_UMBO: (f64, f64) = (0.75, 1.25);

/// The kind of an atlas's verdict: bands from the literature, a sanity net.
pub const LITERATURE: &str = "literature bands";
/// The kind of a package's verdict: against the atlas it was registered from.
pub const CONSISTENCY: &str = "consistency with the atlas";

/// One check: what was measured, the band it must lie in, and whether it does.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Gate {
    pub name: String,
    pub value: f64,
    pub low: f64,
    pub high: f64,
    pub unit: &'static str,
    pub passed: bool,
}

impl Gate {
    fn band(
        name: impl Into<String>,
        value: f64,
        (low, high): (f64, f64),
        unit: &'static str,
    ) -> Self {
        Gate {
            name: name.into(),
            value,
            low,
            high,
            unit,
            passed: value.is_finite() && value >= low && value <= high,
        }
    }
}

/// A list of gates; it passes when all do.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    pub kind: &'static str,
    pub passed: bool,
    pub gates: Vec<Gate>,
}

impl Verdict {
    fn new(kind: &'static str, gates: Vec<Gate>) -> Self {
        Verdict {
            kind,
            passed: !gates.is_empty() && gates.iter().all(|g| g.passed),
            gates,
        }
    }

    /// The failed gates.
    pub fn failures(&self) -> impl Iterator<Item = &Gate> {
        self.gates.iter().filter(|g| !g.passed)
    }
}

fn magnitude(tf: &TransferFunction, f: f64) -> f64 {
    tf.at(f).map_or(f64::NAN, |p| p.magnitude_um_s_per_pa)
}

/// The atlas against the literature bands. A quantity that was not computed (a frequency
/// or pressure missing from the sweep) fails its gate.
pub fn literature_verdict(tf: &TransferFunction, udsp: &StaticCurve) -> Verdict {
    let mut gates: Vec<Gate> = GOODE_BAND
        .iter()
        .map(|&(f, lo, hi)| {
            Gate::band(
                format!("|H_V| at {f:.0} Hz (Goode band)"),
                magnitude(tf, f),
                (lo, hi),
                "um/s/Pa",
            )
        })
        .collect();
    let slope = 20.0 * (magnitude(tf, 500.0) / magnitude(tf, 250.0)).log10();
    gates.push(Gate::band(
        "slope 250-500 Hz",
        slope,
        SLOPE_DB_PER_OCTAVE,
        "dB/octave",
    ));
    let (peak_hz, peak) = tf.peak().unwrap_or((f64::NAN, f64::NAN));
    gates.push(Gate::band("frequency of max |H_V|", peak_hz, PEAK_HZ, "Hz"));
    gates.push(Gate::band(
        "drop from max to 4 kHz",
        20.0 * (peak / magnitude(tf, 4000.0)).log10(),
        ROLL_OFF_DB,
        "dB",
    ));
    gates.push(Gate::band(
        "UDSP asymmetry |u(-4 kPa)|/|u(+4 kPa)|",
        udsp.asymmetry().unwrap_or(f64::NAN),
        ASYMMETRY,
        "",
    ));
    gates.push(Gate::band(
        "UDSP monotonic and sign-preserving (1 = yes)",
        if udsp.monotonic() { 1.0 } else { 0.0 },
        (1.0, 1.0),
        "",
    ));
    Verdict::new(LITERATURE, gates)
}

/// A package against its atlas (`reference`). Without a reference static-pressure curve
/// (not computed), only the transfer-function gates.
pub fn relative_verdict(
    tf: &TransferFunction,
    udsp: &StaticCurve,
    reference_tf: &TransferFunction,
    reference_udsp: &StaticCurve,
) -> Verdict {
    let mut gates = Vec::new();
    for r in &reference_tf.points {
        let p = tf.at(r.frequency_hz);
        let db = p.map_or(f64::NAN, |p| p.db() - r.db());
        gates.push(Gate::band(
            format!("|H_V| vs atlas at {:.0} Hz", r.frequency_hz),
            db,
            (-RELATIVE_DB, RELATIVE_DB),
            "dB",
        ));
        if r.frequency_hz <= PHASE_UP_TO_HZ * (1.0 + 1e-9) {
            let dphi = p.map_or(f64::NAN, |p| p.phase_deg - r.phase_deg);
            gates.push(Gate::band(
                format!("phase vs atlas at {:.0} Hz", r.frequency_hz),
                dphi,
                (-RELATIVE_PHASE_DEG, RELATIVE_PHASE_DEG),
                "deg",
            ));
        }
    }
    let ratio = match (
        tf.maximum_band_centre(MAXIMUM_BAND_DB),
        reference_tf.maximum_band_centre(MAXIMUM_BAND_DB),
    ) {
        (Some(f), Some(f0)) => f / f0,
        _ => f64::NAN,
    };
    gates.push(Gate::band(
        format!("centre of the band within {MAXIMUM_BAND_DB} dB of the maximum / the atlas's"),
        ratio,
        RELATIVE_BAND_CENTRE,
        "",
    ));
    if reference_udsp.points.is_empty() {
        // the static-pressure curve was not asked for: no UDSP gates
        return Verdict::new(CONSISTENCY, gates);
    }
    for p in GATE_PRESSURES_PA {
        let r = match (udsp.at(p), reference_udsp.at(p)) {
            (Some(u), Some(u0)) => u / u0,
            _ => f64::NAN,
        };
        gates.push(Gate::band(
            format!("umbo displacement / atlas at {p:.0} Pa"),
            r,
            RELATIVE_UMBO,
            "",
        ));
    }
    gates.push(Gate::band(
        "UDSP asymmetry |u(-4 kPa)|/|u(+4 kPa)|",
        udsp.asymmetry().unwrap_or(f64::NAN),
        ASYMMETRY,
        "",
    ));
    let same_side = match (udsp.asymmetry(), reference_udsp.asymmetry()) {
        (Some(a), Some(a0)) => (a > 1.0) == (a0 > 1.0),
        _ => false,
    };
    gates.push(Gate::band(
        "larger side as in the atlas (1 = yes)",
        if same_side { 1.0 } else { 0.0 },
        (1.0, 1.0),
        "",
    ));
    gates.push(loaded_to_the_end(udsp));
    Verdict::new(CONSISTENCY, gates)
}

/// Whether every static-pressure increment reached equilibrium (`StaticCurve::failure` says
/// where one did not).
fn loaded_to_the_end(udsp: &StaticCurve) -> Gate {
    Gate::band(
        "static pressure carried to every load (1 = yes)",
        if udsp.failure.is_none() { 1.0 } else { 0.0 },
        (1.0, 1.0),
        "",
    )
}
