//! Reading a DICOM CT series (a folder searched recursively, or one multi-frame file) into a
//! [`Volume`] in LPS millimetres and Hounsfield units.

mod geometry;
mod lengths;
pub mod patient;
mod pixels;
mod scan;
mod tags;
pub mod write;

use std::collections::BTreeMap;
use std::path::Path;

use crate::image::IngestConfig;
use crate::image::{ImageError, ImageInfo, LoadedImage, Volume};
use crate::io_util::sha256_hex;
use crate::progress::Reporter;
pub use scan::{ImageFile, Rescale};

/// True if any file under `dir` (recursively) carries the DICOM marker: what `run` accepts as
/// a case folder without a `dicom/` inside.
pub fn holds_dicom(dir: &Path) -> bool {
    scan::list_files(dir)
        .map(|files| {
            files
                .iter()
                .any(|f| scan::has_dicom_marker(f).unwrap_or(false))
        })
        .unwrap_or(false)
}

/// Human name of a transfer syntax UID, from the registry dicom-rs was built with.
pub fn transfer_syntax_name(uid: &str) -> String {
    use dicom_encoding::TransferSyntaxIndex;
    dicom_transfer_syntax_registry::TransferSyntaxRegistry
        .get(uid)
        .map(|ts| ts.name().to_string())
        .unwrap_or_else(|| "unknown".into())
}

/// Whether `wanted` (a SeriesInstanceUID, or a prefix of at least 6 hex digits of the SHA-256
/// of one, as [`read_dicom`]'s listing gives them) names the series whose UID's SHA-256 is
/// `uid_sha256` (`ImageInfo::series_uid_sha256`).
pub fn series_selects(wanted: &str, uid_sha256: &str) -> bool {
    let wanted_lc = wanted.to_ascii_lowercase();
    sha256_hex(wanted.as_bytes()) == uid_sha256
        || (wanted_lc.len() >= 6 && uid_sha256.starts_with(&wanted_lc))
}

/// Reads the image series at `path` (a folder or a single file). With several image series in
/// a folder, `series` picks one by SeriesInstanceUID or by a prefix of its SHA-256.
pub fn read_dicom(
    path: &Path,
    series: Option<&str>,
    cfg: &IngestConfig,
    progress: &dyn Reporter,
) -> Result<LoadedImage, ImageError> {
    let files = if path.is_dir() {
        scan::list_files(path)?
    } else {
        if !scan::has_dicom_marker(path)? {
            return Err(ImageError::NotDicom {
                path: path.to_path_buf(),
            });
        }
        vec![path.to_path_buf()]
    };
    let max_bytes = (cfg.max_file_mib * 1048576.0) as u64;
    let header_bar = progress.task("headers", files.len() as u64);
    let scanned = scan::scan_files(&files, max_bytes)?;
    header_bar.inc(files.len() as u64);
    let mut notes = Vec::new();
    let mut by_series: BTreeMap<String, Vec<ImageFile>> = BTreeMap::new();
    for s in scanned {
        match s {
            scan::Scanned::Image(f) => by_series.entry(f.series_uid.clone()).or_default().push(*f),
            scan::Scanned::Skipped { path, reason } => {
                let note = format!("skipped {}: {reason}", path.display());
                progress.log(&note);
                notes.push(note);
            }
        }
    }
    header_bar.finish(&format!(
        "{} files, {} image series",
        files.len(),
        by_series.len()
    ));
    let skipped = notes.len();
    let listing = || series_listing(&by_series);
    let (uid, files) = match (by_series.len(), series) {
        (0, _) => {
            return Err(ImageError::NoImageSeries {
                path: path.to_path_buf(),
                skipped,
            });
        }
        (_, Some(wanted)) => {
            let hit = by_series
                .keys()
                .find(|uid| series_selects(wanted, &sha256_hex(uid.as_bytes())));
            match hit.cloned() {
                Some(uid) => {
                    let files = by_series.remove(&uid).unwrap_or_default();
                    (uid, files)
                }
                None => {
                    return Err(ImageError::SeriesNotFound {
                        path: path.to_path_buf(),
                        wanted: wanted.to_string(),
                        listing: listing(),
                    });
                }
            }
        }
        (1, None) => by_series.pop_first().unwrap_or_default(),
        (count, None) => {
            return Err(ImageError::SeveralSeries {
                path: path.to_path_buf(),
                count,
                listing: listing(),
            });
        }
    };
    let geometry = geometry::series_geometry(&files, cfg)?;
    super::check_volume_budget(path, geometry.dims.map(|d| d as u64), cfg)?;
    let n_planes = geometry.dims[2] as u64;
    let mut data = vec![0f32; geometry.dims.iter().product()];
    let bar = progress.task("decode", n_planes);
    pixels::decode_series(&files, &geometry.order, &mut data, &|| bar.inc(1))?;
    bar.finish(&format!(
        "{} x {} x {} voxels",
        geometry.dims[0], geometry.dims[1], geometry.dims[2]
    ));
    for w in &geometry.warnings {
        progress.log(&format!("warning: {w}"));
    }
    let first = &files[0];
    let mut syntaxes: Vec<&str> = files.iter().map(|f| f.transfer_syntax.as_str()).collect();
    syntaxes.sort_unstable();
    syntaxes.dedup();
    let laterality = files.iter().find_map(|f| f.laterality.clone());
    let volume = Volume {
        dims: geometry.dims,
        spacing: geometry.spacing,
        origin: geometry.origin,
        direction: geometry.direction,
        data,
    };
    Ok(LoadedImage {
        volume,
        info: ImageInfo {
            format: "dicom".into(),
            modality: first.modality.clone(),
            transfer_syntax: syntaxes.join(", "),
            transfer_syntax_name: syntaxes
                .iter()
                .map(|s| transfer_syntax_name(s))
                .collect::<Vec<_>>()
                .join(", "),
            slices: geometry.order.len(),
            files: files.len(),
            series_uid_sha256: Some(sha256_hex(uid.as_bytes())),
            laterality,
            warnings: geometry.warnings,
            notes,
        },
    })
}

/// One line per series: hash of its UID, SeriesNumber, modality and size; no free text
/// (descriptions can hold patient information).
fn series_listing(by_series: &BTreeMap<String, Vec<ImageFile>>) -> String {
    by_series
        .iter()
        .map(|(uid, files)| {
            let frames: usize = files.iter().map(|f| f.frames.len()).sum();
            let f = &files[0];
            let number = f
                .series_number
                .map_or_else(|| "-".to_string(), |n| n.to_string());
            format!(
                "  {}  series number {number:<5} {:<3} {:>4} slices  {}x{}x{}",
                &sha256_hex(uid.as_bytes())[..16],
                f.modality,
                frames,
                f.columns,
                f.rows,
                frames,
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_series_is_named_by_its_uid_or_a_prefix_of_its_hash() {
        let uid = "1.2.826.0.1.3680043.10.543.7";
        let hash = sha256_hex(uid.as_bytes());
        assert!(series_selects(uid, &hash));
        assert!(series_selects(&hash, &hash));
        assert!(series_selects(&hash[..6].to_ascii_uppercase(), &hash));
        assert!(!series_selects(&hash[..5], &hash), "under 6 hex digits");
        assert!(!series_selects("1.2.826.0.1.3680043.10.543.8", &hash));
        assert!(!series_selects(&sha256_hex(b"another")[..8], &hash));
    }
}
