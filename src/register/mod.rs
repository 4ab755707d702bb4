//! Registration of the atlas onto a patient: landmarks, the ear's side, the rigid (Kabsch /
//! Umeyama) alignment, and (later) the deformable stage.

pub mod deform;
pub mod landmarks;
pub mod rigid;

pub use crate::ear::Side;
pub use landmarks::{LandmarkName, Landmarks};
pub use rigid::{RigidFit, SimilarityTransform, fit_similarity};
