//! Mechanical validation and simulation of an atlas (or of a package: the atlas with
//! registered node positions): umbo displacement under static pressure (UDSP), the stapes
//! velocity transfer function (TFA), the eardrum mesh's convergence, their verdicts against literature bands and against a
//! reference atlas, pathologies of the chain (`condition`) and what they change against
//! temporal bones (`condition_evidence`), and real-time implicit time
//! stepping. Method, bands (and where they come
//! from) and figures: `docs/mechanics.md`; the FEM formulas: `docs/fem.md`.

pub mod boundary;
pub mod condition;
pub mod condition_evidence;
pub mod convergence;
pub mod error;
pub mod evidence;
pub mod simulate;
pub mod tfa;
pub mod udsp;
pub mod validate;
pub mod verdict;

pub use boundary::{MechanicalSystem, Ossicles, TiedPoint};
pub use condition::{Condition, FIXATION_FACTOR};
pub use condition_evidence::{ConditionChange, Velocity, condition_changes};
pub use convergence::{ConvergenceLevel, DrumConvergence, DrumStudy};
pub use error::MechanicsError;
pub use evidence::{Evidence, EvidencePoint, evidence};
pub use tfa::{Drive, TfPoint, TfaOptions, TransferFunction, transfer_function};
pub use udsp::{StaticCurve, UdspOptions, UdspPoint, static_pressure_curve};
pub use validate::{
    Mechanics, Validation, ValidationOptions, mechanics, validate_atlas, validate_package,
    validate_package_against,
};
pub use verdict::{Gate, Verdict, literature_verdict, relative_verdict};
