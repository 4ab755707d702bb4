//! Patient variability on top of the atlas anatomy, in the atlas frame: small rigid motions of
//! the ossicles within their joints (applied to the anatomy description, so the eardrum apex
//! follows the umbo and the ligaments stay attached), and shape detail the atlas does not
//! have: smooth Gaussian bumps and dimples on the ossicle surfaces, added to the bones' signed
//! distances, so that no atlas deformation reaches a phantom's shape exactly.

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::atlas::spec::{DiscSpec, PrimitiveSpec, TubeSpec};
use crate::atlas::{Anatomy, AnatomySpec, Bone};
use crate::mesh::LabelledDomain;

/// One of the three ossicles, as written in truth.json.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ossicle {
    Malleus,
    Incus,
    Stapes,
}

impl Ossicle {
    pub const ALL: [Ossicle; 3] = [Ossicle::Malleus, Ossicle::Incus, Ossicle::Stapes];

    pub fn bone(self) -> Bone {
        match self {
            Ossicle::Malleus => Bone::Malleus,
            Ossicle::Incus => Bone::Incus,
            Ossicle::Stapes => Bone::Stapes,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Ossicle::Malleus => "malleus",
            Ossicle::Incus => "incus",
            Ossicle::Stapes => "stapes",
        }
    }
}

/// What a motion moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotionTarget {
    /// The whole chain (three bones and both joints) relative to the eardrum annulus.
    Chain,
    /// The malleus relative to the incus, about the incudomalleolar joint.
    Malleus,
    /// The stapes relative to the incus, about the incudostapedial joint.
    Stapes,
}

/// A rotation of part of the chain about a pivot (atlas frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OssicleMotion {
    pub target: MotionTarget,
    pub pivot: [f64; 3],
    pub axis: [f64; 3],
    pub angle_deg: f64,
}

/// A rotation about a pivot, applied to points and directions of the description.
struct Rigid {
    rotation: Rotation3<f64>,
    pivot: Vector3<f64>,
}

impl Rigid {
    fn point(&self, p: &mut [f64; 3]) {
        let q = self.rotation * (Vector3::from(*p) - self.pivot) + self.pivot;
        *p = q.into();
    }

    fn direction(&self, d: &mut [f64; 3]) {
        *d = (self.rotation * Vector3::from(*d)).into();
    }

    fn tube(&self, t: &mut TubeSpec) {
        t.points.iter_mut().for_each(|p| self.point(p));
    }

    fn disc(&self, d: &mut DiscSpec) {
        self.point(&mut d.center);
        self.direction(&mut d.normal);
        self.direction(&mut d.long_axis);
    }

    fn primitive(&self, p: &mut PrimitiveSpec) {
        match p {
            PrimitiveSpec::Tube(t) => self.tube(t),
            PrimitiveSpec::Disc(d) => self.disc(d),
            PrimitiveSpec::Ellipsoid(e) => {
                self.point(&mut e.center);
                self.direction(&mut e.axis_1);
                self.direction(&mut e.axis_2);
            }
        }
    }

    /// Moves the first node of a ligament or tendon (the one inside its bone); the wall
    /// anchor stays.
    fn band_root(&self, t: &mut TubeSpec) {
        if let Some(p) = t.points.first_mut() {
            self.point(p);
        }
    }
}

