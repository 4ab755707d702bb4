//! Transfer function analysis (TFA): the stapes velocity transfer function
//! H_V(f) = V_stapes / P_TM (ASTM F2504; docs/mechanics.md) from harmonic solves
//! linearised about the rest shape,
//! [K(1 + iωβ) + iω(αM + C_cochlea) − ω²M] û = F̂.
//!
//! Drive: a uniform pressure on the lateral eardrum face (default 0.632 Pa rms = 90 dB SPL, as
//! the source study), or the equivalent force (pressure × eardrum area) on the umbo along the
//! medial axis ("malleus drive"). V_stapes is the piston velocity: the area-weighted mean over
//! the medial footplate face of iω û·n_fp, n_fp into the vestibule. Magnitude in µm/s per Pa
//! of drive, phase in degrees (unwrapped from the lowest frequency; +90° = velocity leads the
//! pressure, the stiffness-controlled regime).

use faer::c64;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use super::boundary::{MechanicalSystem, Ossicles};
use super::error::MechanicsError;
use crate::fem::{ComplexDisplacement, HarmonicSolver, PressureLoad, SweepOptions};
use crate::progress::Reporter;

/// The source study's sound pressure: 90 dB SPL re 20 µPa, in Pa rms.
pub const DRIVE_PA: f64 = 0.632;

/// Where the sound drives the middle ear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Drive {
    /// Pressure on the lateral face of the eardrum.
    Eardrum,
    /// The eardrum's total force (pressure × area) applied at the umbo, medially.
    Umbo,
}

/// What to compute.
#[derive(Debug, Clone, PartialEq)]
pub struct TfaOptions {
    pub frequencies_hz: Vec<f64>,
    pub drive: Drive,
    /// Drive pressure (Pa); the response is linear, so it only scales the displacements.
    pub drive_pa: f64,
    /// How the frequencies are solved: from one reduced model checked on the full system at
    /// each frequency (`fem::SweepOptions`, the default), or `None`: one sparse factorisation per
    /// frequency.
    pub reduced: Option<SweepOptions>,
    pub ossicles: Ossicles,
}

impl Default for TfaOptions {
    fn default() -> Self {
        TfaOptions {
            frequencies_hz: third_octaves(250.0, 8000.0),
            drive: Drive::Eardrum,
            drive_pa: DRIVE_PA,
            reduced: Some(SweepOptions::default()),
            ossicles: Ossicles::Elastic,
        }
    }
}

/// Base-2 one-third-octave frequencies 1000·2^(k/3) Hz within [lo, hi] (250 and 8000 Hz are
/// exact members).
pub fn third_octaves(lo: f64, hi: f64) -> Vec<f64> {
    (-30..=30)
        .map(|k| 1000.0 * 2f64.powf(k as f64 / 3.0))
        .filter(|f| *f >= lo * (1.0 - 1e-9) && *f <= hi * (1.0 + 1e-9))
        .collect()
}

/// One frequency of the transfer function.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct TfPoint {
    pub frequency_hz: f64,
    /// |H_V| in µm/s/Pa.
    pub magnitude_um_s_per_pa: f64,
    /// ∠H_V in degrees, unwrapped along frequency.
    pub phase_deg: f64,
    /// |umbo velocity along the medial axis| / drive, µm/s/Pa (for diagnosis).
    pub umbo_um_s_per_pa: f64,
}

impl TfPoint {
    /// Magnitude in dB re 1 µm/s/Pa.
    pub fn db(&self) -> f64 {
        20.0 * self.magnitude_um_s_per_pa.log10()
    }
}

/// The stapes velocity transfer function at the requested frequencies.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct TransferFunction {
    pub drive: Drive,
    pub drive_pa: f64,
    /// The ossicles' model the solves used.
    #[serde(default)]
    pub ossicles: Ossicles,
    pub points: Vec<TfPoint>,
}

impl TransferFunction {
    /// The point at `f` Hz (within 0.1 %), if computed.
    pub fn at(&self, f: f64) -> Option<&TfPoint> {
        self.points
            .iter()
            .find(|p| (p.frequency_hz - f).abs() <= 1e-3 * f)
    }

