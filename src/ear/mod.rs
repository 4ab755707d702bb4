//! The vocabulary every stage shares about an ear: which side it is, and its three landmarks.
//! The atlas carries them, the registration reads and fits them, the phantom writes them.

mod landmarks;
mod side;

pub use landmarks::{LandmarkName, Landmarks};
pub use side::Side;
