//! The crate-level error: every module's error folds into it, and each maps to an exit code
//! (0 ok, 1 a case failed, 2 bad usage, configuration or input).

use std::path::PathBuf;

/// Exit status of the command line, as documented in the README.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExitStatus {
    /// A case (or one case of a cohort) failed while processing valid input.
    CaseFailed = 1,
    /// Bad usage, configuration or input data.
    BadInput = 2,
}

/// Any error the library reports to the command line.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Image(#[from] crate::image::ImageError),
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    #[error(transparent)]
    Landmark(#[from] crate::register::landmarks::LandmarkError),
    #[error(transparent)]
    Case(#[from] crate::pipeline::case::CaseNotFound),
    #[error(transparent)]
    Cohort(#[from] crate::pipeline::cohort::CohortError),
    #[error(transparent)]
    MeshDev(#[from] crate::meshdev::MeshDevError),
    #[error(transparent)]
    MeshIo(#[from] crate::mesh::io::MeshIoError),
    #[error(transparent)]
    Structures(#[from] crate::meshdev::structures::StructuresError),
    #[error(transparent)]
    Anatomy(#[from] crate::atlas::AnatomyError),
    #[error(transparent)]
    Atlas(#[from] crate::atlas::AtlasError),
    #[error(transparent)]
    Phantom(#[from] crate::phantom::PhantomError),
    #[error(transparent)]
    Mechanics(#[from] crate::mechanics::MechanicsError),
    #[error("{path}: cannot write the report: {source}")]
    Report {
        path: PathBuf,
        #[source]
        source: crate::report::ReportError,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Usage(String),
}

impl From<crate::ear::LandmarkFileError> for Error {
    fn from(e: crate::ear::LandmarkFileError) -> Error {
        Error::Landmark(e.into())
    }
}

impl From<crate::io_util::FileError> for Error {
    fn from(crate::io_util::FileError { path, source }: crate::io_util::FileError) -> Error {
        Error::Io { path, source }
    }
}

impl Error {
    /// The exit status this error maps to.
    pub fn exit_status(&self) -> ExitStatus {
        match self {
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
            Error::Mechanics(e) => match e {
                crate::mechanics::MechanicsError::InvalidOption { .. } => ExitStatus::BadInput,
                _ => ExitStatus::CaseFailed,
            },
            Error::Io { .. } | Error::MeshDev(_) | Error::Report { .. } => ExitStatus::CaseFailed,
        }
    }
}
