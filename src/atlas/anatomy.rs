//! The parametric middle ear evaluated as a labelled implicit domain, with its landmarks and
//! boundary-condition sites (ligament/tendon wall anchors, tympanic annulus, footplate).
//!
//! Composition, in priority order (an earlier structure wins where two overlap, and the
//! signed distance of a later one is carved by every earlier one, `max(d, -d_earlier)`, so
//! that `label(p) = r` exactly when `signed_distance(r, p) < 0`):
//! 1. the two joints: each a layer of its `thickness` around the interface of its two bones
//!    (their bisector), where the bones overlap or come within half a thickness of each
//!    other, inside the elliptic footprint of its disc (`JOINT_HALF_DEPTH_MM` either side of
//!    the disc's plane). The layer follows the bones' own interface, so that outside the
//!    joints no two ossicles touch, however curved the articular facets;
//! 2. the bones (malleus, incus, stapes): each a smooth union (polynomial `smin`) of its
//!    primitives; where two bones overlap, the point belongs to the bone it is deeper in
//!    (bisector `(d_k - d_j) / 2`); inside a bone a point belongs to the part (Table 1 row) of
//!    its nearest primitive, with signed distance `max(d_bone, (d_part - d_other_parts) / 2)`;
//! 3. the ligaments and tendons (tapered tubes from the bone to a wall anchor).
//!
//! Every term is a max/min of 1-Lipschitz bounds, so the distances are 1-Lipschitz up to the
//! first-order ellipsoid approximation (see `sdf`).

use std::path::Path;

use nalgebra::{Point3, Vector3};

use super::eardrum::Eardrum;
use super::region::{Bone, Region};
use super::sdf::{Disc, Primitive, Tube, smooth_min};
use super::spec::{AnatomyError, AnatomySpec, Checker, Side};
use crate::ear::Landmarks;
use crate::mesh::LabelledDomain;

/// The default atlas anatomy (a right ear), as shipped in `assets/anatomy.toml`.
pub const DEFAULT_TOML: &str = include_str!("../../assets/anatomy.toml");

/// One ossicle: its primitives, each tagged with the Table 1 part it belongs to.
#[derive(Debug, Clone, PartialEq)]
struct BoneShape {
    blend: f64,
    parts: Vec<(Region, Primitive)>,
}

impl BoneShape {
    /// Smooth-union distance of the whole bone and the part of the nearest primitive.
    fn distance_and_part(&self, p: &Point3<f64>) -> (f64, Region) {
        let mut d = f64::INFINITY;
        let mut best = (f64::INFINITY, self.parts[0].0);
        for (region, prim) in &self.parts {
            let di = prim.distance(p);
            d = smooth_min(d, di, self.blend);
            if di < best.0 {
                best = (di, *region);
            }
        }
        (d, best.1)
    }

    fn distance(&self, p: &Point3<f64>) -> f64 {
        self.distance_and_part(p).0
    }

    /// Signed distance of one part: the bone cut by the bisector between the part's
    /// primitives and the others'.
    fn part_distance(&self, region: Region, p: &Point3<f64>) -> f64 {
        let (mut d, mut own, mut other) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        for (r, prim) in &self.parts {
            let di = prim.distance(p);
            d = smooth_min(d, di, self.blend);
            if *r == region {
                own = own.min(di);
            } else {
                other = other.min(di);
            }
        }
        if other.is_infinite() {
            d
        } else {
            d.max(0.5 * (own - other))
        }
    }
}

/// The parametric anatomy of one middle ear.
#[derive(Debug, Clone, PartialEq)]
pub struct Anatomy {
    spec: AnatomySpec,
    /// Malleus, incus, stapes.
    bones: [BoneShape; 3],
    /// Incudomalleolar, incudostapedial.
    joints: [Disc; 2],
    /// Ligaments then tendons, in label order (regions 10..=15).
    bands: [Tube; 6],
    footplate: Disc,
    eardrum: Eardrum,
    landmarks: Landmarks,
    bounds: (Point3<f64>, Point3<f64>),
}