/// The description with `motions` applied in order.
pub fn apply_motions(spec: &AnatomySpec, motions: &[OssicleMotion]) -> AnatomySpec {
    let mut s = spec.clone();
    for m in motions {
        let axis = Unit::new_normalize(Vector3::from(m.axis));
        let r = Rigid {
            rotation: Rotation3::from_axis_angle(&axis, m.angle_deg.to_radians()),
            pivot: Vector3::from(m.pivot),
        };
        let malleus = matches!(m.target, MotionTarget::Chain | MotionTarget::Malleus);
        let stapes = matches!(m.target, MotionTarget::Chain | MotionTarget::Stapes);
        if malleus {
            let b = &mut s.malleus;
            b.head
                .iter_mut()
                .chain(&mut b.neck)
                .chain(&mut b.anterior_process)
                .chain(&mut b.lateral_process)
                .for_each(|p| r.primitive(p));
            r.tube(&mut b.manubrium);
            let l = &mut s.ligaments;
            for t in [
                &mut l.superior_malleal,
                &mut l.anterior_malleal,
                &mut l.lateral_malleal,
                &mut s.tendons.tensor_tympani,
            ] {
                r.band_root(t);
            }
        }
        if stapes {
            let b = &mut s.stapes;
            b.head.iter_mut().for_each(|p| r.primitive(p));
            r.tube(&mut b.anterior_crus);
            r.tube(&mut b.posterior_crus);
            r.disc(&mut b.footplate);
            r.band_root(&mut s.tendons.stapedius);
        }
        if m.target == MotionTarget::Chain {
            let b = &mut s.incus;
            b.body
                .iter_mut()
                .chain(&mut b.short_process)
                .chain(&mut b.long_process)
                .chain(&mut b.lenticular_process)
                .for_each(|p| r.primitive(p));
            r.disc(&mut s.joints.incudomalleolar);
            r.disc(&mut s.joints.incudostapedial);
            r.band_root(&mut s.ligaments.posterior_incudal);
        }
    }
    s
}

/// A smooth bump (height > 0) or dimple (height < 0) on an ossicle surface: the bone's signed
/// distance is lowered by `height · exp(-|p - c|² / 2σ²)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bump {
    pub ossicle: Ossicle,
    pub center: [f64; 3],
    pub height_mm: f64,
    pub sigma_mm: f64,
}

/// Bounds on the bumps, so the detailed distance stays within `1 + max |h| / σ · e^{-1/2}` of
/// 1-Lipschitz (at most 1.35 here).
pub const BUMP_HEIGHT_MM: (f64, f64) = (0.1, 0.2);
pub const BUMP_SIGMA_MM: (f64, f64) = (0.35, 0.6);
/// Lipschitz bound of a detailed bone distance.
pub const DETAILED_LIPSCHITZ: f64 = 1.35;

/// No bump closer than this to a landmark, so the landmarks keep their place on the joints.
const LANDMARK_CLEARANCE_MM: f64 = 1.5;
/// Bumps per ossicle.
const BUMPS: [(Ossicle, usize); 3] = [
    (Ossicle::Malleus, 5),
    (Ossicle::Incus, 5),
    (Ossicle::Stapes, 2),
];

/// The shape detail of one patient.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDetail {
    pub bumps: Vec<Bump>,
}

impl ShapeDetail {
    /// How far the surface of `ossicle` moves outward near `p` \[mm\].
    #[inline]
    pub fn offset(&self, ossicle: Ossicle, p: &Point3<f64>) -> f64 {
        self.bumps
            .iter()
            .filter(|b| b.ossicle == ossicle)
            .map(|b| {
                let r2 = (p - Point3::from(b.center)).norm_squared();
                b.height_mm * (-r2 / (2.0 * b.sigma_mm * b.sigma_mm)).exp()
            })
            .sum()
    }

