//! Synthetic CBCT cases with known truth: the atlas anatomy varied per patient (ossicle
//! motions, shape detail, scale, smooth deformation, pose, side), or a real chain given as
//! surfaces (`chain_anatomy`, placed by `mesh_chain`), imaged by a cone-beam CT model, and
//! written as case folders with their ground truth. See docs/phantom.md.

pub mod case_writer;
pub mod chain_anatomy;
pub mod chain_articulation;
pub mod chain_landmarks;
pub mod chain_variation;
pub mod draws;
pub mod drum;
pub mod generator;
pub mod imaging;
pub mod mesh_chain;
pub mod patient;
pub mod patient_field;
pub mod scene;
pub mod truth;
pub mod variability;
pub mod warp;

pub use case_writer::write_case;
pub use chain_anatomy::{ChainAnatomy, ChainError};
pub use generator::{
    ChainPhantoms, ChainShape, PhantomCase, PhantomError, PhantomOptions, SPACING_RANGE_MM,
    generate_case, generate_chain_case,
};
