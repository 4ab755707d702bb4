//! Exit codes: the command line alone decides them. 0 success; 1 a case failed while
//! processing valid input (including a numerical failure or a failed verdict); 2 bad usage,
//! configuration or input data (see the README).

use crate::Error;

/// Exit status of the command line, as documented in the README.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitStatus {
    /// A case (or one case of a cohort) failed while processing valid input.
    CaseFailed = 1,
    /// Bad usage, configuration or input data.
    BadInput = 2,
}

/// The exit status `err` maps to.
pub fn exit_status(err: &Error) -> ExitStatus {
    match err {
        Error::Image(_)
        | Error::Config(_)
        | Error::Landmark(_)
        | Error::Case(_)
        | Error::Cohort(_)
        | Error::MeshIo(_)
        | Error::Anatomy(_)
        | Error::Atlas(_)
        | Error::Usage(_) => ExitStatus::BadInput,
        Error::Structures(e) => match e {
            crate::meshdev::structures::StructuresError::Io { .. } => ExitStatus::CaseFailed,
            _ => ExitStatus::BadInput,
        },
        Error::Phantom(e) => match e {
            crate::phantom::PhantomError::Anatomy { .. }
            | crate::phantom::PhantomError::Write(_)
            | crate::phantom::PhantomError::WriteImage(_)
            | crate::phantom::PhantomError::WriteMesh(_) => ExitStatus::CaseFailed,
            _ => ExitStatus::BadInput,
        },
        Error::Export(e) => match e {
            crate::export::ExportError::File(_) | crate::export::ExportError::Serialise { .. } => {
                ExitStatus::CaseFailed
            }
            crate::export::ExportError::Mechanics(
                crate::mechanics::MechanicsError::InvalidOption { .. },
            ) => ExitStatus::BadInput,
            crate::export::ExportError::Mechanics(_) => ExitStatus::CaseFailed,
            _ => ExitStatus::BadInput,
        },
        Error::Mechanics(e) => match e {
            crate::mechanics::MechanicsError::InvalidOption { .. } => ExitStatus::BadInput,
            _ => ExitStatus::CaseFailed,
        },
        Error::Io { .. } | Error::MeshDev(_) | Error::Report { .. } => ExitStatus::CaseFailed,
    }
}
