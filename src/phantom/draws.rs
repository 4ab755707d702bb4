//! Random draws shared by the phantom's generators (the atlas-shape cases and a real chain's
//! shape variation), so that each module draws alike without importing the other.

use nalgebra::{Quaternion, Rotation3, UnitQuaternion};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The rotation of a unit quaternion with Gaussian components: uniform over SO(3).
pub fn uniform_rotation(rng: &mut ChaCha8Rng) -> Rotation3<f64> {
    let q = Quaternion::from(nalgebra::Vector4::from_fn(|_, _| {
        StandardNormal.sample(rng)
    }));
    UnitQuaternion::from_quaternion(q).to_rotation_matrix()
}
