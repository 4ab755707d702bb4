//! Isotropic linear-elastic materials of the solid (tetrahedra) and the membrane (triangles),
//! validated on construction, with their Lamé parameters.
//!
//! Units (mm-g-s): Young's modulus in Pa (= µN/mm²), density in g/mm³ (1 kg/m³ = 1e-6 g/mm³),
//! thickness in mm. Lamé parameters: λ = Eν/((1+ν)(1−2ν)), μ = E/(2(1+ν)); plane stress uses
//! λ* = 2λμ/(λ+2μ) = Eν/(1−ν²), which gives D_ps = E/(1−ν²)[[1,ν,0],[ν,1,0],[0,0,(1−ν)/2]]
//! (docs/fem.md).

use super::error::FemError;

/// Solid material of a tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetMaterial {
    /// Young's modulus E in Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (−1, 0.5).
    pub poisson_ratio: f64,
    /// Density ρ in g/mm³.
    pub density: f64,
}

/// Membrane material of a plane-stress triangle (constant-strain, no bending).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneMaterial {
    /// Young's modulus E in Pa.
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (−1, 0.5).
    pub poisson_ratio: f64,
    /// Thickness h in mm.
    pub thickness: f64,
    /// Flexural thickness h_b in mm of a shell (bending rigidity E h_b³/(12(1 − ν²)));
    /// `None`: a bending-free membrane.
    pub bending_thickness: Option<f64>,
    /// Density ρ in g/mm³.
    pub density: f64,
}

/// The two Lamé parameters of an isotropic law, in Pa.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lame {
    pub lambda: f64,
    pub mu: f64,
}

impl Lame {
    /// Flexural rigidity D = (λ + 2μ) h³/12 of a plate of thickness `h` (mm) of this
    /// plane-stress pair, i.e. E h³/(12(1 − ν²)) (µN·mm).
    pub(crate) fn flexural_rigidity(&self, h: f64) -> f64 {
        (self.lambda + 2.0 * self.mu) * h.powi(3) / 12.0
    }

    /// Poisson's ratio ν = λ/(λ + 2μ) of this plane-stress pair.
    pub(crate) fn plane_stress_poisson_ratio(&self) -> f64 {
        self.lambda / (self.lambda + 2.0 * self.mu)
    }
}

fn check(
    kind: &'static str,
    index: usize,
    field: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), FemError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(FemError::InvalidMaterial {
            kind,
            index,
            field,
            value,
            expected,
        })
    }
}

fn check_elastic(kind: &'static str, index: usize, e: f64, nu: f64) -> Result<(), FemError> {
    check(kind, index, "youngs_modulus", e, e > 0.0, "E > 0 Pa")?;
    check(
        kind,
        index,
        "poisson_ratio",
        nu,
        nu > -1.0 && nu < 0.5,
        "-1 < nu < 0.5",
    )
}

impl TetMaterial {
    /// Checks E > 0, −1 < ν < 0.5, ρ > 0, all finite; `index` names the material in errors.
    pub fn validate(&self, index: usize) -> Result<(), FemError> {
        check_elastic(
            "tetrahedron",
            index,
            self.youngs_modulus,
            self.poisson_ratio,
        )?;
        check(
            "tetrahedron",
            index,
            "density",
            self.density,
            self.density > 0.0,
            "density > 0 g/mm^3",
        )
    }

    pub(crate) fn lame(&self) -> Lame {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        Lame {
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: e / (2.0 * (1.0 + nu)),
        }
    }
}

impl MembraneMaterial {
    /// Checks E > 0, −1 < ν < 0.5, h > 0, ρ > 0, all finite; `index` names the material.
    pub fn validate(&self, index: usize) -> Result<(), FemError> {
        check_elastic("membrane", index, self.youngs_modulus, self.poisson_ratio)?;
        check(
            "membrane",
            index,
            "thickness",
            self.thickness,
            self.thickness > 0.0,
            "thickness > 0 mm",
        )?;
        if let Some(h) = self.bending_thickness {
            check(
                "membrane",
                index,
                "bending thickness",
                h,
                h > 0.0,
                "bending thickness > 0 mm",
            )?;
        }
        check(
            "membrane",
            index,
            "density",
            self.density,
            self.density > 0.0,
            "density > 0 g/mm^3",
        )
    }

    /// Flexural rigidity D = E h_b³/(12(1 − ν²)) (µN·mm with E in Pa = µN/mm²); 0 without
    /// a bending thickness.
    pub fn flexural_rigidity(&self) -> f64 {
        self.bending_thickness
            .map_or(0.0, |h| self.plane_stress_lame().flexural_rigidity(h))
    }

    /// Plane-stress Lamé pair (λ* = Eν/(1−ν²), μ = E/(2(1+ν))).
    pub(crate) fn plane_stress_lame(&self) -> Lame {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        Lame {
            lambda: e * nu / (1.0 - nu * nu),
            mu: e / (2.0 * (1.0 + nu)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_out_of_range_values() {
        let good = TetMaterial {
            youngs_modulus: 1e9,
            poisson_ratio: 0.3,
            density: 1e-3,
        };
        assert!(good.validate(0).is_ok());
        for bad in [
            TetMaterial {
                youngs_modulus: 0.0,
                ..good
            },
            TetMaterial {
                poisson_ratio: 0.5,
                ..good
            },
            TetMaterial {
                poisson_ratio: -1.0,
                ..good
            },
            TetMaterial {
                density: f64::NAN,
                ..good
            },
        ] {
            assert!(matches!(
                bad.validate(3),
                Err(FemError::InvalidMaterial { index: 3, .. })
            ));
        }
        let m = MembraneMaterial {
            youngs_modulus: 3e7,
            poisson_ratio: 0.3,
            thickness: 0.0,
            bending_thickness: None,
            density: 1e-3,
        };
        assert!(matches!(
            m.validate(1),
            Err(FemError::InvalidMaterial {
                field: "thickness",
                ..
            })
        ));
    }

    #[test]
    fn plane_stress_lame_reproduces_d_ps() {
        let m = MembraneMaterial {
            youngs_modulus: 2.0e7,
            poisson_ratio: 0.3,
            thickness: 0.1,
            bending_thickness: None,
            density: 1e-3,
        };
        let l = m.plane_stress_lame();
        let (e, nu) = (m.youngs_modulus, m.poisson_ratio);
        let d11 = e / (1.0 - nu * nu);
        assert!((l.lambda + 2.0 * l.mu - d11).abs() <= 1e-12 * d11);
        assert!((l.lambda - nu * d11).abs() <= 1e-12 * d11);
        assert!((l.mu - d11 * (1.0 - nu) / 2.0).abs() <= 1e-12 * d11);
    }
}
