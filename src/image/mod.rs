//! Images: the [`Volume`] type and the readers that make one from a DICOM series or a NIfTI
//! file, in LPS millimetres and Hounsfield units.

pub mod dicom;
mod error;
pub mod filter;
pub mod nifti;
pub mod sample;
mod volume;

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::progress::Reporter;

pub use error::ImageError;
pub use sample::Sampler;
pub use volume::Volume;

/// Knobs of the ingest stage (reading DICOM series and NIfTI volumes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IngestConfig {
    /// Largest single input file accepted, and the most a deflated DICOM data set may inflate
    /// to, in MiB (guards against malformed length fields).
    pub max_file_mib: f64,
    /// Largest image volume held in memory, in MiB of 32-bit voxels: checked from the header's
    /// sizes before any voxel is read.
    pub max_volume_mib: f64,
    /// Largest relative deviation of one slice gap from the median gap before the series is
    /// called non-uniform (a missing or extra slice), as a fraction of the median gap.
    pub slice_gap_tolerance: f64,
    /// Largest difference between two slices' ImageOrientationPatient direction cosines before
    /// the series is called mixed-orientation (unitless).
    pub orientation_tolerance: f64,
}

/// What ingest learned about the input besides the voxels (never a patient field or raw UID).
#[derive(Debug, Clone, Serialize)]
pub struct ImageInfo {
    /// "dicom", "nifti1" or "nifti2".
    pub format: String,
    pub modality: String,
    /// Transfer syntax UID(s) of the series (comma-separated if mixed).
    pub transfer_syntax: String,
    pub transfer_syntax_name: String,
    /// Number of slices (frames) stacked along k.
    pub slices: usize,
    /// Number of files the volume was read from.
    pub files: usize,
    /// SHA-256 of the SeriesInstanceUID (DICOM only).
    pub series_uid_sha256: Option<String>,
    /// Laterality as written in the DICOM (R or L), if any.
    pub laterality: Option<String>,
    /// Assumptions made where the data did not say.
    pub warnings: Vec<String>,
    /// Files skipped while scanning (non-image objects, non-DICOM files).
    pub notes: Vec<String>,
}

/// Refuses a volume of `dims` voxels whose 32-bit voxels would take more than
/// `ingest.max_volume_mib`: checked from the header's sizes before anything is allocated.
fn check_volume_budget(path: &Path, dims: [u64; 3], cfg: &IngestConfig) -> Result<(), ImageError> {
    let voxels = dims.iter().fold(1u64, |n, d| n.saturating_mul(*d));
    let size_mib = voxels.saturating_mul(std::mem::size_of::<f32>() as u64) as f64 / 1048576.0;
    if size_mib > cfg.max_volume_mib {
        return Err(ImageError::VolumeTooLarge {
            path: path.to_path_buf(),
            dims: format!("{dims:?}"),
            size_mib,
            max_mib: cfg.max_volume_mib,
        });
    }
    Ok(())
}

/// A volume together with what ingest learned about its source.
#[derive(Debug, Clone)]
pub struct LoadedImage {
    pub volume: Volume,
    pub info: ImageInfo,
}

/// The ingest stage's record (`OUT/stages/ingest.json`, `metrics.json`'s `image`): where the
/// image came from, what its files hold and its geometry. `run --from` compares it with the
/// image read again ([`ImageRecord::differences`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageRecord {
    /// The input path (written lossily when it is not UTF-8).
    pub image: String,
    /// One SHA-256 over the image's files, each by its path inside the image folder (or the
    /// file's name): the same for a moved or copied image, another for any changed, added,
    /// removed or renamed file. Empty in a record written before it was kept (such a run is
    /// resumed from ingest only).
    #[serde(default)]
    pub files_sha256: String,
    pub format: String,
    pub dims: [usize; 3],
    pub spacing: [f64; 3],
    pub origin: [f64; 3],
    /// The direction cosines, row-major.
    pub direction: [f64; 9],
    pub laterality: Option<String>,
    pub series_uid_sha256: Option<String>,
}

impl ImageRecord {
    /// The record of `loaded`, read from `source`, whose files have the digest `files_sha256`.
    pub fn of(loaded: &LoadedImage, source: &Path, files_sha256: String) -> ImageRecord {
        let v = &loaded.volume;
        ImageRecord {
            image: source.display().to_string(),
            files_sha256,
            format: loaded.info.format.clone(),
            dims: v.dims,
            spacing: v.spacing,
            origin: [v.origin.x, v.origin.y, v.origin.z],
            direction: v.direction_row_major(),
            laterality: loaded.info.laterality.clone(),
            series_uid_sha256: loaded.info.series_uid_sha256.clone(),
        }
    }

