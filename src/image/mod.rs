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
/// image came from and its geometry. `run --from` compares it with the image read again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageRecord {
    /// The input path (written lossily when it is not UTF-8).
    pub image: String,
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
    /// The record of `loaded`, read from `source`.
    pub fn of(loaded: &LoadedImage, source: &Path) -> ImageRecord {
        let v = &loaded.volume;
        ImageRecord {
            image: source.display().to_string(),
            format: loaded.info.format.clone(),
            dims: v.dims,
            spacing: v.spacing,
            origin: [v.origin.x, v.origin.y, v.origin.z],
            direction: v.direction_row_major(),
            laterality: loaded.info.laterality.clone(),
            series_uid_sha256: loaded.info.series_uid_sha256.clone(),
        }
    }
}

/// Reads `path`: a NIfTI file (`.nii`, `.nii.gz`), a DICOM file (single- or multi-frame), or a
/// folder searched recursively for a DICOM series (`series` chooses among several). Reports
/// nothing; see [`load_reporting`].
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
        return nifti::read_nifti(path, cfg);
    }
    dicom::read_dicom(path, series, cfg, progress)
}
