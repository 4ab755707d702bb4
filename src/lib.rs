//! otoatlas: registers a validated mechanical atlas of the middle ear onto a patient's
//! cone-beam CT and exports a ready-to-simulate finite-element package.
//!
//! World space everywhere is DICOM patient space (LPS) in millimetres; see the README
//! ("Conventions") for the conventions each module keeps.

pub mod atlas;
pub mod cli;
pub mod config;
pub mod ear;
pub mod export;
pub mod fem;
pub mod image;
pub mod io_util;
pub mod mechanics;
pub mod mesh;
pub mod meshdev;
pub mod phantom;
pub mod pipeline;
pub mod progress;
pub mod register;
pub mod report;

pub use pipeline::Error;
