//! The eardrum as a surface (a membrane, not a volume): a cone with its apex at the umbo and
//! its rim on the elliptic tympanic annulus, the pars flaccida as the superior sector above
//! the lateral process, and the manubrium attachment line along the superior generator.
//!
//! Points are addressed by (s, θ): s ∈ [0, 1] runs from the umbo (0) to the annulus (1) along
//! a generator; θ is the angle on the annulus measured from the superior direction toward
//! anterior. The generators are not straight: the human tympanic membrane is a cone whose
//! radial fibres bow outward, toward the ear canal (Funnell & Laszlo 1978, J Acoust Soc Am
//! 63:1461; Funnell, Decraemer & Khanna 1987, J Acoust Soc Am 81:1851; Fay, Puria & Steele
//! 2006, PNAS 103:19743). Each generator is the straight line plus a lateral parabolic bow
//! of height `radial_sagitta` at its middle. The curvature is what turns canal pressure into
//! membrane tension: without it the cone is several times too stiff and its static response
//! to ±pressure far too asymmetric (docs/mechanics.md).

use nalgebra::{Point3, Vector3};

use super::region::MembraneRegion;
use super::spec::{AnatomyError, Checker, EardrumSpec, Side};

/// The eardrum cone.
#[derive(Debug, Clone, PartialEq)]
pub struct Eardrum {
    /// The apex of the cone: the umbo.
    pub apex: Point3<f64>,
    pub annulus_center: Point3<f64>,
    /// Unit normal of the annulus plane, from the ear canal into the middle ear.
    pub medial_normal: Vector3<f64>,
    /// Unit in-plane direction toward the superior rim.
    pub superior: Vector3<f64>,
    /// Unit in-plane direction toward the anterior rim.
    pub anterior: Vector3<f64>,
    pub semi_axis_superior: f64,
    pub semi_axis_anterior: f64,
    /// Half-angle of the pars flaccida sector (radians).
    pub flaccida_half_angle: f64,
    /// Radial fraction from which the superior sector is pars flaccida.
    pub flaccida_start_fraction: f64,
    /// Lateral bow of each generator at its middle (mm).
    pub radial_sagitta: f64,
}

impl Eardrum {
    /// Builds the cone from its description and the umbo (the manubrium tip).
    pub fn new(
        spec: &EardrumSpec,
        side: Side,
        umbo: Point3<f64>,
        check: &Checker,
    ) -> Result<Eardrum, AnatomyError> {
        let normal = check.direction("eardrum.medial_normal", &spec.medial_normal)?;
        let sup = check.direction("eardrum.superior", &spec.superior)?;
        let frame = check.frame("eardrum.superior", normal, sup)?;
        let anterior = match side {
            Side::Right => normal.cross(&frame.e2),
            Side::Left => frame.e2.cross(&normal),
        };
        let half = spec.flaccida_half_angle_deg;
        if !(half.is_finite() && half > 0.0 && half < 90.0) {
            return Err(check.invalid(
                "eardrum.flaccida_half_angle_deg",
                half.to_string(),
                "an angle in (0, 90) degrees",
            ));
        }
        let start = spec.flaccida_start_fraction;
        if !(start.is_finite() && start > 0.0 && start < 1.0) {
            return Err(check.invalid(
                "eardrum.flaccida_start_fraction",
                start.to_string(),
                "a fraction in (0, 1)",
            ));
        }
        let drum = Eardrum {
            apex: umbo,
            annulus_center: check.point("eardrum.annulus_center", &spec.annulus_center)?,
            medial_normal: normal,
            superior: frame.e2,
            anterior,
            semi_axis_superior: check
                .positive("eardrum.semi_axis_superior_mm", spec.semi_axis_superior_mm)?,
            semi_axis_anterior: check
                .positive("eardrum.semi_axis_anterior_mm", spec.semi_axis_anterior_mm)?,
            flaccida_half_angle: half.to_radians(),
            flaccida_start_fraction: start,
            radial_sagitta: spec.radial_sagitta_mm,
        };
        let shortest = drum.semi_axis_superior.min(drum.semi_axis_anterior);
        if !(drum.radial_sagitta.is_finite()
            && drum.radial_sagitta >= 0.0
            && drum.radial_sagitta < 0.25 * shortest)
        {
            return Err(check.invalid(
                "eardrum.radial_sagitta_mm",
                drum.radial_sagitta.to_string(),
                "a bow in mm, >= 0 and under a quarter of the shorter semi-axis",
            ));
        }
        let depth = drum.depth();
        if depth <= 0.0 {
            return Err(check.invalid(
                "eardrum.annulus_center",
                format!("a cone depth of {depth:.3} mm at the umbo"),
                "the umbo medial to the annulus plane (depth > 0)",
            ));
        }
        Ok(drum)
    }

    /// The annulus point at angle `theta` (radians, from superior toward anterior).
    pub fn rim(&self, theta: f64) -> Point3<f64> {
        self.annulus_center
            + self.superior * (self.semi_axis_superior * theta.cos())
            + self.anterior * (self.semi_axis_anterior * theta.sin())
    }

    /// The membrane point at radial fraction `s` along the generator at angle `theta`: the
    /// straight line from the umbo to the rim, bowed laterally by 4·sagitta·s(1 − s).
    pub fn point(&self, s: f64, theta: f64) -> Point3<f64> {
        self.apex + (self.rim(theta) - self.apex) * s
            - self.medial_normal * (4.0 * self.radial_sagitta * s * (1.0 - s))
    }

    /// Which membrane region (s, θ) belongs to.
    pub fn region(&self, s: f64, theta: f64) -> MembraneRegion {
        let from_superior = theta.sin().atan2(theta.cos()).abs();
        if s > self.flaccida_start_fraction && from_superior < self.flaccida_half_angle {
            MembraneRegion::ParsFlaccida
        } else {
            MembraneRegion::ParsTensa
        }
    }

    /// `n` points evenly spaced in angle around the tympanic annulus (the clamped rim).
    pub fn annulus(&self, n: usize) -> Vec<Point3<f64>> {
        (0..n)
            .map(|k| self.rim(std::f64::consts::TAU * k as f64 / n as f64))
            .collect()
    }

    /// Depth of the cone: distance of the umbo medial to the annulus plane (mm).
    pub fn depth(&self) -> f64 {
        (self.apex - self.annulus_center).dot(&self.medial_normal)
    }

    /// The manubrium attachment line: from the umbo up the superior generator to the lateral
    /// process (where the pars flaccida starts).
    pub fn manubrium_line(&self) -> (Point3<f64>, Point3<f64>) {
        (self.apex, self.point(self.flaccida_start_fraction, 0.0))
    }

    /// Superior–inferior and anterior–posterior diameters of the annulus (mm).
    pub fn diameters(&self) -> (f64, f64) {
        (2.0 * self.semi_axis_superior, 2.0 * self.semi_axis_anterior)
    }
}
