//! The changes a pathology makes to the ear's response, against the normal ear, beside the
//! changes temporal bones showed: the stapes's and umbo's velocity over ear-canal pressure,
//! in dB, at the transfer function's octaves. A condition is a negative control of the
//! normal-ear bands (it must fail them); these say whether it moves the response as the
//! measured pathology does. Sources and figures: docs/mechanics.md, "Pathologies".

use serde::Serialize;

use super::condition::Condition;
use super::tfa::TransferFunction;

/// Which velocity a change is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Velocity {
    Stapes,
    Umbo,
}

impl Velocity {
    pub fn name(self) -> &'static str {
        match self {
            Velocity::Stapes => "stapes",
            Velocity::Umbo => "umbo",
        }
    }
}

/// One change the condition makes, with the range temporal bones showed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConditionChange {
    pub velocity: Velocity,
    pub frequency_hz: f64,
    /// 20·log10 of the condition's velocity over the normal ear's.
    pub model_db: f64,
    /// The measured range (dB); `None` is an open end.
    pub low_db: Option<f64>,
    pub high_db: Option<f64>,
    pub within: bool,
    pub source: &'static str,
}

/// What a measurement says of one velocity at some frequencies.
#[derive(Clone, Copy)]
struct Measured {
    velocity: Velocity,
    frequencies_hz: &'static [f64],
    range: Range,
    source: &'static str,
}

#[derive(Clone, Copy)]
enum Range {
    /// Between two figures (dB), either end open.
    Between(Option<f64>, Option<f64>),
    /// Within this many dB of the stapes's own change at the same frequency.
    AboutTheStapes(f64),
}

/// The transfer function's octaves up to 1 kHz, where fixations act most.
const LOW: &[f64] = &[250.0, 500.0, 1000.0];
/// Its octaves from 250 Hz to 4 kHz.
const OCTAVES: &[f64] = &[250.0, 500.0, 1000.0, 2000.0, 4000.0];

/// The changes temporal bones showed under `condition` (Nakajima, Ravicz, Merchant, Peake &
/// Rosowski 2005 and the others from their abstracts).
fn measured(condition: Condition) -> Vec<Measured> {
    match condition {
        Condition::Normal => Vec::new(),
        Condition::StapesFixation => vec![
            Measured {
                velocity: Velocity::Stapes,
                frequencies_hz: LOW,
                range: Range::Between(Some(-55.0), Some(-35.0)),
                source: "Nakajima et al. 2005, Hear Res 204:60, temporal bones: the stapes's \
                         velocity falls by up to 40-50 dB (taken ±5 dB)",
            },
            Measured {
                velocity: Velocity::Umbo,
                frequencies_hz: OCTAVES,
                range: Range::Between(Some(-10.0), Some(0.0)),
                source: "Nakajima et al. 2005: the umbo's by under 10 dB",
            },
        ],
        Condition::MalleusFixation => vec![
            Measured {
                velocity: Velocity::Stapes,
                frequencies_hz: LOW,
                range: Range::Between(Some(-16.0), Some(-5.0)),
                source: "Huber et al. 2003, 5 temporal bones: about 10 dB with the anterior \
                         mallear ligament fixed; Nakajima, Rosowski et al. 2005, Laryngoscope \
                         115:147: 0-8 dB with it stiffened, 10-30 dB with a bony bar to the head",
            },
            Measured {
                velocity: Velocity::Umbo,
                frequencies_hz: LOW,
                range: Range::AboutTheStapes(6.0),
                source: "Nakajima et al. 2005, Hear Res 204:60: the umbo by about as much as \
                         the stapes (taken ±6 dB of it)",
            },
        ],
        Condition::IsDisarticulation => vec![
            Measured {
                velocity: Velocity::Stapes,
                frequencies_hz: OCTAVES,
                range: Range::Between(None, Some(-40.0)),
                source: "the stapes loses tens of dB (direction only, no verified measurement \
                         of a complete disarticulation)",
            },
            Measured {
                velocity: Velocity::Umbo,
                frequencies_hz: LOW,
                range: Range::Between(Some(0.0), None),
                source: "the umbo, no longer loaded by the cochlea, moves more (direction only)",
            },
        ],
    }
}

