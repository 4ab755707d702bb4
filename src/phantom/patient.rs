//! A patient's middle ear in the atlas frame: the (moved) atlas anatomy with its shape detail,
//! as signed distances of the ossicles, joints and ligaments. It answers what the tissue field
//! and the truth need: which chain tissue a point is in, how far the nearest interface is at
//! least, and each ossicle's region (the surface the truth PLY is made from).
//!
//! Composition follows the atlas (`atlas::anatomy`): joints win over bones, bones over
//! ligaments and tendons; where two bones overlap the point belongs to the one it is deeper in.

use nalgebra::{Point3, Vector3};

use super::variability::{DETAILED_LIPSCHITZ, Ossicle, ShapeDetail};
use crate::atlas::anatomy::JOINT_HALF_DEPTH_MM;
use crate::atlas::{Anatomy, Region};
use crate::mesh::LabelledDomain;

/// The ligaments and tendons.
const BANDS: [Region; 6] = [
    Region::SuperiorMallealLigament,
    Region::AnteriorMallealLigament,
    Region::LateralMallealLigament,
    Region::PosteriorIncudalLigament,
    Region::TensorTympaniTendon,
    Region::StapediusTendon,
];

/// A patient's chain: anatomy (after the ossicle motions) plus shape detail, with a bounding
/// box per structure so that distant structures cost one box distance.
#[derive(Debug, Clone)]
pub struct PatientAnatomy {
    anatomy: Anatomy,
    detail: ShapeDetail,
    /// Boxes holding each ossicle (with its detail), both joints, each band.
    bone_boxes: [Aabb; 3],
    joint_box: Aabb,
    band_boxes: Vec<(Region, Aabb)>,
}

/// An axis-aligned box.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Aabb {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl Aabb {
    pub(crate) fn empty() -> Aabb {
        Aabb {
            lo: Vector3::from_element(f64::INFINITY),
            hi: Vector3::from_element(f64::NEG_INFINITY),
        }
    }

    pub(crate) fn add(&mut self, p: &Vector3<f64>, r: f64) {
        self.lo = self.lo.inf(&p.add_scalar(-r));
        self.hi = self.hi.sup(&p.add_scalar(r));
    }

    /// Distance from `p` to the box (0 inside).
    #[inline]
    pub(crate) fn distance(&self, p: &Point3<f64>) -> f64 {
        Vector3::from_fn(|c, _| (self.lo[c] - p[c]).max(p[c] - self.hi[c]).max(0.0)).norm()
    }
}

/// An ossicular chain the tissue field can image: its signed distances at a point, and the
/// atlas anatomy that supplies what the chain itself lacks (eardrum, footplate frame,
/// ligaments and tendons), in the same frame.
pub trait Chain: Sync {
    /// Every distance of the chain at `p` (see [`PatientAnatomy::distances`] for `far_mm`).
    fn distances(&self, p: &Point3<f64>, far_mm: f64) -> ChainDistances;
    /// The anatomy around the chain.
    fn anatomy(&self) -> &Anatomy;
}

impl Chain for PatientAnatomy {
    fn distances(&self, p: &Point3<f64>, far_mm: f64) -> ChainDistances {
        PatientAnatomy::distances(self, p, far_mm)
    }

    fn anatomy(&self) -> &Anatomy {
        &self.anatomy
    }
}

/// What the chain puts at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChainTissue {
    /// An ossicle.
    Bone(Ossicle),
    /// A joint, ligament or tendon.
    Soft,
}

/// The chain's signed distances at one point (mm, negative inside).
#[derive(Debug, Clone, Copy)]
pub struct ChainDistances {
    /// Detailed distance of each ossicle, in `Ossicle::ALL` order.
    pub bones: [f64; 3],
    /// Union of the two joints.
    pub joints: f64,
    /// Union of the ligaments and tendons.
    pub bands: f64,
}

impl ChainDistances {
    /// The chain tissue at the point, if any.
    pub fn tissue(&self) -> Option<ChainTissue> {
        if self.joints < 0.0 {
            return Some(ChainTissue::Soft);
        }
        if let Some(k) = self.deepest_bone() {
            return Some(ChainTissue::Bone(Ossicle::ALL[k]));
        }
        (self.bands < 0.0).then_some(ChainTissue::Soft)
    }

    fn deepest_bone(&self) -> Option<usize> {
        (0..3)
            .filter(|k| self.bones[*k] < 0.0)
            .min_by(|a, b| self.bones[*a].total_cmp(&self.bones[*b]))
    }

    /// A radius around the point within which `tissue()` cannot change.
    pub fn clearance(&self) -> f64 {
        let bones = self.bones.iter().fold(f64::INFINITY, |m, d| m.min(d.abs()));
        (bones / DETAILED_LIPSCHITZ)
            .min(self.joints.abs())
            .min(self.bands.abs())
    }