    /// The fields in which `other` records another image than this one: all but the path,
    /// so that a case read from another place (moved, copied, named relatively or not) is
    /// the same image.
    pub fn differences(&self, other: &ImageRecord) -> Vec<&'static str> {
        let fields = [
            ("files_sha256", self.files_sha256 == other.files_sha256),
            ("format", self.format == other.format),
            ("dims", self.dims == other.dims),
            ("spacing", self.spacing == other.spacing),
            ("origin", self.origin == other.origin),
            ("direction", self.direction == other.direction),
            ("laterality", self.laterality == other.laterality),
            (
                "series_uid_sha256",
                self.series_uid_sha256 == other.series_uid_sha256,
            ),
        ];
        fields
            .into_iter()
            .filter(|(_, same)| !same)
            .map(|(name, _)| name)
            .collect()
    }
}

/// Reads `path`: a NIfTI file (`.nii`, `.nii.gz`), a DICOM file (single- or multi-frame), or a
/// folder searched recursively for a DICOM series (`series` chooses among several; given with
/// a NIfTI file, it is refused). Reports nothing; see [`load_reporting`].
pub fn load(
    path: &Path,
    series: Option<&str>,
    cfg: &IngestConfig,
) -> Result<LoadedImage, ImageError> {
    load_reporting(path, series, cfg, &crate::progress::Silent)
}

/// [`load`], reporting the DICOM scan and decode and the files skipped to `progress`.
pub fn load_reporting(
    path: &Path,
    series: Option<&str>,
    cfg: &IngestConfig,
    progress: &dyn Reporter,
) -> Result<LoadedImage, ImageError> {
    if !path.exists() {
        return Err(ImageError::NotFound {
            path: path.to_path_buf(),
        });
    }
    if path.is_file() && nifti::is_nifti_path(path) {
        if let Some(wanted) = series {
            return Err(ImageError::SeriesOfNifti {
                path: path.to_path_buf(),
                wanted: wanted.to_string(),
            });
        }
        return nifti::read_nifti(path, cfg);
    }
    dicom::read_dicom(path, series, cfg, progress)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ingest_config() -> IngestConfig {
        IngestConfig {
            max_file_mib: 64.0,
            max_volume_mib: 64.0,
            slice_gap_tolerance: 0.2,
            orientation_tolerance: 1e-3,
        }
    }

    /// A series asked of a NIfTI file is refused before the file is read, not ignored.
    #[test]
    fn a_series_asked_of_a_nifti_file_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scan.nii.gz");
        std::fs::write(&path, b"not read").unwrap();
        let e = load(&path, Some("3f2a9c01"), &ingest_config()).unwrap_err();
        assert!(
            matches!(&e, ImageError::SeriesOfNifti { wanted, .. } if wanted == "3f2a9c01"),
            "{e}"
        );
        // without it the file is read (and found not to be a NIfTI image)
        let e = load(&path, None, &ingest_config()).unwrap_err();
        assert!(!matches!(e, ImageError::SeriesOfNifti { .. }), "{e}");
    }

    /// Every recorded field but the path tells two images apart, by name.
    #[test]
    fn a_record_differs_in_each_field_but_the_path() {
        let a = ImageRecord {
            image: "case/dicom".into(),
            files_sha256: "ab".into(),
            format: "DICOM".into(),
            dims: [4, 5, 6],
            spacing: [0.2; 3],
            origin: [1.0, 2.0, 3.0],
            direction: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            laterality: Some("R".into()),
            series_uid_sha256: Some("cd".into()),
        };
        let moved = ImageRecord {
            image: "elsewhere/case/dicom".into(),
            ..a.clone()
        };
        assert!(a.differences(&moved).is_empty());
        let changed: [(&str, ImageRecord); 8] = [
            (
                "files_sha256",
                ImageRecord {
                    files_sha256: "ac".into(),
                    ..a.clone()
                },
            ),
            (
                "format",
                ImageRecord {
                    format: "NIfTI".into(),
                    ..a.clone()
                },
            ),
            (
                "dims",
                ImageRecord {
                    dims: [4, 5, 7],
                    ..a.clone()
                },
            ),
            (
                "spacing",
                ImageRecord {
                    spacing: [0.2, 0.2, 0.25],
                    ..a.clone()
                },
            ),
            (
                "origin",
                ImageRecord {
                    origin: [1.0, 2.0, 3.5],
                    ..a.clone()
                },
            ),
            (
                "direction",
                ImageRecord {
                    direction: [-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                    ..a.clone()
                },
            ),
            (
                "laterality",
                ImageRecord {
                    laterality: None,
                    ..a.clone()
                },
            ),
            (
                "series_uid_sha256",
                ImageRecord {
                    series_uid_sha256: None,
                    ..a.clone()
                },
            ),
        ];
        for (field, b) in &changed {
            assert_eq!(a.differences(b), [*field]);
        }
        // and no recorded field is left out of the comparison
        let Ok(serde_json::Value::Object(fields)) = serde_json::to_value(&a) else {
            panic!("a record is a JSON object");
        };
        assert_eq!(fields.len(), changed.len() + 1);
    }
}