const BONES: [Bone; 3] = [Bone::Malleus, Bone::Incus, Bone::Stapes];
const BANDS: [Region; 6] = [
    Region::SuperiorMallealLigament,
    Region::AnteriorMallealLigament,
    Region::LateralMallealLigament,
    Region::PosteriorIncudalLigament,
    Region::TensorTympaniTendon,
    Region::StapediusTendon,
];

/// How far a joint's layer may lie from its disc's plane, along the normal (mm): the
/// articular facets are curved (the incudomalleolar joint is a saddle).
pub const JOINT_HALF_DEPTH_MM: f64 = 0.6;

/// Margin added around the primitives' bounds (mm).
const BOUNDS_MARGIN: f64 = 0.5;

impl Anatomy {
    /// The embedded default anatomy (right ear).
    pub fn default_right() -> Result<Anatomy, AnatomyError> {
        let origin = "<embedded assets/anatomy.toml>";
        Anatomy::from_spec(AnatomySpec::from_toml_str(DEFAULT_TOML, origin)?, origin)
    }

    /// Reads and checks an anatomy file.
    pub fn load(path: &Path) -> Result<Anatomy, AnatomyError> {
        Anatomy::from_spec(AnatomySpec::load(path)?, &path.display().to_string())
    }

    /// Checks a description and builds the anatomy; `origin` names it in messages.
    pub fn from_spec(spec: AnatomySpec, origin: &str) -> Result<Anatomy, AnatomyError> {
        let c = Checker { origin };
        let (m, i, s) = (&spec.malleus, &spec.incus, &spec.stapes);
        let tag = |r: Region, v: Vec<Primitive>| v.into_iter().map(move |p| (r, p));
        let manubrium = c.tube("malleus.manubrium", &m.manubrium)?;
        let umbo = *manubrium.points.last().unwrap_or(&Point3::origin());
        let malleus = BoneShape {
            blend: c.non_negative("malleus.blend_mm", m.blend_mm)?,
            parts: tag(Region::MalleusHead, c.primitives("malleus.head", &m.head)?)
                .chain(tag(
                    Region::MalleusNeck,
                    c.primitives("malleus.neck", &m.neck)?,
                ))
                .chain(tag(
                    Region::MalleusNeck,
                    c.primitives("malleus.anterior_process", &m.anterior_process)?,
                ))
                .chain(tag(
                    Region::MalleusHandle,
                    c.primitives("malleus.lateral_process", &m.lateral_process)?,
                ))
                .chain([(Region::MalleusHandle, Primitive::Tube(manubrium))])
                .collect(),
        };
        let incus = BoneShape {
            blend: c.non_negative("incus.blend_mm", i.blend_mm)?,
            parts: tag(Region::IncusBody, c.primitives("incus.body", &i.body)?)
                .chain(tag(
                    Region::IncusShortProcess,
                    c.primitives("incus.short_process", &i.short_process)?,
                ))
                .chain(tag(
                    Region::IncusLongProcess,
                    c.primitives("incus.long_process", &i.long_process)?,
                ))
                .chain(tag(
                    Region::IncusLongProcess,
                    c.primitives("incus.lenticular_process", &i.lenticular_process)?,
                ))
                .collect(),
        };
        let footplate = c.disc("stapes.footplate", &s.footplate)?;
        let stapes = BoneShape {
            blend: c.non_negative("stapes.blend_mm", s.blend_mm)?,
            parts: tag(Region::Stapes, c.primitives("stapes.head", &s.head)?)
                .chain([
                    (
                        Region::Stapes,
                        Primitive::Tube(c.tube("stapes.anterior_crus", &s.anterior_crus)?),
                    ),
                    (
                        Region::Stapes,
                        Primitive::Tube(c.tube("stapes.posterior_crus", &s.posterior_crus)?),
                    ),
                    (Region::Stapes, Primitive::Disc(footplate.clone())),
                ])
                .collect(),
        };
        let joints = [
            c.disc("joints.incudomalleolar", &spec.joints.incudomalleolar)?,
            c.disc("joints.incudostapedial", &spec.joints.incudostapedial)?,
        ];
        let (l, t) = (&spec.ligaments, &spec.tendons);
        let bands = [
            c.tube("ligaments.superior_malleal", &l.superior_malleal)?,
            c.tube("ligaments.anterior_malleal", &l.anterior_malleal)?,
            c.tube("ligaments.lateral_malleal", &l.lateral_malleal)?,
            c.tube("ligaments.posterior_incudal", &l.posterior_incudal)?,
            c.tube("tendons.tensor_tympani", &t.tensor_tympani)?,
            c.tube("tendons.stapedius", &t.stapedius)?,
        ];
        let eardrum = Eardrum::new(&spec.eardrum, spec.side, umbo, &c)?;
        let landmarks = Landmarks {
            umbo,
            incudomalleolar: joints[0].center,
            incudostapedial: joints[1].center,
        };
        let bones = [malleus, incus, stapes];
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        let boxes = bones
            .iter()
            .flat_map(|b| b.parts.iter().map(|(_, p)| p.bounds()))
            .chain(joints.iter().map(|d| {
                let r = d.semi_axes[0]
                    .max(d.semi_axes[1])
                    .hypot(JOINT_HALF_DEPTH_MM);
                (
                    d.center - Vector3::from_element(r),
                    d.center + Vector3::from_element(r),
                )
            }))
            .chain(bands.iter().map(|t| Primitive::Tube(t.clone()).bounds()));
        for (a, b) in boxes {
            lo = lo.inf(&a);
            hi = hi.sup(&b);
        }
        let margin = Vector3::from_element(BOUNDS_MARGIN);
        let anatomy = Anatomy {
            spec,
            bones,
            joints,
            bands,
            footplate,
            eardrum,
            landmarks,
            bounds: (lo - margin, hi + margin),
        };
        anatomy.check_joints(&c)?;
        Ok(anatomy)
    }

