//! Errors of the mechanical checks: a missing boundary set or surface in the atlas, a failed
//! solve (with the FEM's own message), a bad option, or a chart that could not be drawn.

use crate::atlas::BuildError;
use crate::fem::FemError;

/// A mechanical validation or simulation could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum MechanicsError {
    #[error("atlas: the {kind} {name:?} is missing or empty; expected it for the {purpose}")]
    MissingSet {
        kind: &'static str,
        name: String,
        purpose: &'static str,
    },
    #[error("atlas: {what}")]
    BadAtlas { what: String },
    #[error("{stage}: {source}")]
    Solve {
        stage: String,
        #[source]
        source: FemError,
    },
    #[error("the eardrum's convergence: {what}")]
    NotRebuildable { what: String },
    #[error("rebuilding the atlas with a finer eardrum: {0}")]
    Rebuild(#[source] BuildError),
    #[error("{what} = {value} is invalid (expected {expected})")]
    InvalidOption {
        what: &'static str,
        value: f64,
        expected: &'static str,
    },
}

impl MechanicsError {
    /// Wraps a FEM error with the stage that raised it.
    pub fn solve(stage: impl Into<String>) -> impl FnOnce(FemError) -> MechanicsError {
        let stage = stage.into();
        move |source| MechanicsError::Solve { stage, source }
    }
}
