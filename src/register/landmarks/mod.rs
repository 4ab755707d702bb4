//! The three landmarks of the method (umbo, incudomalleolar joint, incudostapedial joint) in
//! LPS millimetres: names and their usual aliases, file formats, plausibility checks, and the
//! interactive prompt.

mod checks;
mod formats;
mod prompt;

use std::path::PathBuf;

pub use checks::{CheckConfig, check_landmarks};
pub use formats::{read_landmarks, write_fcsv, write_json, write_mrk_json};

pub use prompt::{PromptInput, prompt_landmarks};

use crate::ear::Side;
pub use crate::ear::{LandmarkName, Landmarks};

/// Landmarks read from a file, with what the file said besides the points.
#[derive(Debug, Clone, PartialEq)]
pub struct LandmarkFile {
    pub landmarks: Landmarks,
    /// The side of the ear, if the file says it.
    pub side: Option<Side>,
    /// Notes for the user (e.g. a coordinate system assumed).
    pub notes: Vec<String>,
}

/// Errors reading, checking or prompting for landmarks.
#[derive(Debug, thiserror::Error)]
pub enum LandmarkError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: unknown landmark file type; expected .fcsv, .mrk.json, .json or .csv")]
    UnknownFormat { path: PathBuf },
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error(
        "{path}: landmark {name} is missing; expected umbo, incudomalleolar (IMJ) and incudostapedial (ISJ)"
    )]
    Missing { path: PathBuf, name: &'static str },
    #[error("{path}: landmark {name} is given twice (lines {first} and {second})")]
    Duplicate {
        path: PathBuf,
        name: &'static str,
        first: usize,
        second: usize,
    },
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
        "landmarks {a} and {b} look swapped: with them exchanged the distances match the atlas ({swapped_error:.0} % off instead of {error:.0} %); distances (mm) patient {patient:?}, atlas {atlas:?} (umbo-IMJ, umbo-ISJ, IMJ-ISJ)"
    )]
    Swapped {
        a: &'static str,
        b: &'static str,
        error: f64,
        swapped_error: f64,
        patient: [f64; 3],
        atlas: [f64; 3],
    },
    #[error(
        "landmark distances do not look like a middle ear: {pair} is {patient_mm:.2} mm, the atlas has {atlas_mm:.2} mm (ratio {ratio:.2}, expected {min_ratio:.2} to {max_ratio:.2})"
    )]
    Implausible {
        pair: &'static str,
        patient_mm: f64,
        atlas_mm: f64,
        ratio: f64,
        min_ratio: f64,
        max_ratio: f64,
    },
    #[error(
        "no landmarks: give --landmarks FILE, put landmarks.fcsv/.mrk.json/.json/.csv in the case folder, or run `otoatlas landmarks CASE` on a terminal"
    )]
    NoneGiven,
    #[error("the landmark prompt ended before all three landmarks were given")]
    PromptEnded,
}
