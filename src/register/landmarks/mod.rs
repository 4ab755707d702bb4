//! Landmark checks and input for the registration: plausibility checks of the three landmarks
//! (with the image's word on a suspected label swap) and the interactive prompt. Their names
//! and file formats are the ear's vocabulary ([`crate::ear`]).

mod checks;
mod image_check;
mod prompt;

use std::path::PathBuf;

pub use checks::{
    Band, CheckConfig, LandmarkWarning, REGISTRATION_AGREEMENT_MM, check_against_registration,
    check_edge_support, check_landmarks, check_landmarks_on_image,
};
pub use image_check::{BorderFit, ImageCheck, SwapEvidence};

pub use prompt::{PromptInput, prompt_landmarks};

use crate::ear::LandmarkFileError;
pub use crate::ear::{LandmarkName, Landmarks};

/// Errors checking or prompting for landmarks (or reading their file).
#[derive(Debug, thiserror::Error)]
pub enum LandmarkError {
    #[error(transparent)]
    File(#[from] LandmarkFileError),
    #[error(
        "landmark {name} at ({x:.2}, {y:.2}, {z:.2}) mm LPS lies outside the image (voxel index {i:.1}, {j:.1}, {k:.1}; dims {dims:?})"
    )]
    OutsideImage {
        name: &'static str,
        x: f64,
        y: f64,
        z: f64,
        i: f64,
        j: f64,
        k: f64,
        dims: [usize; 3],
    },
    #[error(
        "the three landmarks are (nearly) collinear: the triangle's smallest height is {height_mm:.3} mm (at least {min_mm:.3} mm expected); a rigid fit would be undetermined"
    )]
    Collinear { height_mm: f64, min_mm: f64 },
    #[error(
        "the landmark triangle is {scale:.2} times the atlas's (perimeter {perimeter_mm:.2} mm, the atlas's {atlas_perimeter_mm:.2} mm; expected {min:.2} to {max:.2} times): check the units (mm) and the coordinate system of the landmark file"
    )]
    Scale {
        scale: f64,
        perimeter_mm: f64,
        atlas_perimeter_mm: f64,
        min: f64,
        max: f64,
    },
    #[error(
        "landmark distances do not look like a middle ear: {pair} is {patient_mm:.2} mm, outside what a middle ear can have ({min_mm:.2} to {max_mm:.2} mm, `landmarks.*_possible_mm` in the configuration){atlas}{hint}"
    )]
    OutsideBand {
        pair: &'static str,
        patient_mm: f64,
        min_mm: f64,
        max_mm: f64,
        /// "; the atlas has N mm", or empty.
        atlas: String,
        /// A swap the distances suggest, or empty.
        hint: String,
    },
    #[error(
        "landmarks {a} and {b} are swapped: exchanged, every distance is in its typical band (umbo-IMJ / umbo-ISJ / IMJ-ISJ {swapped_mm:.2?} mm instead of {given_mm:.2?} mm), and the atlas placed by the exchanged labels lies on the image's bone borders (a border found from {swapped_found:.0} % of its surface triangles at a mean |offset| of {swapped_offset_mm:.2} mm, against {given_found:.0} % and {given_offset_mm:.2} mm as given); exchange {a} and {b} in the landmark file"
    )]
    Swapped {
        a: &'static str,
        b: &'static str,
        given_mm: [f64; 3],
        swapped_mm: [f64; 3],
        /// Percent of the probed triangles.
        swapped_found: f64,
        swapped_offset_mm: f64,
        given_found: f64,
        given_offset_mm: f64,
    },
    #[error("{path}: {source}")]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<LandmarkError>,
    },
    #[error("the landmarks proposed from the image: {0}")]
    Proposed(#[source] Box<LandmarkError>),
    #[error(
        "no landmarks: give --landmarks FILE, put landmarks.fcsv/.mrk.json/.json/.csv in the case folder, or run `otoatlas landmarks CASE` on a terminal"
    )]
    NoneGiven,
    #[error("the landmark prompt ended before all three landmarks were given")]
    PromptEnded,
}
