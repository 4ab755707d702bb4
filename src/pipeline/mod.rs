//! The pipeline: the case folder, the stages of `run` with their artefacts and timings, the
//! scoring against a manual segmentation, and cohorts (`batch`, each case in a child process, shards, Slurm arrays).

pub mod auto_landmarks;
pub mod batch;
pub mod case;
pub mod case_process;
pub mod cohort;
pub mod cohort_summary;
mod error;
pub mod mechanics;
pub mod run;
pub mod sbatch;
pub mod score;
pub mod stage;

pub use case::Case;
pub use error::Error;
pub use run::{AutoLandmarks, RunOptions, RunSummary, run_case};
pub use stage::Stage;
