//! The error of the pipeline and the commands: every layer's error folds into it, converted
//! where the layer is called. Which exit code each gets is the command line's choice
//! (`cli::exit`).

use std::path::PathBuf;

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
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
    #[error(transparent)]
    Deform(#[from] crate::register::deform::DeformError),
    #[error(transparent)]
    Propose(#[from] crate::register::auto_landmarks::ProposeError),
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
