//! The pipeline: the case folder, and (as stages land) their sequencing, artefacts and timings.

pub mod case;

pub use case::Case;
