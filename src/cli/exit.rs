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
        // a numerical failure of valid input is the case's failure; nothing found around the
        // placed atlas means the image or the landmarks are not this ear's
        Error::Deform(e) => match e {
            crate::register::deform::DeformError::Fem(_)
            | crate::register::deform::DeformError::FlatElement { .. } => ExitStatus::CaseFailed,
            crate::register::deform::DeformError::NothingFound => ExitStatus::BadInput,
        },
        // no chain in the image is the input's fault; a failed registration of the chain found
        // is the case's
        Error::Propose(e) => match e {
            crate::register::auto_landmarks::ProposeError::Search(_) => ExitStatus::BadInput,
            crate::register::auto_landmarks::ProposeError::Register(
                crate::register::deform::DeformError::NothingFound,
            ) => ExitStatus::BadInput,
            crate::register::auto_landmarks::ProposeError::Register(_) => ExitStatus::CaseFailed,
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
            crate::mechanics::MechanicsError::InvalidOption { .. }
            | crate::mechanics::MechanicsError::NotRebuildable { .. } => ExitStatus::BadInput,
            _ => ExitStatus::CaseFailed,
        },
        // a symbolic link loop among the inputs (a case's segmentation/, say) is the input's
        Error::Io { source, .. } if crate::io_util::is_loop_error(source) => ExitStatus::BadInput,
        Error::Io { .. } | Error::MeshDev(_) | Error::Report { .. } => ExitStatus::CaseFailed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::FemError;
    use crate::register::deform::DeformError;

    #[test]
    fn a_numerical_failure_is_the_cases_failure_and_bad_input_is_bad_input() {
        let fem = Error::from(DeformError::Fem(FemError::NonFinite {
            what: "displacement",
            index: 3,
        }));
        assert_eq!(exit_status(&fem), ExitStatus::CaseFailed);
        let nothing = Error::from(DeformError::NothingFound);
        assert_eq!(exit_status(&nothing), ExitStatus::BadInput);
        let io = Error::from(crate::io_util::io_err(std::path::Path::new("x"))(
            std::io::Error::other("disk full"),
        ));
        assert_eq!(exit_status(&io), ExitStatus::CaseFailed);
        let usage = Error::Usage("--jobs 0".into());
        assert_eq!(exit_status(&usage), ExitStatus::BadInput);
        let link_loop = Error::from(crate::io_util::io_err(std::path::Path::new("seg/x"))(
            crate::io_util::link_loop_error(),
        ));
        assert_eq!(exit_status(&link_loop), ExitStatus::BadInput);
    }
}