    /// Seeded bumps on the surfaces of `anatomy`'s ossicles, away from the landmarks. Thin
    /// parts (less than about 0.35 mm of bone under the surface) only get bumps, not dimples,
    /// so the stapes crura are never cut through.
    pub fn draw(anatomy: &Anatomy, rng: &mut impl Rng) -> ShapeDetail {
        let (lo, hi) = anatomy.bounds();
        let landmarks = anatomy.landmarks().points();
        let mut bumps: Vec<Bump> = Vec::new();
        for (ossicle, count) in BUMPS {
            let bone = ossicle.bone();
            let dist = |p: &Point3<f64>| anatomy.bone_distance(bone, p);
            let mut placed = 0;
            for _ in 0..20_000 {
                if placed == count {
                    break;
                }
                let mut p = Point3::from(Vector3::from_fn(|k, _| {
                    lo[k] + rng.random::<f64>() * (hi[k] - lo[k])
                }));
                if dist(&p).abs() > 0.6 {
                    continue;
                }
                let mut normal = Vector3::zeros();
                for _ in 0..6 {
                    normal = gradient(&dist, &p);
                    p -= normal * dist(&p);
                }
                let far_from = |q: &Point3<f64>, r: f64| (p - q).norm() > r;
                if dist(&p).abs() > 1e-4
                    || !landmarks.iter().all(|q| far_from(q, LANDMARK_CLEARANCE_MM))
                    || !bumps.iter().all(|b| far_from(&Point3::from(b.center), 1.0))
                {
                    continue;
                }
                let scale = if ossicle == Ossicle::Stapes {
                    0.75
                } else {
                    1.0
                };
                let mut height = scale
                    * (BUMP_HEIGHT_MM.0
                        + rng.random::<f64>() * (BUMP_HEIGHT_MM.1 - BUMP_HEIGHT_MM.0));
                let thick = dist(&(p - normal * 0.4)) < -0.35;
                if rng.random::<bool>() && thick {
                    height = -height;
                }
                let sigma =
                    BUMP_SIGMA_MM.0 + rng.random::<f64>() * (BUMP_SIGMA_MM.1 - BUMP_SIGMA_MM.0);
                bumps.push(Bump {
                    ossicle,
                    center: p.into(),
                    height_mm: height,
                    sigma_mm: sigma,
                });
                placed += 1;
            }
        }
        ShapeDetail { bumps }
    }
}

/// Unit gradient of `f` at `p` by central differences (zero where flat).
fn gradient(f: &impl Fn(&Point3<f64>) -> f64, p: &Point3<f64>) -> Vector3<f64> {
    let h = 1e-5;
    let g = Vector3::from_fn(|k, _| {
        let mut e = Vector3::zeros();
        e[k] = h;
        (f(&(p + e)) - f(&(p - e))) / (2.0 * h)
    });
    g.try_normalize(1e-12).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn a_malleus_rotation_moves_the_umbo_and_keeps_the_joint() {
        let a = Anatomy::default_right().unwrap();
        let imj = a.landmarks().incudomalleolar;
        let motion = OssicleMotion {
            target: MotionTarget::Malleus,
            pivot: imj.into(),
            axis: [0.0, 1.0, 0.0],
            angle_deg: 3.0,
        };
        let moved = Anatomy::from_spec(apply_motions(a.spec(), &[motion]), "test").unwrap();
        let (u0, u1) = (a.landmarks().umbo, moved.landmarks().umbo);
        // the umbo turns on a circle about the pivot: same radius, chord = 2 r sin(θ/2)
        let (r0, r1) = ((u0 - imj).norm(), (u1 - imj).norm());
        assert!((r0 - r1).abs() < 1e-9);
        let chord = 2.0 * r0 * (1.5f64).to_radians().sin() * {
            let axis = Vector3::y();
            let v = u0 - imj;
            (v - axis * axis.dot(&v)).norm() / r0
        };
        assert!(((u1 - u0).norm() - chord).abs() < 1e-9);
        assert_eq!(moved.landmarks().incudomalleolar, imj);
        // the eardrum apex follows the umbo; the incus does not move
        assert_eq!(moved.eardrum().apex, u1);
        let p = Point3::new(0.6, 0.1, 5.3);
        assert_eq!(
            a.bone_distance(Bone::Incus, &p),
            moved.bone_distance(Bone::Incus, &p)
        );
    }

    #[test]
    fn bumps_sit_on_the_surface_away_from_the_landmarks() {
        let a = Anatomy::default_right().unwrap();
        let d = ShapeDetail::draw(&a, &mut ChaCha8Rng::seed_from_u64(5));
        assert_eq!(d.bumps.len(), 12);
        for b in &d.bumps {
            let c = Point3::from(b.center);
            assert!(a.bone_distance(b.ossicle.bone(), &c).abs() < 1e-3);
            assert!((0.07..=0.2).contains(&b.height_mm.abs()));
            for l in a.landmarks().points() {
                assert!((c - l).norm() > LANDMARK_CLEARANCE_MM);
            }
            // at the centre the surface moves by about the height
            assert!((d.offset(b.ossicle, &c) - b.height_mm).abs() < 0.05);
        }
    }
}
