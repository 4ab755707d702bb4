//! The noise-free tissue field of a synthetic temporal bone around the ossicular chain, in the
//! anatomy's frame: what a CBCT of the middle ear shows, as Hounsfield units at a point.
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

use super::imaging::TissueField;
use crate::atlas::materials::membrane_thickness_mm;
use crate::atlas::{Anatomy, Bone, Region};
use crate::mesh::LabelledDomain;

/// The grey levels of each tissue [HU].
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
    /// Nearest and farthest distance of the cavity wall from the ossicles [mm].
    pub wall_min_mm: f64,
    pub wall_max_mm: f64,
    /// Phase of the smooth wall variation (a seed-derived number, radians).
    pub wall_phase: f64,
    /// Depth of the cavity medial to the whole eardrum (umbo to promontory is about 2 mm) [mm].
    pub depth_behind_drum_mm: f64,
    /// Radius of the otic capsule block around the footplate [mm].
    pub capsule_radius_mm: f64,
    /// Semi-axes of the vestibule ellipsoid behind the footplate [mm].
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
    pub anatomy: &'a Anatomy,
    pub levels: TissueLevels,
    pub cavity: CavityParams,
}

/// Where a point lies relative to the eardrum cone.
struct DrumPosition {
    /// Signed distance along the medial normal from the membrane (+ medial).
    height: f64,
    /// Radial fraction from the umbo (0) to the annulus (1); > 1 outside the annulus.
    s: f64,
    theta: f64,
}

impl EarScene<'_> {
    fn drum_position(&self, p: &Point3<f64>) -> DrumPosition {
        let d = self.anatomy.eardrum();
        let to_uv = |q: &Point3<f64>| {
            let r = q - d.annulus_center;
            (
                r.dot(&d.superior) / d.semi_axis_superior,
                r.dot(&d.anterior) / d.semi_axis_anterior,
            )
        };
        let (au, av) = to_uv(&d.apex);
        let (pu, pv) = to_uv(p);
        let (du, dv) = (pu - au, pv - av);
        let len = (du * du + dv * dv).sqrt();
        if len < 1e-12 {
            return DrumPosition {
                height: (p - d.apex).dot(&d.medial_normal),
                s: 0.0,
                theta: 0.0,
            };
        }
        let (ux, uy) = (du / len, dv / len);
        // the generator through p meets the unit circle at apex_uv + t (ux, uy)
        let b = au * ux + av * uy;
        let c = au * au + av * av - 1.0;
        let t = -b + (b * b - c).max(0.0).sqrt();
        let theta = (av + t * uy).atan2(au + t * ux);
        let s = len / t.max(1e-12);
        let on_membrane = d.point(s, theta);
        DrumPosition {
            height: (p - on_membrane).dot(&d.medial_normal),
            s,
            theta,
        }
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
}

impl TissueField for EarScene<'_> {
    fn hu(&self, p: &Point3<f64>) -> f32 {
        let l = &self.levels;
        let label = self.anatomy.label(p);
        if let Some(region) = Region::from_label(label) {
            return if region.bone().is_some() {
                l.ossicle
            } else {
                l.soft_tissue
            };
        }
        let drum = self.drum_position(p);
        let d = self.anatomy.eardrum();
        if drum.s <= 1.0 {
            let thickness = membrane_thickness_mm(d.region(drum.s, drum.theta));
            if drum.height.abs() <= 0.5 * thickness {
                return l.soft_tissue;
            }
            if drum.height < 0.0 {
                return l.air; // the external ear canal
            }
        }
        // behind the oval window: the vestibule, then the otic capsule
        let fp = self.anatomy.footplate();
        let depth = (p - fp.center).dot(&fp.frame.e3);
        if depth > 0.5 * fp.thickness && (p - fp.center).norm() < self.cavity.capsule_radius_mm {
            let centre = fp.center + fp.frame.e3 * self.cavity.vestibule_radius_mm;
            return if (p - centre).norm() < self.cavity.vestibule_radius_mm {
                l.fluid
            } else {
                l.otic_capsule
            };
        }
        if drum.s <= 1.0 && drum.height < self.cavity.depth_behind_drum_mm {
            return l.air; // the tympanic cavity behind the membrane
        }
        let to_chain = [Bone::Malleus, Bone::Incus, Bone::Stapes]
            .iter()
            .map(|b| self.anatomy.bone_distance(*b, p))
            .fold(f64::INFINITY, f64::min);
        if to_chain < self.wall_distance(p) {
            l.air
        } else {
            l.temporal_bone
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(anatomy: &Anatomy) -> EarScene<'_> {
        EarScene {
            anatomy,
            levels: TissueLevels::default(),
            cavity: CavityParams::default(),
        }
    }

    #[test]
    fn tissues_where_the_anatomy_puts_them() {
        let a = Anatomy::default_right().unwrap();
        let s = scene(&a);
        let l = TissueLevels::default();
        let lm = a.landmarks();
        let n = a.eardrum().medial_normal;
        let drum = a.eardrum();
        // the umbo is in the manubrium: bone
        assert_eq!(s.hu(&lm.umbo), l.ossicle);
        // a point on the pars tensa half-way to the annulus, off the manubrium: the sheet
        let on = drum.point(0.6, std::f64::consts::PI);
        assert_eq!(s.hu(&on), l.soft_tissue);
        // just lateral of it: the ear canal; just medial: the tympanic cavity
        assert_eq!(s.hu(&(on - n * 0.2)), l.air);
        assert_eq!(s.hu(&(on + n * 0.3)), l.air);
        // behind the footplate: vestibule fluid, then capsule bone further out
        let fp = a.footplate();
        assert_eq!(s.hu(&(fp.center + fp.frame.e3 * 1.0)), l.fluid);
        assert_eq!(s.hu(&(fp.center + fp.frame.e3 * 3.2)), l.otic_capsule);
        // far from everything (medial, beyond any wall): temporal bone
        assert_eq!(
            s.hu(&(lm.incudomalleolar + n * 6.0 + drum.superior * 4.0)),
            l.temporal_bone
        );
    }

    #[test]
    fn drum_position_is_zero_on_the_membrane_and_signed_off_it() {
        let a = Anatomy::default_right().unwrap();
        let s = scene(&a);
        let d = a.eardrum();
        for (sf, th) in [(0.2, 0.3), (0.7, 2.5), (0.95, -1.2)] {
            let p = d.point(sf, th);
            let pos = s.drum_position(&p);
            assert!(
                pos.height.abs() < 1e-9 && (pos.s - sf).abs() < 1e-9,
                "{sf} {th}"
            );
            let off = s.drum_position(&(p + d.medial_normal * 0.1));
            assert!(off.height > 0.0);
        }
    }
}