    /// Frequency (Hz) and magnitude (µm/s/Pa) of the maximum, refined by a parabola through
    /// the largest sample and its neighbours in (log f, dB).
    pub fn peak(&self) -> Option<(f64, f64)> {
        let (i, _) = self.points.iter().enumerate().max_by(|a, b| {
            a.1.magnitude_um_s_per_pa
                .total_cmp(&b.1.magnitude_um_s_per_pa)
        })?;
        let p = &self.points;
        if i == 0 || i + 1 == p.len() {
            return Some((p[i].frequency_hz, p[i].magnitude_um_s_per_pa));
        }
        let (x0, x1, x2) = (
            p[i - 1].frequency_hz.ln(),
            p[i].frequency_hz.ln(),
            p[i + 1].frequency_hz.ln(),
        );
        let (y0, y1, y2) = (p[i - 1].db(), p[i].db(), p[i + 1].db());
        // vertex of the parabola through three points
        let d = (x0 - x1) * (x0 - x2) * (x1 - x2);
        let a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / d;
        let b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / d;
        if a >= 0.0 {
            return Some((p[i].frequency_hz, p[i].magnitude_um_s_per_pa));
        }
        let xv = (-b / (2.0 * a)).clamp(x0, x2);
        let c = y1 - a * x1 * x1 - b * x1;
        let db = a * xv * xv + b * xv + c;
        Some((xv.exp(), 10f64.powf(db / 20.0)))
    }

    /// Edges (Hz) of the band around the maximum where |H_V| stays within `within_db` of it,
    /// each interpolated linearly in (log f, dB) between the samples that straddle it, or the
    /// first or last frequency where the curve does not fall that far.
    pub fn maximum_band(&self, within_db: f64) -> Option<(f64, f64)> {
        let p = &self.points;
        let (i, top) = p
            .iter()
            .enumerate()
            .filter(|(_, q)| q.magnitude_um_s_per_pa > 0.0 && q.frequency_hz > 0.0)
            .max_by(|a, b| {
                a.1.magnitude_um_s_per_pa
                    .total_cmp(&b.1.magnitude_um_s_per_pa)
            })?;
        let level = top.db() - within_db;
        // the edge between the last sample inside the band (`inside`) and the next one out
        let edge = |inside: &TfPoint, outside: Option<&TfPoint>| match outside {
            Some(out) if out.db() < level => {
                let t = (inside.db() - level) / (inside.db() - out.db());
                inside.frequency_hz.ln() + t * (out.frequency_hz.ln() - inside.frequency_hz.ln())
            }
            _ => inside.frequency_hz.ln(),
        };
        let mut lo = i;
        while lo > 0 && p[lo - 1].db() >= level {
            lo -= 1;
        }
        let mut hi = i;
        while hi + 1 < p.len() && p[hi + 1].db() >= level {
            hi += 1;
        }
        let low = edge(&p[lo], lo.checked_sub(1).map(|k| &p[k])).exp();
        let high = edge(&p[hi], p.get(hi + 1)).exp();
        (low.is_finite() && high.is_finite()).then_some((low, high))
    }

    /// Centre (Hz, geometric) of [`maximum_band`](Self::maximum_band).
    ///
    /// Where the frequency of a maximum can jump by a whole sample spacing for a fraction of
    /// a dB (a flat top, two samples nearly level), this moves with the curve: it is what the
    /// consistency gate compares (`verdict::relative_verdict`).
    pub fn maximum_band_centre(&self, within_db: f64) -> Option<f64> {
        self.maximum_band(within_db)
            .map(|(low, high)| (low * high).sqrt())
    }
}

/// Nodal force amplitudes (µN) of the drive.
fn drive_forces(system: &MechanicalSystem, drive: Drive, p: f64) -> Vec<Vector3<f64>> {
    let x = system.model.rest_positions();
    let mut f = vec![Vector3::zeros(); x.len()];
    match drive {
        // the lateral normals point into the canal: canal pressure pushes against them
        Drive::Eardrum => PressureLoad {
            triangles: &system.eardrum,
            pressure: -p,
        }
        .add_forces(x, &mut f),
        Drive::Umbo => {
            let total = system.medial * (p * system.eardrum_area_mm2);
            for (&v, &w) in system.umbo.nodes.iter().zip(&system.umbo.weights) {
                f[v as usize] += total * w;
            }
        }
    }
    f
}

