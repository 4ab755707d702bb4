//! The noise-free tissue field of a synthetic temporal bone around the ossicular chain, in the
//! anatomy's frame: what a CBCT of the middle ear shows, as Hounsfield units at a point, with
//! a clearance (a radius within which the tissue cannot change) for the adaptive renderer.
//! The chain is any [`Chain`]: a `PatientAnatomy` (the atlas, or a patient with its shape
//! detail) or a real chain's surfaces (`mesh_chain`).
//!
//! - ossicles: dense bone; joints, ligaments and tendons: soft tissue;
//! - the eardrum: a soft-tissue sheet of its real thickness (pars tensa / flaccida), far
//!   thinner than a voxel, so partial volume leaves a faint ridge, as in real scans;
//! - the tympanic cavity: air behind the whole eardrum to a depth of about 2 mm (umbo to
//!   promontory), and within a wall distance of the ossicles that varies smoothly between
//!   `wall_min_mm` and `wall_max_mm` (0.5-2 mm);
//! - the external ear canal: air lateral to the eardrum, inside its annulus;
//! - the otic capsule: the densest bone of the body, medial to the footplate, with the
//!   fluid-filled vestibule behind the oval window;
//! - elsewhere: pneumatised temporal bone.
//!
//! HU levels (see docs/phantom.md for sources): CBCT grey values are not calibrated HU, so
//! these are typical CT values on the usual scale.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::drum::{DrumSlopes, drum_position, sheet_fraction};
use super::imaging::{FieldSample, TissueField};
use super::patient::{Chain, ChainTissue};
use super::variability::DETAILED_LIPSCHITZ;
use crate::atlas::materials::membrane_thickness_mm;
use crate::atlas::sdf::Disc;
use crate::atlas::{Anatomy, MembraneRegion};

/// Width of the stapedial annular ligament between the footplate's rim and the oval window's
/// bony rim (about 0.1 mm: Kwacz et al. 2015) [mm].
const ANNULAR_GAP_MM: f64 = 0.1;

/// The grey levels of each tissue \[HU\].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TissueLevels {
    pub air: f32,
    pub soft_tissue: f32,
    pub fluid: f32,
    pub ossicle: f32,
    pub temporal_bone: f32,
    pub otic_capsule: f32,
}

impl Default for TissueLevels {
    fn default() -> Self {
        TissueLevels {
            air: -1000.0,
            soft_tissue: 50.0,
            fluid: 10.0,
            ossicle: 1500.0,
            temporal_bone: 1100.0,
            otic_capsule: 2000.0,
        }
    }
}

/// The cavity and its walls.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CavityParams {
    /// Nearest and farthest distance of the cavity wall from the ossicles \[mm\].
    pub wall_min_mm: f64,
    pub wall_max_mm: f64,
    /// Phase of the smooth wall variation (a seed-derived number, radians).
    pub wall_phase: f64,
    /// Depth of the cavity medial to the whole eardrum (umbo to promontory is about 2 mm) \[mm\].
    pub depth_behind_drum_mm: f64,
    /// Radius of the otic capsule block around the footplate \[mm\].
    pub capsule_radius_mm: f64,
    /// Depth of the vestibule behind the footplate (its opening is the oval window) \[mm\].
    pub vestibule_radius_mm: f64,
}

impl Default for CavityParams {
    fn default() -> Self {
        CavityParams {
            wall_min_mm: 0.5,
            wall_max_mm: 2.0,
            wall_phase: 0.0,
            depth_behind_drum_mm: 2.0,
            capsule_radius_mm: 3.5,
            vestibule_radius_mm: 1.5,
        }
    }
}

/// The tissue field of one ear, in the anatomy's frame (mm).
pub struct EarScene<'a> {
    patient: &'a dyn Chain,
    levels: TissueLevels,
    cavity: CavityParams,
    slopes: DrumSlopes,
    /// The oval window's disc: the anatomy's footplate, or where a real chain's sits.
    footplate: Disc,
}

impl<'a> EarScene<'a> {
    pub fn new(patient: &'a dyn Chain, levels: TissueLevels, cavity: CavityParams) -> Self {
        EarScene {
            patient,
            levels,
            cavity,
            slopes: DrumSlopes::measure(patient.anatomy().eardrum()),
            footplate: patient.anatomy().footplate().clone(),
        }
    }

    /// The same scene with the vestibule and the oval window around `footplate` (a chain
    /// whose stapes is not the anatomy's).
    pub fn with_footplate(mut self, footplate: Disc) -> Self {
        self.footplate = footplate;
        self
    }

    pub fn levels(&self) -> &TissueLevels {
        &self.levels
    }

    pub fn cavity(&self) -> &CavityParams {
        &self.cavity
    }

