//! The vocabulary every stage shares about an ear: which side it is, its three landmarks, the
//! files they are exchanged in, which structure a surface file's name names, and how large a
//! chain is in mm. The atlas carries them, the registration reads and fits
//! them, the phantom and the package write them.

mod chain_span;
mod files;
mod landmarks;
mod side;
mod structure_names;

pub use chain_span::{CHAIN_SPAN_MM, is_chain_span, span_mm};
pub use files::{
    LandmarkFile, LandmarkFileError, read_landmarks, write_fcsv, write_fcsv_described, write_json,
    write_json_with, write_mrk_json, write_mrk_json_described,
};
pub use landmarks::{LandmarkName, Landmarks};
pub use side::Side;
pub use structure_names::{file_stem, structure_in_words, structure_names};
