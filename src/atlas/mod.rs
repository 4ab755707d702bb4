//! The atlas anatomy: a parametric right middle ear (ossicles, joints, ligaments, tendons,
//! eardrum) read from `assets/anatomy.toml`, evaluated as a labelled implicit domain for the
//! mesher, with the landmarks and boundary-condition sites, and the Table 1 materials.
//!
//! The frame, the label numbering and the literature sources are documented in
//! `docs/anatomy.md`.

pub mod anatomy;
pub mod eardrum;
pub mod materials;
pub mod region;
pub mod sdf;
pub mod spec;
pub mod volume;

pub use crate::ear::Landmarks;
pub use anatomy::{Anatomy, DEFAULT_TOML};
pub use eardrum::Eardrum;
pub use region::{Bone, MembraneRegion, Region};
pub use spec::{AnatomyError, AnatomySpec, Side};
