//! The case folder, the unit of work of `run` and `batch`:
//!
//! ```text
//! CASE/
//!   dicom/              the CT series (any file names), or
//!   image.nii.gz        the same volume as NIfTI (used when dicom/ is absent)
//!   landmarks.fcsv      or landmarks.mrk.json / landmarks.json / landmarks.csv
//!   segmentation/       optional manual segmentation (per-structure PLY, labels.nii.gz)
//!   truth.json          phantoms only: the ground truth they were made with
//! ```
//!
//! A bare image (a DICOM folder without that layout, a DICOM file, a NIfTI file) is accepted
//! as a case with no landmarks.

use std::path::{Path, PathBuf};

use crate::image::nifti::is_nifti_path;

/// Landmark file names looked for in a case folder, in order of preference.
pub const LANDMARK_FILES: [&str; 4] = [
    "landmarks.fcsv",
    "landmarks.mrk.json",
    "landmarks.json",
    "landmarks.csv",
];

/// Where a case's inputs are.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// The case folder (or the bare image's parent).
    pub root: PathBuf,
    /// A name for logs and reports: the folder (or file) name.
    pub id: String,
    /// The image: a DICOM folder or file, or a NIfTI file.
    pub image: PathBuf,
    /// The landmark file, if the case has one.
    pub landmarks: Option<PathBuf>,
    /// The manual segmentation folder, if the case has one.
    pub segmentation: Option<PathBuf>,
}

/// The path given as a case does not exist.
#[derive(Debug, thiserror::Error)]
#[error("{path}: no such case folder or image")]
pub struct CaseNotFound {
    pub path: PathBuf,
}

impl Case {
    /// Finds the inputs of the case at `path`.
    pub fn open(path: &Path) -> Result<Case, CaseNotFound> {
        if !path.exists() {
            return Err(CaseNotFound {
                path: path.to_path_buf(),
            });
        }
        let id = path
            .file_name()
            .map(|n| {
                n.to_string_lossy()
                    .trim_end_matches(".gz")
                    .trim_end_matches(".nii")
                    .to_string()
            })
            .unwrap_or_else(|| "case".into());
        if path.is_file() {
            return Ok(Case {
                root: path.parent().unwrap_or(Path::new(".")).to_path_buf(),
                id,
                image: path.to_path_buf(),
                landmarks: None,
                segmentation: None,
            });
        }
        let image = ["dicom", "image.nii.gz", "image.nii"]
            .iter()
            .map(|n| path.join(n))
            .find(|p| p.exists() && (p.is_dir() || is_nifti_path(p)))
            .unwrap_or_else(|| path.to_path_buf());
        let landmarks = LANDMARK_FILES
            .iter()
            .map(|n| path.join(n))
            .find(|p| p.is_file());
        let segmentation = Some(path.join("segmentation")).filter(|p| p.is_dir());
        Ok(Case {
            root: path.to_path_buf(),
            id,
            image,
            landmarks,
            segmentation,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_parts_of_a_case_folder() {
        let dir = tempfile::tempdir().unwrap();
        let case = dir.path().join("case07");
        std::fs::create_dir_all(case.join("dicom")).unwrap();
        std::fs::create_dir_all(case.join("segmentation")).unwrap();
        std::fs::write(case.join("landmarks.json"), "{}").unwrap();
        std::fs::write(case.join("landmarks.fcsv"), "").unwrap();
        let c = Case::open(&case).unwrap();
        assert_eq!(c.id, "case07");
        assert_eq!(c.image, case.join("dicom"));
        assert_eq!(c.landmarks, Some(case.join("landmarks.fcsv")));
        assert_eq!(c.segmentation, Some(case.join("segmentation")));
        // a bare NIfTI file is a case without landmarks
        let nii = dir.path().join("scan.nii.gz");
        std::fs::write(&nii, "").unwrap();
        let c = Case::open(&nii).unwrap();
        assert_eq!((c.id.as_str(), c.landmarks), ("scan", None));
        assert!(Case::open(&dir.path().join("absent")).is_err());
    }
}
