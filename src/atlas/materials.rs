//! Mechanical data of the atlas, in ONE place: Table 1 of Kazmitcheff et al. 2013 exactly
//! (density kg/m³, Young's modulus Pa), converted once to the FEM's mm-g-s system (density
//! g/mm³ = 1e-6 × kg/m³; Young's modulus stays in Pa = µN/mm²), plus the values Table 1 does
//! not give, each with its literature source.
//!
//! Sources (numbers as in the source table):
//! - \[K13\] Kazmitcheff, Duriez, Miroir, Nguyen, Sterkers, Bozorg-Grayeli, Cotin 2013,
//!   "Registration of a validated mechanical atlas of middle ear for surgical simulation",
//!   MICCAI 2013, Table 1.
//! - \[Ko02\] Koike, Wada, Kobayashi 2002, J Acoust Soc Am 111:1306–1317, as tabulated in
//!   Gentil et al. 2016, BioMed Eng OnLine 15 (doi 10.1186/s12938-016-0149-2), Table 1:
//!   tensor tympani tendon E = 2.6e6 Pa, ρ = 2.5e3 kg/m³.
//! - \[Su02\] Sun, Gan, Chang, Dormer 2002, Biomech Model Mechanobiol 1:109–122: Poisson's
//!   ratio 0.3 for every middle-ear structure (same table of Gentil et al. 2016).
//! - \[Ki60\] Kirikae 1960, "The structure and function of the middle ear": pars tensa
//!   thickness 0.074 mm, the value used by Gan et al. 2004 (Ann Biomed Eng 32:847).
//! - \[Li70\] Lim 1970, Acta Otolaryngol 70:176: pars flaccida thicker than the pars tensa
//!   (about 30–230 µm); the 0.1 mm used here is mid-range and commonly used in models.
//! - \[W16\] Wang, Gan et al. 2016, Biomech Model Mechanobiol 15:1263 (PMC4955651), Table 2:
//!   Rayleigh stiffness-damping coefficients β = 0.75e-4 to 1.5e-4 s, TM and stapes 1.0e-4 s;
//!   incudostapedial joint E = 6 MPa, density 1000 kg/m³.
//! - \[Kw15\] Kwacz, Rymuza, Michalowski, Wysocki 2015, JARO 16:433–446: the annular ligament
//!   is linear up to ~100 nm deflection with a stiffness of about 120 N/m (AFM, temporal
//!   bones).
//! - \[TC13\] Todd & Creighton 2013, Ann Otol Rhinol Laryngol 122:60 ("Malleus and incus:
//!   correlates of size", 41 adult crania): mallei weighed 21.2–30.7 mg, incudes 24.4–37.4 mg.
//! - \[A01\] Aibara, Welsh, Puria, Goode 2001, Hear Res 152:100: cochlear input impedance of
//!   12 fresh temporal bones, mean 21.1 GΩ (MKS acoustic, Pa·s/m³ × 1e9), flat from 0.1 to
//!   5 kHz, angle near 0; with a footplate area of 3.3 mm² the dashpot is Z_c·A² ≈ 0.23 N·s/m.

use super::region::{MembraneRegion, Region};

/// A structure of Table 1: a volumetric region or an eardrum membrane region.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Structure {
    Volume(Region),
    Membrane(MembraneRegion),
}

/// kg/m³ → g/mm³ (1 kg = 1e3 g, 1 m³ = 1e9 mm³).
pub const KG_PER_M3_TO_G_PER_MM3: f64 = 1e-6;

/// Poisson's ratio of every volumetric structure \[Su02\].
pub const POISSON: f64 = 0.3;

