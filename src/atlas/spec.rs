//! The anatomy file (`assets/anatomy.toml`) as typed data: serde schema with unknown keys
//! refused, and the checks that turn it into valid geometry (positive radii, tubes whose
//! successive spheres do not swallow each other, non-degenerate frames).
//!
//! Coordinates are in the atlas frame (see `docs/anatomy.md`): millimetres, axes of DICOM
//! LPS (x toward the patient's left, y posterior, z superior), origin at the umbo.

use std::path::Path;

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

pub use crate::ear::Side;

use super::sdf::{Disc, Ellipsoid, Frame, Primitive, Tube};

/// Errors reading or checking an anatomy description.
#[derive(Debug, thiserror::Error)]
pub enum AnatomyError {
    #[error("{origin}: cannot read the anatomy: {source}")]
    Read {
        origin: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("{origin}: `{field}` is {value}, expected {expected}")]
    Invalid {
        origin: String,
        field: String,
        value: String,
        expected: &'static str,
    },
}

/// The whole anatomy file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnatomySpec {
    pub side: Side,
    pub malleus: MalleusSpec,
    pub incus: IncusSpec,
    pub stapes: StapesSpec,
    pub joints: JointsSpec,
    pub ligaments: LigamentsSpec,
    pub tendons: TendonsSpec,
    pub eardrum: EardrumSpec,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MalleusSpec {
    /// Smooth-union blend radius between the primitives of the bone (mm).
    pub blend_mm: f64,
    pub head: Vec<PrimitiveSpec>,
    pub neck: Vec<PrimitiveSpec>,
    pub anterior_process: Vec<PrimitiveSpec>,
    pub lateral_process: Vec<PrimitiveSpec>,
    /// The handle; its last node is the umbo.
    pub manubrium: TubeSpec,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IncusSpec {
    pub blend_mm: f64,
    pub body: Vec<PrimitiveSpec>,
    pub short_process: Vec<PrimitiveSpec>,
    pub long_process: Vec<PrimitiveSpec>,
    pub lenticular_process: Vec<PrimitiveSpec>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StapesSpec {
    pub blend_mm: f64,
    pub head: Vec<PrimitiveSpec>,
    pub anterior_crus: TubeSpec,
    pub posterior_crus: TubeSpec,
    /// The footplate; its normal points medially, into the vestibule.
    pub footplate: DiscSpec,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointsSpec {
    pub incudomalleolar: DiscSpec,
    pub incudostapedial: DiscSpec,
}

/// Each ligament is a tube whose first node lies in its ossicle and last node is the anchor
/// on the cavity wall.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LigamentsSpec {
    pub superior_malleal: TubeSpec,
    pub anterior_malleal: TubeSpec,
    pub lateral_malleal: TubeSpec,
    pub posterior_incudal: TubeSpec,
}

/// Tendons, as ligaments: first node in the ossicle, last node at the wall.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TendonsSpec {
    pub tensor_tympani: TubeSpec,
    pub stapedius: TubeSpec,
}

/// The eardrum as a cone surface: apex at the umbo, rim on the elliptic tympanic annulus,
/// its generators bowed toward the ear canal by `radial_sagitta_mm`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EardrumSpec {
    pub annulus_center: [f64; 3],
    /// Normal of the annulus plane pointing from the ear canal into the middle ear.
    pub medial_normal: [f64; 3],
    /// In-plane direction toward the superior rim (made orthogonal to the normal).
    pub superior: [f64; 3],
    pub semi_axis_superior_mm: f64,
    pub semi_axis_anterior_mm: f64,
    /// Half-angle (degrees, about the superior direction) of the pars flaccida sector.
    pub flaccida_half_angle_deg: f64,
    /// Radial fraction (0 = umbo, 1 = annulus) above which the superior sector is pars
    /// flaccida: the lateral process of the malleus.
    pub flaccida_start_fraction: f64,
    /// Radial curvature: how far (mm) each generator bows laterally, toward the ear canal,
    /// at its middle (a parabolic arc from umbo to annulus). 0, the default, is the
    /// straight-generator cone.
    #[serde(default)]
    pub radial_sagitta_mm: f64,
}

/// A primitive as written in the file, tagged by `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PrimitiveSpec {
    Tube(TubeSpec),
    Ellipsoid(EllipsoidSpec),
    Disc(DiscSpec),
}

/// A tapered tube: nodes (mm) and the radius at each node (mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubeSpec {
    pub points: Vec<[f64; 3]>,
    pub radii: Vec<f64>,
}