    fn anatomy(&self) -> &Anatomy {
        self.patient.anatomy()
    }

    /// Distance from the ossicles to the cavity wall at `p`: a smooth variation between the
    /// configured bounds.
    fn wall_distance(&self, p: &Point3<f64>) -> f64 {
        let c = &self.cavity;
        let phase = c.wall_phase;
        let wave = ((0.9 * p.x + phase).sin() * (0.7 * p.y - phase).cos()
            + (0.8 * p.z + 2.0 * phase).sin())
            / 2.0;
        c.wall_min_mm + (c.wall_max_mm - c.wall_min_mm) * 0.5 * (1.0 + wave)
    }

    /// Lipschitz bound of `wall_distance`: |∇wave| ≤ (|(0.9, 0.7)| + 0.8) / 2 < 0.97.
    fn wall_slope(&self) -> f64 {
        (self.cavity.wall_max_mm - self.cavity.wall_min_mm) * 0.5 * 0.97
    }
}

impl EarScene<'_> {
    /// HU at `p` (anatomy frame) and a radius within which the tissue cannot change (the
    /// smallest distance to any interface the decision consulted, over its Lipschitz bound).
    /// `footprint_mm` is the size the sample stands for (the eardrum sheet is averaged over it).
    pub fn sample(&self, p: &Point3<f64>, footprint_mm: f64) -> FieldSample {
        let l = &self.levels;
        // the wall test compares the chain distance with at most wall_max_mm
        let chain = self.patient.distances(p, self.cavity.wall_max_mm + 0.5);
        let mut clearance = chain.clearance();
        let done = |hu: f32, clearance: f64| FieldSample {
            hu,
            clearance_mm: clearance.max(0.0),
        };
        match chain.tissue() {
            Some(ChainTissue::Bone(_)) => return done(l.ossicle, clearance),
            Some(ChainTissue::Soft) => return done(l.soft_tissue, clearance),
            None => {}
        }
        let d = self.anatomy().eardrum();
        let drum = drum_position(d, p);
        clearance = clearance.min((drum.s - 1.0).abs() / self.slopes.s);
        if drum.s <= 1.0 {
            let thickness = membrane_thickness_mm(d.region(drum.s, drum.theta));
            // the sheet's faces, of either part's thickness (the parts meet along a line)
            for t in [MembraneRegion::ParsTensa, MembraneRegion::ParsFlaccida] {
                let face = (drum.height.abs() - 0.5 * membrane_thickness_mm(t)).abs();
                clearance = clearance.min(face / self.slopes.height);
            }
            let sheet = sheet_fraction(drum.height, thickness, footprint_mm);
            if sheet > 0.0 || drum.height < 0.0 {
                // both sides of the sheet are air (canal, cavity): blend the sheet over it
                let hu = sheet * l.soft_tissue as f64 + (1.0 - sheet) * l.air as f64;
                return done(hu as f32, clearance);
            }
        }
        // behind the oval window: the vestibule, then the otic capsule
        let fp = &self.footplate;
        let depth = (p - fp.center).dot(&fp.frame.e3);
        let from_fp = (p - fp.center).norm();
        clearance = clearance
            .min((depth - 0.5 * fp.thickness).abs())
            .min((from_fp - self.cavity.capsule_radius_mm).abs());
        if depth > 0.5 * fp.thickness && from_fp < self.cavity.capsule_radius_mm {
            // the vestibule: a half-ellipsoid behind the oval window, whose opening is the
            // footplate's outline plus the annular ligament's gap, so the whole medial face
            // of the footplate bathes in perilymph and the capsule bone frames its rim
            let q = fp.frame.local(&(p - fp.center));
            let axes = [
                fp.semi_axes[0] + ANNULAR_GAP_MM,
                fp.semi_axes[1] + ANNULAR_GAP_MM,
                self.cavity.vestibule_radius_mm,
            ];
            let k = ((q.x / axes[0]).powi(2)
                + (q.y / axes[1]).powi(2)
                + ((depth - 0.5 * fp.thickness) / axes[2]).powi(2))
            .sqrt();
            // k - 1 is Lipschitz with constant 1 / (smallest semi-axis)
            clearance = clearance.min((k - 1.0).abs() * axes[0].min(axes[1]).min(axes[2]));
            let hu = if k < 1.0 { l.fluid } else { l.otic_capsule };
            return done(hu, clearance);
        }
        if drum.s <= 1.0 {
            clearance = clearance
                .min((drum.height - self.cavity.depth_behind_drum_mm).abs() / self.slopes.height);
            if drum.height < self.cavity.depth_behind_drum_mm {
                return done(l.air, clearance); // the tympanic cavity behind the membrane
            }
        }
        let wall = chain.to_bones() - self.wall_distance(p);
        clearance = clearance.min(wall.abs() / (DETAILED_LIPSCHITZ + self.wall_slope()));
        let hu = if wall < 0.0 { l.air } else { l.temporal_bone };
        done(hu, clearance)
    }
}