/// Table 1 of \[K13\] as printed: (structure, density kg/m³, Young's modulus Pa). The tensor
/// tympani modulus is missing from the printed table and is taken from \[Ko02\].
pub const TABLE1: [(Structure, f64, f64); 17] = [
    (
        Structure::Membrane(MembraneRegion::ParsTensa),
        1.20e3,
        3.34e7,
    ),
    (
        Structure::Membrane(MembraneRegion::ParsFlaccida),
        1.20e3,
        1.10e7,
    ),
    (Structure::Volume(Region::MalleusHandle), 3.70e3, 1.41e10),
    (Structure::Volume(Region::MalleusHead), 2.55e3, 1.41e10),
    (Structure::Volume(Region::MalleusNeck), 4.53e3, 1.41e10),
    (Structure::Volume(Region::IncusBody), 2.36e3, 1.41e10),
    (
        Structure::Volume(Region::IncusShortProcess),
        2.26e3,
        1.41e10,
    ),
    (Structure::Volume(Region::IncusLongProcess), 5.08e3, 1.41e10),
    (Structure::Volume(Region::Stapes), 2.20e3, 1.41e10),
    (
        Structure::Volume(Region::SuperiorMallealLigament),
        2.50e3,
        4.90e4,
    ),
    (
        Structure::Volume(Region::IncudostapedialJoint),
        2.50e3,
        6.00e5,
    ),
    (
        Structure::Volume(Region::IncudomalleolarJoint),
        2.50e3,
        1.41e10,
    ),
    (
        Structure::Volume(Region::AnteriorMallealLigament),
        2.50e3,
        2.10e7,
    ),
    (
        Structure::Volume(Region::LateralMallealLigament),
        2.50e3,
        6.70e4,
    ),
    (
        Structure::Volume(Region::PosteriorIncudalLigament),
        2.50e3,
        6.50e5,
    ),
    (
        Structure::Volume(Region::TensorTympaniTendon),
        2.50e3,
        2.6e6,
    ),
    (Structure::Volume(Region::StapediusTendon), 2.50e3, 5.20e5),
];

/// The incudostapedial joint's density (kg/m³) and Young's modulus (Pa) \[W16\], used instead of
/// Table 1's 6e5 Pa. Since the atlas's bones meet only through their joints, the joint is in
/// the load path, and with 6e5 Pa the stapes rides on it (a mode near 315 Hz, a 250–500 Hz
/// slope of 12.8 dB/octave, outside the Goode band). This value was chosen after seeing that,
/// so the slope gate is no independent evidence for it (docs/mechanics.md, Joints).
pub const ISJ_DENSITY_KG_M3: f64 = 1.0e3;
pub const ISJ_YOUNG_PA: f64 = 6.0e6;
pub const ISJ_SOURCE: &str = "Wang, Gan et al. 2016, Biomech Model Mechanobiol 15:1263, Table 2 \
     (Kazmitcheff et al. 2013 Table 1 gives 6e5 Pa; docs/mechanics.md, Joints)";

/// The malleus's density (kg/m³), one value for its head, neck and handle, used instead of
/// Table 1's 2.55e3 / 4.53e3 / 3.70e3. Those were set for the source study's own regions; on this
/// atlas's regions they weigh the malleus 38.3 mg, above all of the 21.2–30.7 mg that \[TC13\]
/// weighed (and 4.53e3 is no bone's density). This value weighs the default anatomy's malleus
/// (10.32 mm³; every mesh of it carries the anatomy's masses, `atlas::mass`) 26.0 mg, the
/// middle of that range: it is fitted to a measured mass, not to any mechanical gate
/// (docs/mechanics.md, "The malleus's mass"). The incus (34.4 mg) and the stapes keep Table 1's
/// densities.
pub const MALLEUS_DENSITY_KG_M3: f64 = 2.52e3;
pub const MALLEUS_DENSITY_SOURCE: &str = "density: 26.0 mg over the default anatomy's 10.32 \
     mm3 of malleus, the middle of the 21.2-30.7 mg weighed by Todd & Creighton 2013, Ann Otol \
     Rhinol Laryngol 122:60 (Kazmitcheff et al. 2013 Table 1's region densities weigh this \
     malleus 40.6 mg; docs/mechanics.md); E: Kazmitcheff et al. 2013, Table 1";

/// Eardrum thickness (mm), from the literature: pars tensa 0.074 mm \[Ki60\], pars flaccida
/// 0.1 mm \[Li70\] (the measured pars tensa range is ~0.04-0.12 mm, Kuypers et al. 2006, Hear
/// Res 213:120 \[M\]). The eardrum is a thin shell of this thickness: in-plane stiffness E·h
/// and flexural rigidity E·h³/(12(1 − ν²)) (`bending_thickness_mm` of its atlas regions). The
/// same value is what the phantoms render.
pub fn membrane_thickness_mm(region: MembraneRegion) -> f64 {
    match region {
        MembraneRegion::ParsTensa => 0.074,
        MembraneRegion::ParsFlaccida => 0.1,
    }
}

/// Rayleigh damping C = α M + β K (frozen in the atlas file; docs/fem.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rayleigh {
    /// Mass-proportional coefficient α (1/s).
    pub alpha_per_s: f64,
    /// Stiffness-proportional coefficient β (s).
    pub beta_s: f64,
}

