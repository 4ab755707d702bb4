//! Registration of the atlas onto a patient: landmarks, the ear's side, the rigid (Kabsch /
//! Umeyama) alignment, the deformable stage, and the atlas fitted through them.

pub mod articulate;
pub mod atlas_fit;
pub mod auto_landmarks;
pub mod chain_search;
pub mod deform;
pub mod eardrum;
pub mod icp;
pub mod landmarks;
pub mod placement;
pub mod probes;
pub mod refine;
pub mod rigid;
pub mod stapes_turn;
pub mod support;

pub use crate::ear::Side;
pub use landmarks::{LandmarkName, Landmarks};
pub use rigid::{RigidFit, SimilarityTransform, fit_similarity};

/// The settings of the deformable stage's levels (`[articulate]`, `[deform]`, `[refine]`).
#[derive(Debug, Clone, Copy)]
pub struct DeformSettings<'a> {
    pub articulate: &'a articulate::ArticulateConfig,
    pub deform: &'a deform::DeformConfig,
    pub refine: &'a refine::RefineConfig,
    /// How the FEM levels' solves step (`deform::Steps`).
    pub steps: deform::Steps,
}
