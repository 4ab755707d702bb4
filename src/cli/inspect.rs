//! `otoatlas inspect`: read a CBCT (DICOM series or NIfTI) and describe its geometry.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use super::Report;
use super::series_arg::SeriesArg;
use crate::config::Config;
use crate::progress::Reporter;
use crate::{Error, image};

/// Read a CBCT volume (DICOM folder, multi-frame DICOM file, or NIfTI) and describe it.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  otoatlas inspect sample_cases/case-001/dicom
  otoatlas inspect scan.nii.gz --json
  otoatlas inspect /media/export --series 3f9a1c   # pick a series by its hash prefix")]
pub struct InspectArgs {
    /// A folder of DICOM files (searched recursively), a DICOM file, or a NIfTI file (.nii,
    /// .nii.gz, or the .hdr of a .hdr/.img pair).
    pub path: PathBuf,
    #[command(flatten)]
    pub series: SeriesArg,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(
    args: &InspectArgs,
    config: Option<&Path>,
    progress: &dyn Reporter,
) -> Result<Report, Error> {
    let config = Config::load(config)?;
    let loaded = image::load_reporting(
        &args.path,
        args.series.uid.as_deref(),
        &config.ingest,
        progress,
    )?;
    let v = &loaded.volume;
    let info = &loaded.info;
    let (hu_min, hu_max) = v.value_range().unwrap_or((f32::NAN, f32::NAN));
    let json = json!({
        "format": info.format,
        "dims": v.dims,
        "spacing": v.spacing,
        "origin": [v.origin.x, v.origin.y, v.origin.z],
        "direction": v.direction_row_major(),
        "hu_min": hu_min,
        "hu_max": hu_max,
        "modality": info.modality,
        "transfer_syntax": info.transfer_syntax,
        "transfer_syntax_name": info.transfer_syntax_name,
        "slices": info.slices,
        "files": info.files,
        "series_uid_sha256": info.series_uid_sha256,
        "laterality": info.laterality,
        "warnings": info.warnings,
        "skipped": info.notes,
    });
    let mut text = String::new();
    let _ = writeln!(text, "format          {}", info.format);
    if !info.modality.is_empty() {
        let _ = writeln!(text, "modality        {}", info.modality);
        let _ = writeln!(
            text,
            "transfer syntax {} ({})",
            info.transfer_syntax, info.transfer_syntax_name
        );
    }
    let _ = writeln!(
        text,
        "dims            {} x {} x {}",
        v.dims[0], v.dims[1], v.dims[2]
    );
    let _ = writeln!(
        text,
        "spacing (mm)    {:.4} x {:.4} x {:.4}",
        v.spacing[0], v.spacing[1], v.spacing[2]
    );
    let _ = writeln!(
        text,
        "origin (LPS mm) {:.3}, {:.3}, {:.3}",
        v.origin.x, v.origin.y, v.origin.z
    );
    for (r, label) in ["direction (LPS) ", "                ", "                "]
        .iter()
        .enumerate()
    {
        let _ = writeln!(
            text,
            "{label}{:>8.5} {:>8.5} {:>8.5}",
            v.direction[(r, 0)],
            v.direction[(r, 1)],
            v.direction[(r, 2)]
        );
    }
    let _ = writeln!(text, "HU range        {hu_min} .. {hu_max}");
    let _ = writeln!(
        text,
        "slices          {} (from {} files)",
        info.slices, info.files
    );
    if let Some(h) = &info.series_uid_sha256 {
        let _ = writeln!(text, "series (sha256) {h}");
    }
    if let Some(l) = &info.laterality {
        let _ = writeln!(text, "laterality      {l}");
    }
    for w in &info.warnings {
        let _ = writeln!(text, "warning: {w}");
    }
    Ok(Report { text, json })
}
