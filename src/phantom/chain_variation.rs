//! Seeded shape variation of a real chain, so that the two or three real chains at hand give
//! many people's: `phantom --anatomy DIR --vary-shape` applies, per case, a linear map about
//! the chain's centroid (surfaces and landmarks alike) before the chain is placed and imaged.
//!
//! The map stretches the chain along three random orthogonal directions by 0.87-1.15 each and
//! shears it by up to 0.12 between two of them. The stretch range covers the spread of the
//! landmark triangles of measured chains (umbo-IMJ 5.2-6.3 mm, umbo-ISJ 2.4-2.9 mm, IMJ-ISJ
//! 4.4-5.1 mm: about ±10 % about their middle), and the shear moves the chain's articulation
//! (the angle between the manubrium and the long process) the way people differ in it. Real
//! variation is not affine (the crura, the heads and processes differ in shape too), so this
//! widens a development set; it does not replace more real chains.

use nalgebra::{Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::draws::uniform_rotation;

/// Stretch factors along each direction are drawn from this range.
pub const STRETCH_RANGE: (f64, f64) = (0.87, 1.15);
/// The shear's magnitude is at most this.
pub const MAX_SHEAR: f64 = 0.12;
/// The random stream of the variation, apart from the case's other draws: the same seed with
/// and without `--vary-shape` gives the same side, spacing, pose and imaging draws.
const STREAM: u64 = 0x0ca1_c4a1;

/// One case's variation (truth.json's `anatomy.variation`).
#[derive(Debug, Clone, Serialize)]
pub struct ChainVariation {
    /// The map applied about `centre` (row-major): x' = centre + map (x - centre).
    pub map: [[f64; 3]; 3],
    /// The centroid of the chain's surface vertices, in the chain's own frame \[mm\].
    pub centre: [f64; 3],
    /// The stretch factors along the three directions.
    pub stretches: [f64; 3],
    /// The shear, between the directions `shear_axes` (index of the moved, of the moving).
    pub shear: f64,
    pub shear_axes: [usize; 2],
    /// The map's determinant: the chain's volume change.
    pub volume_ratio: f64,
}

impl ChainVariation {
    /// The variation of the case of `seed` about `centre`.
    pub fn draw(seed: u64, centre: Point3<f64>) -> ChainVariation {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(STREAM);
        let axes = uniform_rotation(&mut rng).into_inner();
        let stretches: [f64; 3] =
            std::array::from_fn(|_| rng.random_range(STRETCH_RANGE.0..=STRETCH_RANGE.1));
        let moved = rng.random_range(0..3usize);
        let moving = (moved + rng.random_range(1..3usize)) % 3;
        let shear = rng.random_range(-MAX_SHEAR..=MAX_SHEAR);
        let mut shape = Matrix3::from_diagonal(&Vector3::from(stretches));
        shape[(moved, moving)] = shear * stretches[moving];
        let map = axes * shape * axes.transpose();
        ChainVariation {
            map: std::array::from_fn(|r| std::array::from_fn(|c| map[(r, c)])),
            centre: centre.coords.into(),
            stretches,
            shear,
            shear_axes: [moved, moving],
            volume_ratio: map.determinant(),
        }
    }

    /// The map as a function: where the variation carries a point (its matrix built once).
    pub fn mapping(&self) -> impl Fn(&Point3<f64>) -> Point3<f64> + use<> {
        let map = Matrix3::from_fn(|r, c| self.map[r][c]);
        let centre = Point3::from(self.centre);
        move |p| centre + map * (p - centre)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_map_stretches_within_its_range_and_keeps_the_centre() {
        for seed in 0..50 {
            let centre = Point3::new(1.0, -2.0, 3.0);
            let v = ChainVariation::draw(seed, centre);
            assert!((v.mapping()(&centre) - centre).norm() < 1e-12);
            let map = Matrix3::from_fn(|r, c| v.map[r][c]);
            // the singular values lie within the stretches widened by the shear
            let sv = map.singular_values();
            let (lo, hi) = (sv.min(), sv.max());
            assert!(
                lo > STRETCH_RANGE.0 * (1.0 - MAX_SHEAR) - 1e-9,
                "{seed}: {sv}"
            );
            assert!(
                hi < STRETCH_RANGE.1 * (1.0 + MAX_SHEAR) + 1e-9,
                "{seed}: {sv}"
            );
            let product: f64 = v.stretches.iter().product();
            assert!((v.volume_ratio - product).abs() < 1e-9, "{seed}");
            assert_ne!(v.shear_axes[0], v.shear_axes[1]);
        }
    }

    #[test]
    fn a_seed_gives_one_variation_and_seeds_differ() {
        let a = ChainVariation::draw(7, Point3::origin());
        let b = ChainVariation::draw(7, Point3::origin());
        let c = ChainVariation::draw(8, Point3::origin());
        assert_eq!(a.map, b.map);
        assert_ne!(a.map, c.map);
    }
}