    /// Each joint must sit between its two bones: its centre within `JOINT_REACH` of both.
    fn check_joints(&self, c: &Checker) -> Result<(), AnatomyError> {
        const JOINT_REACH: f64 = 0.5;
        let pairs = [
            ("joints.incudomalleolar.center", 0, [0, 1]),
            ("joints.incudostapedial.center", 1, [1, 2]),
        ];
        for (field, j, [a, b]) in pairs {
            let p = self.joints[j].center;
            let (da, db) = (self.bones[a].distance(&p), self.bones[b].distance(&p));
            if da > JOINT_REACH || db > JOINT_REACH {
                return Err(c.invalid(
                    field,
                    format!("{da:.3} mm and {db:.3} mm from the two bones' surfaces"),
                    "a joint centre within 0.5 mm of both bones it joins",
                ));
            }
        }
        Ok(())
    }

    /// The description this anatomy was built from.
    pub fn spec(&self) -> &AnatomySpec {
        &self.spec
    }

    pub fn side(&self) -> Side {
        self.spec.side
    }

    /// The other ear: the mirror image in the sagittal plane x = 0 of the atlas frame.
    pub fn mirrored(&self) -> Result<Anatomy, AnatomyError> {
        Anatomy::from_spec(self.spec.mirrored(), "<mirrored anatomy>")
    }

    pub fn landmarks(&self) -> Landmarks {
        self.landmarks
    }

    pub fn eardrum(&self) -> &Eardrum {
        &self.eardrum
    }

    /// The stapes footplate (normal pointing medially into the vestibule): where the cochlear
    /// load and the annular ligament act.
    pub fn footplate(&self) -> &Disc {
        &self.footplate
    }

