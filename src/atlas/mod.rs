//! The mechanical atlas: a parametric right middle ear (ossicles, joints, ligaments, tendons,
//! eardrum) read from `assets/anatomy.toml`, evaluated as a labelled implicit domain for the
//! mesher, with the landmarks and boundary-condition sites, and the Table 1 materials; the
//! assembled FEM atlas built from it, its file format and the embedded default.
//!
//! The frame, the label numbering and the literature sources are documented in
//! `docs/anatomy.md`.

pub mod anatomy;
mod attachment;
pub mod build;
pub mod eardrum;
pub mod export;
pub mod format;
pub mod import;
pub mod joint_layer;
pub mod mapping;
pub mod mass;
pub mod materials;
pub mod membrane;
pub mod model;
pub mod region;
pub mod sdf;
pub mod spec;
pub mod summary;
pub mod surfaces;
pub mod volume;

pub use crate::ear::Landmarks;
pub use anatomy::{Anatomy, DEFAULT_TOML};
pub use build::{BuildError, build_atlas};
pub use eardrum::Eardrum;
pub use format::{AtlasError, default_atlas, load_atlas, read_atlas, write_atlas};
pub use model::{Atlas, LabelledTriangles, Part};
pub use region::{Bone, MembraneRegion, Region};
pub use spec::{AnatomyError, AnatomySpec, Side};
