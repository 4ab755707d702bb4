//! `validate`: the two mechanical checks (TFA and UDSP) of an atlas at given node positions,
//! and their verdicts — against the literature for the atlas itself, against the atlas for a
//! package (the atlas with registered node positions, which must keep the atlas's behaviour).

use nalgebra::Point3;
use rayon::join;
use serde::Serialize;

use super::boundary::{MechanicalSystem, footplate_area_mm2};
use super::condition::Condition;
use super::condition_evidence::{ConditionChange, condition_changes};
use super::error::MechanicsError;
use super::evidence::{Evidence, evidence};
use super::tfa::{TfaOptions, TransferFunction, transfer_function};
use super::udsp::{StaticCurve, StaticCurveSolver, UdspOptions};
use super::verdict::{Verdict, literature_verdict, relative_verdict};
use crate::atlas::Atlas;
use crate::progress::Reporter;

/// What to compute.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationOptions {
    pub tfa: TfaOptions,
    /// The static-pressure curve; `None` skips it (an empty curve, no UDSP gates for a
    /// package).
    pub udsp: Option<UdspOptions>,
    /// A what-if for the eardrum model: bend its whole membrane at this flexural thickness
    /// (mm; `MechanicalSystem::with_eardrum_bending`) instead of the atlas's own. `None`, the
    /// atlas as it is, is what `run` and `batch` use.
    pub eardrum_bending_mm: Option<f64>,
    /// The ear's condition (`Condition::apply`): a fixation or disarticulation of the atlas
    /// (and, for a package, of the atlas it is gated against).
    pub condition: Condition,
}

impl Default for ValidationOptions {
    /// Both checks with their default sweeps.
    fn default() -> Self {
        ValidationOptions {
            tfa: TfaOptions::default(),
            udsp: Some(UdspOptions::default()),
            eardrum_bending_mm: None,
            condition: Condition::Normal,
        }
    }
}

/// The results of both checks on one geometry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Mechanics {
    pub transfer_function: TransferFunction,
    pub udsp: StaticCurve,
    /// Wall time of the TFA (with the UDSP's solvers built beside it) and of the UDSP's loads
    /// after it (s).
    pub tfa_seconds: f64,
    pub udsp_seconds: f64,
}

/// Runs TFA and UDSP on `atlas` with its rest shape at `nodes`, reporting to `progress`.
pub fn mechanics(
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    options: &ValidationOptions,
    progress: &dyn Reporter,
) -> Result<Mechanics, MechanicsError> {
    let mut system = MechanicalSystem::new(&options.condition.apply(atlas)?, nodes)?;
    if let Some(h) = options.eardrum_bending_mm {
        system = system.with_eardrum_bending(h)?;
    }
    // the static curve's solver is built while the transfer function builds its own: both
    // constructions are serial, and the sweep after them keeps both cores busy
    let t = std::time::Instant::now();
    let ((transfer_function, tfa_seconds), static_solver) = join(
        || {
            let tf = transfer_function(&system, &options.tfa, progress);
            (tf, t.elapsed().as_secs_f64())
        },
        || {
            let udsp = options.udsp.as_ref();
            udsp.map(|u| StaticCurveSolver::new(&system, u)).transpose()
        },
    );
    let (transfer_function, static_solver) = (transfer_function?, static_solver?);
    let t = std::time::Instant::now();
    let udsp = match static_solver {
        Some(solver) => solver.solve(progress)?,
        None => StaticCurve::default(),
    };
    Ok(Mechanics {
        transfer_function,
        udsp,
        tfa_seconds,
        udsp_seconds: t.elapsed().as_secs_f64(),
    })
}

/// The validation of an atlas (literature gates) or of a package (gates relative to the atlas
/// it came from, whose own results are kept as `reference`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Validation {
    /// The ear's condition the checks ran on.
    pub condition: Condition,
    pub mechanics: Mechanics,
    pub reference: Option<Mechanics>,
    pub verdict: Verdict,
    /// An atlas against each measured source, with residuals (`evidence`); empty for a
    /// package, whose gates compare it with its atlas.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub evidence: Vec<Evidence>,
    /// An atlas under a condition: what the condition changes against the normal ear, beside
    /// what temporal bones showed (`condition_evidence`); empty for the normal ear and for a
    /// package.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub changes: Vec<ConditionChange>,
}

/// Validates the atlas against the literature bands.
pub fn validate_atlas(
    atlas: &Atlas,
    options: &ValidationOptions,
    progress: &dyn Reporter,
) -> Result<Validation, MechanicsError> {
    let m = mechanics(atlas, atlas.nodes(), options, progress)?;
    let verdict = literature_verdict(&m.transfer_function, &m.udsp);
    let footplate = footplate_area_mm2(atlas, atlas.nodes())?;
    let changes = if options.condition.is_normal() {
        Vec::new()
    } else {
        progress.log("transfer function of the normal ear (the condition's changes)");
        let normal = ValidationOptions {
            condition: Condition::Normal,
            udsp: None,
            ..options.clone()
        };
        let n = mechanics(atlas, atlas.nodes(), &normal, progress)?;
        condition_changes(
            options.condition,
            &n.transfer_function,
            &m.transfer_function,
        )
    };
    Ok(Validation {
        condition: options.condition,
        changes,
        evidence: evidence(&m.transfer_function, &m.udsp, footplate),
        mechanics: m,
        reference: None,
        verdict,
    })
}

/// Validates a package — `atlas` with its nodes moved to `registered` — against the atlas.
pub fn validate_package(
    atlas: &Atlas,
    registered: &[Point3<f64>],
    options: &ValidationOptions,
    progress: &dyn Reporter,
) -> Result<Validation, MechanicsError> {
    progress.log("mechanics of the atlas (the reference)");
    let reference = mechanics(atlas, atlas.nodes(), options, progress)?;
    validate_package_against(&reference, atlas, registered, options, progress)
}

/// As [`validate_package`], with the atlas's own mechanics (`reference`, computed with the
/// same `options`) already known: a cohort computes them once.
pub fn validate_package_against(
    reference: &Mechanics,
    atlas: &Atlas,
    registered: &[Point3<f64>],
    options: &ValidationOptions,
    progress: &dyn Reporter,
) -> Result<Validation, MechanicsError> {
    progress.log("mechanics of the package");
    let m = mechanics(atlas, registered, options, progress)?;
    let verdict = relative_verdict(
        &m.transfer_function,
        &m.udsp,
        &reference.transfer_function,
        &reference.udsp,
    );
    Ok(Validation {
        condition: options.condition,
        mechanics: m,
        reference: Some(reference.clone()),
        verdict,
        evidence: Vec::new(),
        changes: Vec::new(),
    })
}