    /// The incudostapedial joint's interface (its centre is the ISJ landmark; normal `e3`).
    pub fn incudostapedial_joint(&self) -> &Disc {
        &self.joints[1]
    }

    /// The tube of a ligament or tendon region (None for other regions).
    pub fn band(&self, region: Region) -> Option<&Tube> {
        BANDS
            .iter()
            .position(|r| *r == region)
            .map(|k| &self.bands[k])
    }

    /// The wall anchor (last node) of every ligament and tendon, in label order.
    pub fn anchors(&self) -> Vec<(Region, Point3<f64>)> {
        BANDS
            .iter()
            .zip(&self.bands)
            .filter_map(|(r, t)| t.points.last().map(|p| (*r, *p)))
            .collect()
    }

    /// Signed distance to a whole ossicle, before any carving by the joints.
    pub fn bone_distance(&self, bone: Bone, p: &Point3<f64>) -> f64 {
        let k = BONES.iter().position(|b| *b == bone).unwrap_or(0);
        self.bones[k].distance(p)
    }

    /// Signed distance to joint `k`: its footprint, the layer of its thickness around the
    /// bisector of its two bones, and no farther than half a thickness outside both bones.
    fn joint_distance(&self, k: usize, p: &Point3<f64>) -> f64 {
        let disc = &self.joints[k];
        let footprint = Disc {
            thickness: 2.0 * JOINT_HALF_DEPTH_MM,
            ..disc.clone()
        }
        .distance(p);
        let Some([a, b]) = Region::JOINTS[k].joined_bones() else {
            return f64::INFINITY;
        };
        let (da, db) = (self.bone_distance(a, p), self.bone_distance(b, p));
        let half = 0.5 * disc.thickness;
        let layer = 0.5 * (da - db).abs() - half;
        let near = da.min(db) - half;
        footprint.max(layer).max(near)
    }

    fn joints_distance(&self, p: &Point3<f64>) -> f64 {
        self.joint_distance(0, p).min(self.joint_distance(1, p))
    }
}

impl LabelledDomain for Anatomy {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        self.bounds
    }

    fn region_count(&self) -> u16 {
        Region::ALL.len() as u16
    }

    fn label(&self, p: &Point3<f64>) -> u16 {
        for (k, r) in Region::JOINTS.iter().enumerate() {
            if self.joint_distance(k, p) < 0.0 {
                return r.label();
            }
        }
        let mut best: Option<(f64, Region)> = None;
        for b in &self.bones {
            let (d, part) = b.distance_and_part(p);
            if d < 0.0 && best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, part));
            }
        }
        if let Some((_, part)) = best {
            return part.label();
        }
        for (r, t) in BANDS.iter().zip(&self.bands) {
            if t.distance(p) < 0.0 {
                return r.label();
            }
        }
        0
    }

    fn signed_distance(&self, region: u16, p: &Point3<f64>) -> f64 {
        let Some(region) = Region::from_label(region) else {
            return f64::INFINITY;
        };
        if let Some(k) = Region::JOINTS.iter().position(|r| *r == region) {
            return (0..k).fold(self.joint_distance(k, p), |d, j| {
                d.max(-self.joint_distance(j, p))
            });
        }
        let carve_joints = -self.joints_distance(p);
        if let Some(bone) = region.bone() {
            let k = BONES.iter().position(|b| *b == bone).unwrap_or(0);
            let own = self.bones[k].distance(p);
            return self.bones.iter().enumerate().filter(|(j, _)| *j != k).fold(
                self.bones[k].part_distance(region, p).max(carve_joints),
                |d, (_, b)| d.max(0.5 * (own - b.distance(p))),
            );
        }
        let k = BANDS.iter().position(|r| *r == region).unwrap_or(0);
        let d = self
            .bones
            .iter()
            .fold(self.bands[k].distance(p).max(carve_joints), |d, b| {
                d.max(-b.distance(p))
            });
        self.bands[..k].iter().fold(d, |d, t| d.max(-t.distance(p)))
    }
}