/// The piston velocity of the footplate and the umbo's medial velocity (µm/s per Pa of drive)
/// of the displacement amplitudes `u` at angular frequency `omega`.
fn response(
    system: &MechanicalSystem,
    u: &[ComplexDisplacement],
    omega: f64,
    drive_pa: f64,
) -> (c64, c64) {
    let along = |v: u32, w: f64, n: &Vector3<f64>| {
        let d = u[v as usize];
        (d[0] * n.x + d[1] * n.y + d[2] * n.z) * w
    };
    let n = system.footplate_normal;
    let piston = system
        .footplate
        .iter()
        .map(|&(v, w)| along(v, w, &n))
        .sum::<c64>();
    let umbo = system
        .umbo
        .nodes
        .iter()
        .zip(&system.umbo.weights)
        .map(|(&v, &w)| along(v, w, &system.medial))
        .sum::<c64>();
    // velocity = iω û (mm/s) → µm/s per Pa of drive
    let to_velocity = c64::new(0.0, omega * 1e3 / drive_pa);
    (piston * to_velocity, umbo * to_velocity)
}

/// The stapes velocity transfer function of `system` (`options.reduced`: one reduced model
/// for all frequencies, or the frequencies solved directly in parallel), reported to
/// `progress`.
pub fn transfer_function(
    system: &MechanicalSystem,
    options: &TfaOptions,
    progress: &dyn Reporter,
) -> Result<TransferFunction, MechanicsError> {
    if !(options.drive_pa.is_finite() && options.drive_pa > 0.0) {
        return Err(MechanicsError::InvalidOption {
            what: "drive pressure (Pa)",
            value: options.drive_pa,
            expected: "finite and > 0",
        });
    }
    if let Some(f) = options
        .frequencies_hz
        .iter()
        .find(|f| !(f.is_finite() && **f > 0.0))
    {
        return Err(MechanicsError::InvalidOption {
            what: "frequency (Hz)",
            value: *f,
            expected: "finite and > 0",
        });
    }
    let solver = match options.ossicles {
        Ossicles::Elastic => HarmonicSolver::new(
            &system.model,
            &system.fixed,
            &system.node_stiffness,
            &system.dashpots,
            system.rayleigh,
        ),
        Ossicles::Rigid => HarmonicSolver::with_rigid_bodies(
            &system.model,
            &system.fixed,
            &system.node_stiffness,
            &system.dashpots,
            system.rayleigh,
            &system.ossicles,
        ),
    }
    .map_err(MechanicsError::solve("harmonic system"))?;
    let force = drive_forces(system, options.drive, options.drive_pa);
    let count = options.frequencies_hz.len();
    let task = progress.task("TFA", count as u64);
    let omegas: Vec<f64> = options
        .frequencies_hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .collect();
    let (displacements, how) = match &options.reduced {
        Some(sweep) => {
            let s = solver
                .sweep(&omegas, &force, sweep)
                .map_err(MechanicsError::solve("harmonic sweep"))?;
            task.inc(count as u64);
            let r = &s.report;
            let how = format!(
                "a reduced model of {} from {} factorisations, largest relative residual {:.1e}, {} solved directly",
                r.basis_size,
                r.shifts_hz.len(),
                r.max_relative_residual,
                r.direct_solves
            );
            (s.responses, how)
        }
        None => {
            let u = omegas
                .par_iter()
                .zip(&options.frequencies_hz)
                .map(|(&omega, f)| {
                    let u = solver
                        .solve(omega, &force)
                        .map_err(MechanicsError::solve(format!("harmonic solve at {f} Hz")));
                    task.inc(1);
                    u
                })
                .collect::<Result<Vec<_>, MechanicsError>>()?;
            (u, "one factorisation each".to_string())
        }
    };
    task.finish(&format!("{count} frequencies solved ({how})"));
    let responses: Vec<(c64, c64)> = omegas
        .iter()
        .zip(&displacements)
        .map(|(&omega, u)| response(system, u, omega, options.drive_pa))
        .collect();
    let mut points = Vec::with_capacity(responses.len());
    let mut previous: Option<f64> = None;
    for (&f, (h, umbo)) in options.frequencies_hz.iter().zip(&responses) {
        let mut phase = h.im.atan2(h.re).to_degrees();
        if let Some(prev) = previous {
            phase -= 360.0 * ((phase - prev) / 360.0).round();
        }
        previous = Some(phase);
        points.push(TfPoint {
            frequency_hz: f,
            magnitude_um_s_per_pa: h.norm(),
            phase_deg: phase,
            umbo_um_s_per_pa: umbo.norm(),
        });
    }
    Ok(TransferFunction {
        drive: options.drive,
        drive_pa: options.drive_pa,
        ossicles: options.ossicles,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(points: &[(f64, f64)]) -> TransferFunction {
        TransferFunction {
            drive: Drive::Eardrum,
            drive_pa: 1.0,
            ossicles: Ossicles::Elastic,
            points: points
                .iter()
                .map(|&(f, m)| TfPoint {
                    frequency_hz: f,
                    magnitude_um_s_per_pa: m,
                    phase_deg: 0.0,
                    umbo_um_s_per_pa: 0.0,
                })
                .collect(),
        }
    }

    /// A maximum symmetric in log f (a parabola in dB, 6 dB per squared natural log of the
    /// frequency ratio) whose top lies midway between two one-third-octave samples: the
    /// samples are symmetric about it, so the band's centre is its frequency.
    #[test]
    fn the_band_centre_of_a_symmetric_maximum_is_its_frequency() {
        let f0 = 1000.0 * 2f64.powf(1.0 / 6.0);
        let db = |f: f64| 40.0 - 6.0 * (f / f0).ln().powi(2);
        let tf = curve(
            &third_octaves(250.0, 8000.0)
                .into_iter()
                .map(|f| (f, 10f64.powf(db(f) / 20.0)))
                .collect::<Vec<_>>(),
        );
        for within in [0.5, 1.0, 3.0] {
            let centre = tf.maximum_band_centre(within).unwrap();
            assert!((centre / f0 - 1.0).abs() < 1e-9, "{within} dB: {centre}");
        }
    }

    /// Two samples of a flat top three tenths of a dB apart trade places: the parabola's
    /// maximum moves by 2.8 % (689 → 708 Hz), the band's centre by 0.04 %.
    #[test]
    fn a_flat_top_moves_the_band_centre_less_than_the_maximum() {
        let shape = |a: f64, b: f64| {
            curve(&[
                (400.0, 120.0),
                (500.0, 166.0),
                (630.0, a),
                (794.0, b),
                (1000.0, 130.0),
                (1260.0, 100.0),
            ])
        };
        let (left, right) = (shape(168.3, 168.0), shape(168.0, 168.3));
        let (fl, fr) = (left.peak().unwrap().0, right.peak().unwrap().0);
        let (cl, cr) = (
            left.maximum_band_centre(1.0).unwrap(),
            right.maximum_band_centre(1.0).unwrap(),
        );
        assert!(fr / fl > 1.02, "the parabola's maxima {fl} and {fr}");
        assert!(
            (cr / cl - 1.0).abs() < 1e-3,
            "the band's centres {cl} and {cr}"
        );
        // the band runs from between 400 and 500 Hz to between 794 and 1000 Hz, each edge
        // where the straight line in (ln f, dB) between those samples crosses the level
        let db = |m: f64| 20.0 * m.log10();
        let level = db(168.3) - 1.0;
        let crossing = |(f_in, m_in): (f64, f64), (f_out, m_out): (f64, f64)| {
            let t = (db(m_in) - level) / (db(m_in) - db(m_out));
            f_in.ln() + t * (f_out.ln() - f_in.ln())
        };
        let low = crossing((500.0, 166.0), (400.0, 120.0));
        let high = crossing((794.0, 168.0), (1000.0, 130.0));
        let expected = (0.5 * (low + high)).exp();
        assert!((cl / expected - 1.0).abs() < 1e-12, "{cl} vs {expected}");
    }

    /// A maximum at the end of the sweep: the band runs to the last sample.
    #[test]
    fn a_band_that_does_not_close_ends_at_the_last_sample() {
        let tf = curve(&[(250.0, 10.0), (500.0, 80.0), (1000.0, 105.0)]);
        let centre = tf.maximum_band_centre(1.0).unwrap();
        // the low edge where the level, 1 dB under 105, crosses the line from 1000 to 500 Hz
        let (top, out) = (20.0 * 105f64.log10(), 20.0 * 80f64.log10());
        let low = 1000f64.ln() + (1.0 / (top - out)) * (500f64.ln() - 1000f64.ln());
        let expected = (0.5 * (low + 1000f64.ln())).exp();
        assert!(
            (centre / expected - 1.0).abs() < 1e-12,
            "{centre} vs {expected}"
        );
        assert_eq!(curve(&[]).maximum_band_centre(1.0), None);
    }
}