impl TissueField for EarScene<'_> {
    fn sample(&self, p: &Point3<f64>, footprint_mm: f64) -> FieldSample {
        EarScene::sample(self, p, footprint_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::LabelledDomain;
    use crate::phantom::patient::PatientAnatomy;

    fn scene(patient: &PatientAnatomy) -> EarScene<'_> {
        EarScene::new(patient, TissueLevels::default(), CavityParams::default())
    }

    fn hu(s: &EarScene, p: &Point3<f64>) -> f32 {
        s.sample(p, 0.0).hu
    }

    #[test]
    fn tissues_where_the_anatomy_puts_them() {
        let a = Anatomy::default_right().unwrap();
        let p = PatientAnatomy::plain(a.clone());
        let s = scene(&p);
        let l = TissueLevels::default();
        let lm = a.landmarks();
        let n = a.eardrum().medial_normal;
        let drum = a.eardrum();
        // the umbo is in the manubrium: bone
        assert_eq!(hu(&s, &lm.umbo), l.ossicle);
        // a point on the pars tensa half-way to the annulus, off the manubrium: the sheet
        let on = drum.point(0.6, std::f64::consts::PI);
        assert_eq!(hu(&s, &on), l.soft_tissue);
        // just lateral of it: the ear canal; just medial: the tympanic cavity
        assert_eq!(hu(&s, &(on - n * 0.2)), l.air);
        assert_eq!(hu(&s, &(on + n * 0.3)), l.air);
        // behind the footplate: vestibule fluid, then capsule bone further out
        let fp = a.footplate();
        assert_eq!(hu(&s, &(fp.center + fp.frame.e3 * 1.0)), l.fluid);
        // the whole medial face of the footplate faces fluid, out to its rim; beyond the
        // oval window's opening, capsule bone
        let behind = fp.frame.e3 * (0.5 * fp.thickness + 0.15);
        for (u, v) in [(0.9, 0.0), (0.0, 0.9), (-0.9, 0.0), (0.6, -0.6)] {
            let rim = fp.frame.e1 * (u * fp.semi_axes[0]) + fp.frame.e2 * (v * fp.semi_axes[1]);
            assert_eq!(hu(&s, &(fp.center + rim + behind)), l.fluid, "({u}, {v})");
            assert_eq!(
                hu(&s, &(fp.center + rim * 1.5 + behind)),
                l.otic_capsule,
                "({u}, {v})"
            );
        }
        assert_eq!(hu(&s, &(fp.center + fp.frame.e3 * 3.2)), l.otic_capsule);
        // far from everything (medial, beyond any wall): temporal bone
        assert_eq!(
            hu(&s, &(lm.incudomalleolar + n * 6.0 + drum.superior * 4.0)),
            l.temporal_bone
        );
    }

    #[test]
    fn clearance_is_a_radius_of_constant_tissue() {
        // around random points, points within the reported clearance have the same HU, up to
        // the reach the renderer relies on (a voxel's half-diagonal with margin, 0.33 mm at
        // 0.3 mm voxels; beyond that the first-order ellipse distances may overestimate)
        const REACH: f64 = 0.5;
        use rand::{Rng, SeedableRng};
        let a = Anatomy::default_right().unwrap();
        let p = PatientAnatomy::plain(a.clone());
        let s = scene(&p);
        let (lo, hi) = a.bounds();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut checked = 0;
        let d = a.eardrum();
        for n in 0..6000 {
            // two thirds anywhere around the chain, one third within 0.5 mm of the membrane
            let q = if n % 3 == 0 {
                d.point(rng.random::<f64>() * 1.1, rng.random::<f64>() * 7.0)
                    + d.medial_normal * (rng.random::<f64>() - 0.5)
            } else {
                Point3::from(nalgebra::Vector3::from_fn(|k, _| {
                    lo[k] - 2.0 + rng.random::<f64>() * (hi[k] - lo[k] + 4.0)
                }))
            };
            let at = s.sample(&q, 0.0);
            if at.clearance_mm < 1e-3 {
                continue;
            }
            for _ in 0..8 {
                let dir = nalgebra::Vector3::from_fn(|_, _| rng.random::<f64>() - 0.5).normalize();
                let r = at.clearance_mm.min(REACH) * rng.random::<f64>() * 0.999;
                let there = q + dir * r;
                assert_eq!(
                    hu(&s, &there),
                    at.hu,
                    "{q:?} r {r} {:?}",
                    p.distances(&there, f64::INFINITY)
                );
                checked += 1;
            }
        }
        assert!(checked > 10_000);
    }
}
