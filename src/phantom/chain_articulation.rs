//! Seeded articulation of a real chain, so that one chain with its ossicles apart gives many
//! people's joint angles: `phantom --anatomy DIR --vary-articulation` turns, per case, the
//! stapes about the chain's ISJ landmark and the malleus about its IMJ landmark, each by a
//! random angle about a uniformly random axis, before the chain is placed and imaged.
//!
//! Why: people differ most in how the chain is articulated, and the CT chain at hand shows it
//! (its stapes lies 20-25 degrees from the atlas's about its head), but a fused chain's
//! articulation cannot be changed and a linear variation of the whole chain (`--vary-shape`)
//! does not turn one ossicle against the next. Turned about their joints, the ossicles keep
//! their own shapes, so a registration's error on these cases is its search for each
//! ossicle's pose. The stapes is turned by up to 25 degrees (the CT chain's offset, with a
//! margin), the malleus by up to 8 (its umbo then moves by up to about 0.8 mm about the IMJ,
//! within the spread of measured umbo-IMJ-ISJ triangles); the oval window follows the
//! stapes (`MeshChain::place`). The umbo landmark moves with the malleus, the IMJ and ISJ
//! landmarks are the pivots and stay.

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::draws::uniform_rotation;
use crate::ear::Landmarks;

/// The stapes's turn about the ISJ is at most this \[degrees\].
pub const STAPES_MAX_DEG: f64 = 25.0;
/// The malleus's turn about the IMJ is at most this \[degrees\].
pub const MALLEUS_MAX_DEG: f64 = 8.0;
/// The random stream of the articulation, apart from the case's other draws and from
/// `--vary-shape`'s: the same seed with and without it gives the same side, spacing, pose and
/// imaging draws.
const STREAM: u64 = 0x0a47_1c0e;

/// One ossicle's turn about a pivot (truth.json's `anatomy.articulation`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OssicleTurn {
    /// The unit axis of the turn.
    pub axis: [f64; 3],
    /// The angle about it, right-handed \[degrees\].
    pub angle_deg: f64,
    /// The point it turns about: the joint's landmark \[mm\].
    pub pivot: [f64; 3],
}

impl OssicleTurn {
    /// A turn about `pivot` by an angle uniform in 0..`max_deg` about a uniformly random axis.
    fn draw(rng: &mut ChaCha8Rng, max_deg: f64, pivot: Point3<f64>) -> OssicleTurn {
        let axis = uniform_rotation(rng) * Vector3::z();
        OssicleTurn {
            axis: axis.into(),
            angle_deg: rng.random_range(0.0..=max_deg),
            pivot: pivot.coords.into(),
        }
    }

    /// The turn's rotation (about the origin).
    pub fn rotation(&self) -> Rotation3<f64> {
        Rotation3::from_axis_angle(
            &Unit::new_normalize(Vector3::from(self.axis)),
            self.angle_deg.to_radians(),
        )
    }

    /// The turn as a function: where it carries a point.
    pub fn mapping(&self) -> impl Fn(&Point3<f64>) -> Point3<f64> + use<> {
        let rotation = self.rotation();
        let pivot = Point3::from(self.pivot);
        move |p| pivot + rotation * (p - pivot)
    }
}

/// One case's articulation, in the chain's own frame before mirroring.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChainArticulation {
    /// The malleus turned about the IMJ landmark.
    pub malleus: OssicleTurn,
    /// The stapes turned about the ISJ landmark.
    pub stapes: OssicleTurn,
}

impl ChainArticulation {
    /// The articulation of the case of `seed` for a chain with `landmarks`.
    pub fn draw(seed: u64, landmarks: &Landmarks) -> ChainArticulation {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM);
        let malleus = OssicleTurn::draw(&mut rng, MALLEUS_MAX_DEG, landmarks.incudomalleolar);
        let stapes = OssicleTurn::draw(&mut rng, STAPES_MAX_DEG, landmarks.incudostapedial);
        ChainArticulation { malleus, stapes }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn landmarks() -> Landmarks {
        Landmarks {
            umbo: Point3::new(1.0, 2.0, -4.0),
            incudomalleolar: Point3::new(0.0, 0.0, 1.0),
            incudostapedial: Point3::new(2.0, 1.0, -1.0),
        }
    }

    #[test]
    fn each_turn_keeps_its_joint_and_stays_within_its_angle() {
        for seed in 0..50 {
            let a = ChainArticulation::draw(seed, &landmarks());
            for (turn, pivot, max) in [
                (&a.malleus, landmarks().incudomalleolar, MALLEUS_MAX_DEG),
                (&a.stapes, landmarks().incudostapedial, STAPES_MAX_DEG),
            ] {
                assert!((turn.mapping()(&pivot) - pivot).norm() < 1e-12, "{seed}");
                assert!((0.0..=max).contains(&turn.angle_deg), "{seed}: {turn:?}");
                assert!((Vector3::from(turn.axis).norm() - 1.0).abs() < 1e-12);
                // the angle between a point's arm and its turned arm is the turn's at most
                let p = pivot + Vector3::new(0.3, -1.2, 2.0);
                let (before, after) = (p - pivot, turn.mapping()(&p) - pivot);
                assert!((after.norm() - before.norm()).abs() < 1e-12);
                assert!(before.angle(&after).to_degrees() <= turn.angle_deg + 1e-9);
            }
        }
    }

    #[test]
    fn a_seed_gives_one_articulation_and_seeds_differ() {
        let a = ChainArticulation::draw(7, &landmarks());
        assert_eq!(a, ChainArticulation::draw(7, &landmarks()));
        assert_ne!(a, ChainArticulation::draw(8, &landmarks()));
    }
}
