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

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::export::digest::{combined_sha256, file_digests};
use crate::image::nifti::is_nifti_path;

/// The names a case folder's image goes by, in the order they are looked for.
pub const IMAGE_NAMES: [&str; 3] = ["dicom", "image.nii.gz", "image.nii"];

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
    /// The DICOM series to read where the image folder holds several: its SeriesInstanceUID,
    /// or a prefix of at least 6 hex digits of its SHA-256, as `inspect` lists them (`run
    /// --series`, a cohort manifest's `series`).
    pub series: Option<String>,
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
                series: None,
            });
        }
        let image = IMAGE_NAMES
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
            series: None,
        })
    }
}

/// The SHA-256 of each file of a case's image, by its path inside a DICOM folder (or the
/// file's name): read once per run, for the ingest record and the package's inputs digest.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageDigests(BTreeMap<String, String>);

impl ImageDigests {
    /// One SHA-256 over the image's files (`ImageRecord::files_sha256`).
    pub fn sha256(&self) -> String {
        combined_sha256(self.0.iter().map(|(n, d)| (n.as_str(), d.as_str())))
    }
}

impl Case {
    /// Reads the image's files and hashes each of them.
    pub fn image_digests(&self) -> Result<ImageDigests, crate::Error> {
        Ok(ImageDigests(file_digests(&self.image)?))
    }

    /// One SHA-256 over the contents of the case's inputs: the image (its `image` digests),
    /// the landmark file used (`landmarks_override`, else the case's) and the segmentation
    /// folder. Paths outside the case do not enter it, so a moved or copied case keeps its
    /// digest; any changed, added, removed or renamed input file changes it. Reads the
    /// landmark and segmentation files once.
    pub fn inputs_sha256(
        &self,
        image: &ImageDigests,
        landmarks_override: Option<&Path>,
    ) -> Result<String, crate::Error> {
        let mut entries: Vec<(String, String)> = image
            .0
            .iter()
            .map(|(name, digest)| (format!("image/{name}"), digest.clone()))
            .collect();
        let landmarks = landmarks_override.or(self.landmarks.as_deref());
        let roles = [
            ("landmarks", landmarks),
            ("segmentation", self.segmentation.as_deref()),
        ];
        for (role, path) in roles {
            let Some(path) = path else { continue };
            for (name, digest) in file_digests(path)? {
                entries.push((format!("{role}/{name}"), digest));
            }
        }
        Ok(combined_sha256(
            entries.iter().map(|(n, d)| (n.as_str(), d.as_str())),
        ))
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

    fn digest(case: &Case, landmarks: Option<&Path>) -> String {
        let image = case.image_digests().unwrap();
        case.inputs_sha256(&image, landmarks).unwrap()
    }

    #[test]
    fn inputs_digest_follows_contents_and_the_landmark_file_used() {
        let dir = tempfile::tempdir().unwrap();
        let case = dir.path().join("c");
        std::fs::create_dir_all(case.join("dicom/sub")).unwrap();
        std::fs::write(case.join("dicom/sub/1.dcm"), b"slice one").unwrap();
        std::fs::write(case.join("landmarks.fcsv"), b"points").unwrap();
        let c = Case::open(&case).unwrap();
        let d0 = digest(&c, None);
        // a copy elsewhere has the same digest
        let copy = dir.path().join("copy");
        std::fs::create_dir_all(copy.join("dicom/sub")).unwrap();
        std::fs::write(copy.join("dicom/sub/1.dcm"), b"slice one").unwrap();
        std::fs::write(copy.join("landmarks.fcsv"), b"points").unwrap();
        assert_eq!(digest(&Case::open(&copy).unwrap(), None), d0);
        // another landmark file with the same content and name: same; other content: not
        let other = dir.path().join("landmarks.fcsv");
        std::fs::write(&other, b"points").unwrap();
        assert_eq!(digest(&c, Some(&other)), d0);
        std::fs::write(&other, b"moved points").unwrap();
        assert_ne!(digest(&c, Some(&other)), d0);
        // one changed image byte, or a segmentation added, changes it
        std::fs::write(case.join("dicom/sub/1.dcm"), b"slice 0ne").unwrap();
        let d1 = digest(&c, None);
        assert_ne!(d1, d0);
        std::fs::create_dir_all(case.join("segmentation")).unwrap();
        std::fs::write(case.join("segmentation/incus.ply"), b"ply").unwrap();
        assert_ne!(digest(&Case::open(&case).unwrap(), None), d1);
    }
}