    /// Distance to the nearest ossicle (negative inside one).
    pub fn to_bones(&self) -> f64 {
        self.bones.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// Signed distance of ossicle `k`'s region: its detailed shape, carved by the joints and
    /// cut by the bisector with the other bones.
    pub fn region(&self, k: usize) -> f64 {
        let own = self.bones[k];
        (0..3)
            .filter(|j| *j != k)
            .fold(own.max(-self.joints), |d, j| {
                d.max(0.5 * (own - self.bones[j]))
            })
    }
}

impl PatientAnatomy {
    /// Builds the chain and its boxes. Ossicle boxes come from a 0.3 mm lattice: every point
    /// of a bone lies within 0.26 mm of a lattice node whose distance is then below
    /// 0.26 × 1.35 < 0.4 mm, so the nodes under 0.4 mm, grown by a lattice step, hold the bone.
    pub fn new(anatomy: Anatomy, detail: ShapeDetail) -> PatientAnatomy {
        let spec = anatomy.spec();
        let mut joint_box = Aabb::empty();
        for d in [&spec.joints.incudomalleolar, &spec.joints.incudostapedial] {
            let r = d.semi_axes[0]
                .max(d.semi_axes[1])
                .hypot(JOINT_HALF_DEPTH_MM);
            joint_box.add(&Vector3::from(d.center), r);
        }
        let band_boxes = BANDS
            .iter()
            .filter_map(|r| anatomy.band(*r).map(|t| (*r, t)))
            .map(|(r, t)| {
                let mut b = Aabb::empty();
                for (p, radius) in t.points.iter().zip(&t.radii) {
                    b.add(&p.coords, *radius);
                }
                (r, b)
            })
            .collect();
        let mut chain = PatientAnatomy {
            anatomy,
            detail,
            bone_boxes: [Aabb::empty(); 3],
            joint_box,
            band_boxes,
        };
        let (lo, hi) = chain.anatomy.bounds();
        let step = 0.3;
        let n = |c: usize| ((hi[c] - lo[c]) / step).ceil() as usize + 1;
        let mut boxes = [Aabb::empty(); 3];
        for k in 0..n(2) {
            for j in 0..n(1) {
                for i in 0..n(0) {
                    let p = lo + Vector3::new(i as f64, j as f64, k as f64) * step;
                    for (b, o) in boxes.iter_mut().zip(Ossicle::ALL) {
                        if chain.bone_distance(o, &p) < 0.4 {
                            b.add(&p.coords, step);
                        }
                    }
                }
            }
        }
        chain.bone_boxes = boxes;
        chain
    }

    /// The atlas anatomy itself (no shape detail).
    pub fn plain(anatomy: Anatomy) -> PatientAnatomy {
        PatientAnatomy::new(anatomy, ShapeDetail::default())
    }

    /// The anatomy after the ossicle motions.
    pub fn anatomy(&self) -> &Anatomy {
        &self.anatomy
    }

    /// The shape detail.
    pub fn detail(&self) -> &ShapeDetail {
        &self.detail
    }

    /// Detailed signed distance of one ossicle.
    #[inline]
    pub fn bone_distance(&self, ossicle: Ossicle, p: &Point3<f64>) -> f64 {
        self.anatomy.bone_distance(ossicle.bone(), p) - self.detail.offset(ossicle, p)
    }

    /// Every distance of the chain at `p`. For a structure more than `far_mm` from its box,
    /// the distance to the box stands for its own: a lower bound, which keeps every decision
    /// made from them as long as no decision compares them with a distance beyond `far_mm`,
    /// and only shrinks the clearance.
    pub fn distances(&self, p: &Point3<f64>, far_mm: f64) -> ChainDistances {
        // a structure farther than far_mm from its box is represented by the box distance
        let near = |b: &Aabb, exact: &dyn Fn() -> f64| {
            let d = b.distance(p);
            if d > far_mm { d } else { exact() }
        };
        let bands = self.bands_distance(p, far_mm);
        let mut bones = [0.0; 3];
        for (k, o) in Ossicle::ALL.iter().enumerate() {
            bones[k] = near(&self.bone_boxes[k], &|| self.bone_distance(*o, p));
        }
        ChainDistances {
            bones,
            joints: near(&self.joint_box, &|| self.joints_distance(p)),
            bands,
        }
    }

    /// Signed distance to the union of the ligaments and tendons (a band farther than
    /// `far_mm` from its box is represented by the box distance).
    pub fn bands_distance(&self, p: &Point3<f64>, far_mm: f64) -> f64 {
        self.band_boxes
            .iter()
            .map(|(r, b)| {
                let d = b.distance(p);
                if d > far_mm {
                    d
                } else {
                    self.anatomy
                        .band(*r)
                        .map_or(f64::INFINITY, |t| t.distance(p))
                }
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Signed distance to the union of the two joints.
    fn joints_distance(&self, p: &Point3<f64>) -> f64 {
        let a = &self.anatomy;
        a.signed_distance(Region::IncudomalleolarJoint.label(), p)
            .min(a.signed_distance(Region::IncudostapedialJoint.label(), p))
    }

    /// Signed distance of each ossicle's region (see `ChainDistances::region`), in
    /// `Ossicle::ALL` order; ligaments and tendons play no part in it.
    pub fn regions(&self, p: &Point3<f64>) -> [f64; 3] {
        let d = ChainDistances {
            bones: Ossicle::ALL.map(|o| self.bone_distance(o, p)),
            joints: self.joints_distance(p),
            bands: f64::INFINITY,
        };
        [0, 1, 2].map(|k| d.region(k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_detail_the_chain_tissue_is_the_atlas_label() {
        let a = Anatomy::default_right().unwrap();
        let p = PatientAnatomy::plain(a.clone());
        let (lo, hi) = a.bounds();
        let n = 24;
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let t =
                        |c: usize, v: usize| lo[c] + (hi[c] - lo[c]) * (v as f64 + 0.5) / n as f64;
                    let q = Point3::new(t(0, i), t(1, j), t(2, k));
                    let expected = Region::from_label(a.label(&q)).map(|r| match r.bone() {
                        Some(_) => "bone",
                        None => "soft",
                    });
                    let got = p.distances(&q, f64::INFINITY).tissue().map(|t| match t {
                        ChainTissue::Bone(_) => "bone",
                        ChainTissue::Soft => "soft",
                    });
                    assert_eq!(got, expected, "{q:?}");
                }
            }
        }
    }
}
