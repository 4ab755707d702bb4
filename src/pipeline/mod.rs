//! The pipeline: the case folder, the stages of `run` with their artefacts and timings, and
//! the scoring against a manual segmentation.

pub mod case;
pub mod run;
pub mod score;
pub mod stage;

pub use case::Case;
pub use run::{RunOptions, RunSummary, run_case};
pub use stage::Stage;