/// Rayleigh coefficients from the literature: β = 1.0e-4 s, the eardrum's and stapes' value
/// in \[W16\] (range 0.75e-4 to 1.5e-4 s); no mass-proportional term (α = 0): with the cochlear load, β is all
/// the damping the atlas needs to land in the transfer-function bands.
pub const RAYLEIGH: Rayleigh = Rayleigh {
    alpha_per_s: 0.0,
    beta_s: 1.0e-4,
};

/// Cochlear input impedance Z_c (Pa·s/m³): 2.11e10, the mean of \[A01\]'s 12 temporal bones
/// (literature, not calibrated). Until 2026-12-01 the atlas had 1.0e10, set with the first
/// atlas's calibrations (commit 51522bb) and then listed as chosen; docs/mechanics.md,
/// "Parameters", gives what the change moved.
pub const COCHLEAR_IMPEDANCE_PA_S_PER_M3: f64 = 2.11e10;

/// Where the damping values come from (stored with them in the atlas file).
pub const DAMPING_SOURCE: &str = "literature, not calibrated (docs/mechanics.md): Rayleigh \
     beta 1.0e-4 s, the eardrum's value in Wang, Gan et al. 2016, Biomech Model Mechanobiol \
     15:1263, Table 2, and alpha 0; cochlear impedance 2.11e10 Pa s/m^3, the mean of 12 \
     temporal bones in Aibara et al. 2001, Hear Res 152:100";

/// Total stiffness of the stapedial annular ligament (N/m), shared by isotropic springs on
/// the footplate rim nodes: 120 N/m, the AFM value of \[Kw15\] (measured at one point of the
/// footplate, linear up to ~100 nm; taken here as the whole ring's stiffness).
pub const ANNULAR_LIGAMENT_STIFFNESS_N_PER_M: f64 = 120.0;

/// Where the annular ligament stiffness comes from.
pub const ANNULAR_LIGAMENT_SOURCE: &str = "literature, not calibrated (docs/mechanics.md): \
     Kwacz, Rymuza, Michalowski, Wysocki 2015, JARO 16:433 (AFM on temporal bones: linear up \
     to ~100 nm, about 120 N/m), taken as the whole ring's stiffness";

/// Total cochlear dashpot on the footplate, Z_c · A² with A the footplate area in m², in the
/// mm-g-s unit g/s (1 N·s/m = 1 kg/s = 1000 g/s; g/s × mm/s = g·mm/s² = µN). For
/// A = 3.2 mm² it is 0.205 N·s/m = 205 g/s. Spread it over the footplate nodes in proportion
/// to their area.
pub fn cochlear_damping_g_per_s(footplate_area_mm2: f64) -> f64 {
    cochlear_damping_for(COCHLEAR_IMPEDANCE_PA_S_PER_M3, footplate_area_mm2)
}

/// Total cochlear dashpot (g/s) of an impedance `z_c` (Pa·s/m³) on a footplate of
/// `footplate_area_mm2`: Z_c · A², as [`cochlear_damping_g_per_s`].
pub fn cochlear_damping_for(z_c: f64, footplate_area_mm2: f64) -> f64 {
    let area_m2 = footplate_area_mm2 * 1e-6;
    z_c * area_m2 * area_m2 * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_table_row_is_listed_once() {
        for r in Region::ALL {
            let n = TABLE1
                .iter()
                .filter(|t| t.0 == Structure::Volume(r))
                .count();
            assert_eq!(n, 1, "{}", r.name());
        }
        for m in [MembraneRegion::ParsTensa, MembraneRegion::ParsFlaccida] {
            assert_eq!(
                TABLE1
                    .iter()
                    .filter(|t| t.0 == Structure::Membrane(m))
                    .count(),
                1
            );
        }
    }

    #[test]
    fn units_are_converted_once_to_mm_g_s() {
        // pars tensa: 1.2e3 kg/m³ = 1.2e-3 g/mm³; the modulus stays in Pa (µN/mm²)
        let row = |structure: Structure| TABLE1.iter().find(|r| r.0 == structure).copied();
        let tensa = row(Structure::Membrane(MembraneRegion::ParsTensa));
        assert!(tensa.is_some_and(|(_, rho, e)| {
            (rho * KG_PER_M3_TO_G_PER_MM3 - 1.2e-3).abs() < 1e-15 && e == 3.34e7
        }));
        // 0.2 N·s/m = 200 g/s for a 3.2 mm² footplate at 2e10 Pa·s/m³ (within 3 %).
        let c = cochlear_damping_for(2.0e10, 3.2);
        assert!((c - 204.8).abs() < 1e-9, "{c}");
    }
}