/// An ellipsoid: semi-axes along `axis_1`, along `axis_2` made orthogonal to `axis_1`, and
/// along their cross product.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EllipsoidSpec {
    pub center: [f64; 3],
    pub semi_axes: [f64; 3],
    pub axis_1: [f64; 3],
    pub axis_2: [f64; 3],
}

/// An elliptic plate: semi-axes along `long_axis` (made orthogonal to `normal`) and across,
/// and its thickness along `normal`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscSpec {
    pub center: [f64; 3],
    pub normal: [f64; 3],
    pub long_axis: [f64; 3],
    pub semi_axes: [f64; 2],
    pub thickness: f64,
}

impl AnatomySpec {
    /// Reads an anatomy file.
    pub fn load(path: &Path) -> Result<AnatomySpec, AnatomyError> {
        let origin = path.display().to_string();
        let text = crate::io_util::read_text(path).map_err(|source| AnatomyError::Read {
            origin: origin.clone(),
            source,
        })?;
        AnatomySpec::from_toml_str(&text, &origin)
    }

    /// Parses an anatomy description; `origin` names it in messages. Only the syntax and
    /// the schema are checked here; the geometry is checked by [`Checker`] on conversion.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<AnatomySpec, AnatomyError> {
        toml::from_str(text).map_err(|e| AnatomyError::Parse {
            origin: origin.to_string(),
            message: e.to_string().trim_end().replace('\n', " "),
        })
    }

    /// The mirror image in the plane x = 0 (right ear ↔ left ear).
    pub fn mirrored(&self) -> AnatomySpec {
        let mut m = self.clone();
        m.side = self.side.other();
        m.visit_vectors(&mut |v| v[0] = -v[0]);
        m
    }

    /// Applies `f` to every point and direction of the description.
    fn visit_vectors(&mut self, f: &mut dyn FnMut(&mut [f64; 3])) {
        let m = &mut self.malleus;
        for p in m
            .head
            .iter_mut()
            .chain(&mut m.neck)
            .chain(&mut m.anterior_process)
            .chain(&mut m.lateral_process)
        {
            p.visit_vectors(f);
        }
        m.manubrium.visit_vectors(f);
        let i = &mut self.incus;
        for p in i
            .body
            .iter_mut()
            .chain(&mut i.short_process)
            .chain(&mut i.long_process)
            .chain(&mut i.lenticular_process)
        {
            p.visit_vectors(f);
        }
        let s = &mut self.stapes;
        for p in &mut s.head {
            p.visit_vectors(f);
        }
        s.anterior_crus.visit_vectors(f);
        s.posterior_crus.visit_vectors(f);
        s.footplate.visit_vectors(f);
        self.joints.incudomalleolar.visit_vectors(f);
        self.joints.incudostapedial.visit_vectors(f);
        let l = &mut self.ligaments;
        for t in [
            &mut l.superior_malleal,
            &mut l.anterior_malleal,
            &mut l.lateral_malleal,
            &mut l.posterior_incudal,
            &mut self.tendons.tensor_tympani,
            &mut self.tendons.stapedius,
        ] {
            t.visit_vectors(f);
        }
        let e = &mut self.eardrum;
        f(&mut e.annulus_center);
        f(&mut e.medial_normal);
        f(&mut e.superior);
    }
}

impl PrimitiveSpec {
    fn visit_vectors(&mut self, f: &mut dyn FnMut(&mut [f64; 3])) {
        match self {
            PrimitiveSpec::Tube(t) => t.visit_vectors(f),
            PrimitiveSpec::Ellipsoid(e) => {
                f(&mut e.center);
                f(&mut e.axis_1);
                f(&mut e.axis_2);
            }
            PrimitiveSpec::Disc(d) => d.visit_vectors(f),
        }
    }
}

impl TubeSpec {
    fn visit_vectors(&mut self, f: &mut dyn FnMut(&mut [f64; 3])) {
        self.points.iter_mut().for_each(f);
    }
}

impl DiscSpec {
    fn visit_vectors(&mut self, f: &mut dyn FnMut(&mut [f64; 3])) {
        f(&mut self.center);
        f(&mut self.normal);
        f(&mut self.long_axis);
    }
}

/// Checks values and converts them into geometry, naming the offending field on error.
pub struct Checker<'a> {
    pub origin: &'a str,
}

