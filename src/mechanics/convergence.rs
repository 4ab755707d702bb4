//! The eardrum's mesh convergence: the atlas rebuilt from the anatomy it was built from with
//! finer eardrum triangles (the bones' tetrahedra at the same edge), its materials carried
//! over, and each rebuild's transfer function and static curve compared with the finest's. A
//! model whose figures still move with the drum's mesh is fitting its discretisation, not
//! the ear (docs/mechanics.md, "The eardrum's own convergence").

use serde::Serialize;

use super::error::MechanicsError;
use super::validate::{Mechanics, ValidationOptions, mechanics};
use crate::atlas::build::anatomy_digest;
use crate::atlas::build::remesh_atlas;
use crate::atlas::{Anatomy, Atlas};
use crate::progress::Reporter;

/// The bound on the transfer function's change against the finest drum (dB, every
/// frequency): the criterion for a converged eardrum.
pub const CONVERGED_DB: f64 = 1.0;

/// The bound on the static curve's change against the finest drum (|Δu| / |u|, every
/// pressure but 0).
pub const CONVERGED_STATIC_FRACTION: f64 = 0.05;

/// The refinements studied: the atlas's own drum edge divided by √2 and by 2 (about twice and
/// four times the triangles).
pub const REFINEMENTS: [f64; 2] = [std::f64::consts::SQRT_2, 2.0];

/// One drum mesh of the study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConvergenceLevel {
    pub membrane_edge_mm: f64,
    pub membrane_triangles: usize,
    /// How the drum was tied to the manubrium (the build's provenance).
    pub manubrium_attachment: String,
    /// Largest |ΔdB| of the stapes velocity against the finest drum, over the frequencies.
    pub worst_db: f64,
    /// Largest |Δphase| against the finest drum (degrees).
    pub worst_phase_deg: f64,
    /// Largest |Δu| / |u| of the umbo displacement against the finest drum, over the
    /// pressures (a fraction; 0 for the finest itself).
    pub worst_static_fraction: f64,
    /// The asymmetry |u(−4 kPa)| / |u(+4 kPa)| of this drum, if both were reached.
    pub asymmetry: Option<f64>,
}

/// The study: the levels from the atlas's own drum to the finest.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DrumConvergence {
    pub levels: Vec<ConvergenceLevel>,
    pub bound_db: f64,
    pub bound_static_fraction: f64,
    /// Whether the atlas's own drum (the first level) is within both bounds of the finest.
    pub converged: bool,
}

/// The convergence study of an atlas built from an anatomy, checked before any solve.
#[derive(Debug, Clone, Copy)]
pub struct DrumStudy<'a> {
    atlas: &'a Atlas,
    anatomy: &'a Anatomy,
    tet_edge_mm: f64,
    membrane_edge_mm: f64,
}

impl<'a> DrumStudy<'a> {
    /// The study of `atlas`, which must have been built from `anatomy` by `otoatlas atlas
    /// build` (its provenance says so, with the two edges it was meshed at).
    pub fn new(atlas: &'a Atlas, anatomy: &'a Anatomy) -> Result<Self, MechanicsError> {
        let provenance = |key: &str| atlas.provenance.get(key).map(String::as_str);
        let expected = anatomy_digest(anatomy);
        if provenance("anatomy_sha256") != Some(expected.as_str()) {
            return Err(MechanicsError::NotRebuildable {
                what: format!(
                    "expected the anatomy the atlas was built from (give it with --anatomy): \
                     the atlas's provenance anatomy_sha256 is {:?}, the anatomy's {expected}",
                    provenance("anatomy_sha256").unwrap_or("absent")
                ),
            });
        }
        let edge = |key: &str| -> Result<f64, MechanicsError> {
            provenance(key)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite() && *v > 0.0)
                .ok_or_else(|| MechanicsError::NotRebuildable {
                    what: format!(
                        "the atlas's provenance {key}: expected the build's edge in mm (> 0)"
                    ),
                })
        };
        Ok(DrumStudy {
            atlas,
            anatomy,
            tet_edge_mm: edge("tet_edge_mm")?,
            membrane_edge_mm: edge("membrane_edge_mm")?,
        })
    }

    /// Rebuilds the atlas at its drum edge divided by each of [`REFINEMENTS`] and compares
    /// the mechanics, the atlas's own (`own`, computed with `options`) first. The atlas's
    /// regions, materials, damping and supports are those of every rebuild, so an atlas whose
    /// materials were edited is studied with its own.
    pub fn run(
        &self,
        own: &Mechanics,
        options: &ValidationOptions,
        progress: &dyn Reporter,
    ) -> Result<DrumConvergence, MechanicsError> {
        let atlas = self.atlas;
        let membrane_edge = self.membrane_edge_mm;
        let mut results = vec![(membrane_edge, atlas.mesh.triangles.len(), own.clone())];
        let attachment = |a: &Atlas| {
            a.provenance
                .get("manubrium_attachment")
                .cloned()
                .unwrap_or_default()
        };
        let mut attachments = vec![attachment(atlas)];
        for divisor in REFINEMENTS {
            let fine_edge = membrane_edge / divisor;
            progress.log(&format!(
                "eardrum convergence: the atlas rebuilt with {fine_edge:.3} mm drum triangles"
            ));
            let fine = remesh_atlas(self.anatomy, atlas, self.tet_edge_mm, fine_edge)
                .map_err(MechanicsError::Rebuild)?;
            let m = mechanics(&fine, fine.nodes(), options, progress)?;
            attachments.push(attachment(&fine));
            results.push((fine_edge, fine.mesh.triangles.len(), m));
        }
        let finest = &results[results.len() - 1].2;
        let levels: Vec<ConvergenceLevel> = results
            .iter()
            .zip(attachments)
            .map(
                |((edge, triangles, m), manubrium_attachment)| ConvergenceLevel {
                    membrane_edge_mm: *edge,
                    membrane_triangles: *triangles,
                    manubrium_attachment,
                    worst_db: worst(
                        &m.transfer_function.points,
                        &finest.transfer_function.points,
                        |a, b| (a.db() - b.db()).abs(),
                    ),
                    worst_phase_deg: worst(
                        &m.transfer_function.points,
                        &finest.transfer_function.points,
                        |a, b| (a.phase_deg - b.phase_deg).abs(),
                    ),
                    worst_static_fraction: worst(&m.udsp.points, &finest.udsp.points, |a, b| {
                        if a.pressure_pa == 0.0 {
                            0.0
                        } else {
                            (a.umbo_mm / b.umbo_mm - 1.0).abs()
                        }
                    }),
                    asymmetry: m.udsp.asymmetry(),
                },
            )
            .collect();
        let own_level = &levels[0];
        Ok(DrumConvergence {
            converged: own_level.worst_db <= CONVERGED_DB
                && own_level.worst_static_fraction <= CONVERGED_STATIC_FRACTION,
            levels,
            bound_db: CONVERGED_DB,
            bound_static_fraction: CONVERGED_STATIC_FRACTION,
        })
    }
}

/// The largest `diff` over pairs of points; infinite when the lists differ in length (a
/// branch that stopped short is not converged).
fn worst<T>(a: &[T], b: &[T], diff: impl Fn(&T, &T) -> f64) -> f64 {
    if a.len() != b.len() {
        return f64::INFINITY;
    }
    a.iter().zip(b).map(|(x, y)| diff(x, y)).fold(0.0, f64::max)
}