/// The changes `ear` (the transfer function under `condition`) makes against `normal`, each
/// against what temporal bones showed; a frequency either lacks is left out.
pub fn condition_changes(
    condition: Condition,
    normal: &TransferFunction,
    ear: &TransferFunction,
) -> Vec<ConditionChange> {
    let change = |velocity: Velocity, f: f64| -> Option<f64> {
        let (n, e) = (normal.at(f)?, ear.at(f)?);
        let ratio = match velocity {
            Velocity::Stapes => e.magnitude_um_s_per_pa / n.magnitude_um_s_per_pa,
            Velocity::Umbo => e.umbo_um_s_per_pa / n.umbo_um_s_per_pa,
        };
        let db = 20.0 * ratio.log10();
        db.is_finite().then_some(db)
    };
    measured(condition)
        .into_iter()
        .flat_map(|m| m.frequencies_hz.iter().map(move |&f| (m, f)))
        .filter_map(|(m, f)| {
            let model_db = change(m.velocity, f)?;
            let (low_db, high_db) = match m.range {
                Range::Between(low, high) => (low, high),
                Range::AboutTheStapes(db) => {
                    let stapes = change(Velocity::Stapes, f)?;
                    (Some(stapes - db), Some(stapes + db))
                }
            };
            let within = low_db.is_none_or(|low| model_db >= low)
                && high_db.is_none_or(|high| model_db <= high);
            Some(ConditionChange {
                velocity: m.velocity,
                frequency_hz: f,
                model_db,
                low_db,
                high_db,
                within,
                source: m.source,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mechanics::Ossicles;
    use crate::mechanics::tfa::{Drive, TfPoint};

    /// A transfer function with the stapes and umbo velocities `stapes` and `umbo` at every
    /// octave from 250 Hz to 4 kHz.
    fn flat(stapes: f64, umbo: f64) -> TransferFunction {
        TransferFunction {
            drive: Drive::Eardrum,
            drive_pa: 1.0,
            ossicles: Ossicles::Elastic,
            points: OCTAVES
                .iter()
                .map(|&f| TfPoint {
                    frequency_hz: f,
                    magnitude_um_s_per_pa: stapes,
                    phase_deg: 0.0,
                    umbo_um_s_per_pa: umbo,
                })
                .collect(),
        }
    }

    #[test]
    fn a_change_is_the_velocity_ratio_in_db_held_to_its_measured_range() {
        let normal = flat(100.0, 200.0);
        // the stapes 100 times slower (−40 dB), the umbo 2 times (−6.02 dB)
        let fixed = condition_changes(Condition::StapesFixation, &normal, &flat(1.0, 100.0));
        assert_eq!(fixed.len(), LOW.len() + OCTAVES.len());
        for c in &fixed {
            let want = match c.velocity {
                Velocity::Stapes => -40.0,
                Velocity::Umbo => -20.0 * 2f64.log10(),
            };
            assert!((c.model_db - want).abs() < 1e-9 && c.within, "{c:?}");
        }
        // the umbo following the stapes within 6 dB, or not
        let malleus = |umbo: f64| {
            condition_changes(Condition::MalleusFixation, &normal, &flat(31.6, umbo))
                .into_iter()
                .filter(|c| c.velocity == Velocity::Umbo)
                .all(|c| c.within)
        };
        assert!(malleus(63.2), "−10 dB at both");
        assert!(
            !malleus(200.0),
            "the umbo unchanged while the stapes loses 10 dB"
        );
        // open ends: a disarticulated stapes must lose more than 40 dB, the umbo gain
        let loose = condition_changes(Condition::IsDisarticulation, &normal, &flat(0.5, 300.0));
        assert!(loose.iter().all(|c| c.within), "{loose:?}");
        let held = condition_changes(Condition::IsDisarticulation, &normal, &flat(2.0, 300.0));
        assert!(
            held.iter()
                .any(|c| !c.within && c.velocity == Velocity::Stapes)
        );
        // the normal ear has nothing to compare; a missing frequency is left out
        assert!(condition_changes(Condition::Normal, &normal, &normal).is_empty());
        let mut sparse = flat(1.0, 100.0);
        sparse.points.retain(|p| p.frequency_hz != 500.0);
        assert_eq!(
            condition_changes(Condition::StapesFixation, &normal, &sparse).len(),
            fixed.len() - 2
        );
    }
}