impl Checker<'_> {
    pub fn invalid(&self, field: &str, value: String, expected: &'static str) -> AnatomyError {
        AnatomyError::Invalid {
            origin: self.origin.to_string(),
            field: field.to_string(),
            value,
            expected,
        }
    }

    pub fn positive(&self, field: &str, v: f64) -> Result<f64, AnatomyError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(field, v.to_string(), "a finite number > 0"))
        }
    }

    pub fn non_negative(&self, field: &str, v: f64) -> Result<f64, AnatomyError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(field, v.to_string(), "a finite number >= 0"))
        }
    }

    pub fn point(&self, field: &str, v: &[f64; 3]) -> Result<Point3<f64>, AnatomyError> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(Point3::from(*v))
        } else {
            Err(self.invalid(field, format!("{v:?}"), "three finite coordinates (mm)"))
        }
    }

    pub fn direction(&self, field: &str, v: &[f64; 3]) -> Result<Vector3<f64>, AnatomyError> {
        let p = self.point(field, v)?;
        p.coords
            .try_normalize(1e-12)
            .ok_or_else(|| self.invalid(field, format!("{v:?}"), "a non-zero direction"))
    }

    pub fn frame(
        &self,
        field: &str,
        first: Vector3<f64>,
        second: Vector3<f64>,
    ) -> Result<Frame, AnatomyError> {
        Frame::from_axes(first, second).ok_or_else(|| {
            self.invalid(
                field,
                format!("{second:?} against {first:?}"),
                "two non-parallel directions",
            )
        })
    }

    pub fn tube(&self, field: &str, t: &TubeSpec) -> Result<Tube, AnatomyError> {
        if t.points.len() < 2 || t.points.len() != t.radii.len() {
            return Err(self.invalid(
                field,
                format!("{} points and {} radii", t.points.len(), t.radii.len()),
                "at least 2 points and one radius per point",
            ));
        }
        let mut points = Vec::with_capacity(t.points.len());
        let mut radii = Vec::with_capacity(t.radii.len());
        for (k, (p, r)) in t.points.iter().zip(&t.radii).enumerate() {
            points.push(self.point(&format!("{field}.points[{k}]"), p)?);
            radii.push(self.positive(&format!("{field}.radii[{k}]"), *r)?);
        }
        for k in 1..points.len() {
            let len = (points[k] - points[k - 1]).norm();
            if len <= (radii[k] - radii[k - 1]).abs() {
                return Err(self.invalid(
                    &format!("{field}.points[{k}]"),
                    format!("{len:.3} mm from the previous node"),
                    "a segment longer than the difference of its end radii",
                ));
            }
        }
        Ok(Tube { points, radii })
    }

    pub fn disc(&self, field: &str, d: &DiscSpec) -> Result<Disc, AnatomyError> {
        let normal = self.direction(&format!("{field}.normal"), &d.normal)?;
        let long = self.direction(&format!("{field}.long_axis"), &d.long_axis)?;
        let f = self.frame(&format!("{field}.long_axis"), normal, long)?;
        Ok(Disc {
            center: self.point(&format!("{field}.center"), &d.center)?,
            // e1 = long axis, e2 = across, e3 = normal.
            frame: Frame {
                e1: f.e2,
                e2: f.e3,
                e3: f.e1,
            },
            semi_axes: [
                self.positive(&format!("{field}.semi_axes[0]"), d.semi_axes[0])?,
                self.positive(&format!("{field}.semi_axes[1]"), d.semi_axes[1])?,
            ],
            thickness: self.positive(&format!("{field}.thickness"), d.thickness)?,
        })
    }

    pub fn primitive(&self, field: &str, p: &PrimitiveSpec) -> Result<Primitive, AnatomyError> {
        Ok(match p {
            PrimitiveSpec::Tube(t) => Primitive::Tube(self.tube(field, t)?),
            PrimitiveSpec::Disc(d) => Primitive::Disc(self.disc(field, d)?),
            PrimitiveSpec::Ellipsoid(e) => {
                let a1 = self.direction(&format!("{field}.axis_1"), &e.axis_1)?;
                let a2 = self.direction(&format!("{field}.axis_2"), &e.axis_2)?;
                let mut semi = Vector3::zeros();
                for k in 0..3 {
                    semi[k] = self.positive(&format!("{field}.semi_axes[{k}]"), e.semi_axes[k])?;
                }
                Primitive::Ellipsoid(Ellipsoid {
                    center: self.point(&format!("{field}.center"), &e.center)?,
                    frame: self.frame(&format!("{field}.axis_2"), a1, a2)?,
                    semi_axes: semi,
                })
            }
        })
    }

    /// A non-empty list of primitives.
    pub fn primitives(
        &self,
        field: &str,
        list: &[PrimitiveSpec],
    ) -> Result<Vec<Primitive>, AnatomyError> {
        if list.is_empty() {
            return Err(self.invalid(field, "empty".into(), "at least one primitive"));
        }
        list.iter()
            .enumerate()
            .map(|(k, p)| self.primitive(&format!("{field}[{k}]"), p))
            .collect()
    }
}
