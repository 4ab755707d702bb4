//! Finding DICOM files and reading their headers (everything before PixelData), so a folder
//! can be grouped into series without decoding a single pixel.

use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};

use dicom_dictionary_std::tags;
use dicom_object::{InMemDicomObject, OpenFileOptions};
use nalgebra::Vector3;
use rayon::prelude::*;

use super::tags as attr;
use crate::image::ImageError;
use crate::io_util::is_link_loop;

/// Modality rescale of one frame: `HU = slope · stored + intercept`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rescale {
    pub slope: f64,
    pub intercept: f64,
}

/// Geometry and rescale of one frame (a single-frame file has one).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameHeader {
    /// ImagePositionPatient: LPS position of the first transmitted pixel.
    pub position: Option<Vector3<f64>>,
    /// ImageOrientationPatient: row direction then column direction cosines.
    pub orientation: Option<[f64; 6]>,
    /// PixelSpacing: [spacing between rows, spacing between columns] in mm.
    pub pixel_spacing: Option<[f64; 2]>,
    pub rescale: Rescale,
}

/// The header of one DICOM image file.
#[derive(Debug, Clone)]
pub struct ImageFile {
    pub path: PathBuf,
    pub series_uid: String,
    /// SeriesNumber: identifies a series in a listing without free text (a description can
    /// hold a patient's name, so it is never read).
    pub series_number: Option<i64>,
    pub modality: String,
    pub transfer_syntax: String,
    pub rows: usize,
    pub columns: usize,
    pub photometric: String,
    pub frames: Vec<FrameHeader>,
    /// Laterality (0020,0060), ImageLaterality (0020,0062) or FrameLaterality, as written.
    pub laterality: Option<String>,
    /// SpacingBetweenSlices, else SliceThickness (mm): used only when positions are absent.
    pub slice_spacing_hint: Option<f64>,
}

/// What scanning one file found.
#[derive(Debug)]
pub enum Scanned {
    Image(Box<ImageFile>),
    Skipped { path: PathBuf, reason: String },
}

/// SOP classes that are never image volumes: DICOMDIR, structured reports, segmentations,
/// presentation states, key objects, encapsulated documents.
fn is_non_image_class(uid: &str) -> Option<&'static str> {
    match uid {
        "1.2.840.10008.1.3.10" => Some("DICOMDIR (media storage directory)"),
        "1.2.840.10008.5.1.4.1.1.66.4" => Some("segmentation (SEG)"),
        u if u.starts_with("1.2.840.10008.5.1.4.1.1.88.") => Some("structured report (SR)"),
        u if u.starts_with("1.2.840.10008.5.1.4.1.1.11.") => Some("presentation state"),
        u if u.starts_with("1.2.840.10008.5.1.4.1.1.104.") => Some("encapsulated document"),
        _ => None,
    }
}

/// True for media directory index files (DICOMDIR and its variants), by name.
fn is_dicomdir_name(path: &Path) -> bool {
    path.file_name()
        .map(|n| {
            n.to_string_lossy()
                .to_ascii_uppercase()
                .starts_with("DICOMDIR")
        })
        .unwrap_or(false)
}

/// All regular files under `root` (recursively), sorted for determinism.
pub fn list_files(root: &Path) -> Result<Vec<PathBuf>, ImageError> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = fs::read_dir(&dir).map_err(|source| ImageError::Io {
            path: dir.clone(),
            source,
        })?;
        for entry in entries {
            let entry = entry.map_err(|source| ImageError::Io {
                path: dir.clone(),
                source,
            })?;
            let path = entry.path();
            let kind = entry.file_type().map_err(|source| ImageError::Io {
                path: path.clone(),
                source,
            })?;
            if kind.is_symlink() && is_link_loop(&path, root) {
                return Err(ImageError::SymlinkLoop {
                    folder: root.to_path_buf(),
                    link: path,
                });
            }
            if kind.is_dir() {
                stack.push(path);
            } else if kind.is_file() || (kind.is_symlink() && path.is_file()) {
                out.push(path);
            }
        }
    }
    out.sort();
    Ok(out)
}

/// True if the file carries the DICM marker of a DICOM Part 10 file.
pub fn has_dicom_marker(path: &Path) -> Result<bool, ImageError> {
    let mut head = [0u8; 132];
    let mut f = fs::File::open(path).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut filled = 0;
    while filled < head.len() {
        match f.read(&mut head[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(source) => {
                return Err(ImageError::Io {
                    path: path.to_path_buf(),
                    source,
                });
            }
        }
    }
    Ok(filled == 132 && &head[128..132] == b"DICM")
}

/// Reads the headers of `files` in parallel. Files without the DICM marker are skipped with a
/// note; a file that has the marker but does not parse is an error naming it.
pub fn scan_files(files: &[PathBuf], max_bytes: u64) -> Result<Vec<Scanned>, ImageError> {
    files.par_iter().map(|p| scan_file(p, max_bytes)).collect()
}

fn scan_file(path: &Path, max_bytes: u64) -> Result<Scanned, ImageError> {
    let size = fs::metadata(path)
        .map_err(|source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if size > max_bytes {
        return Err(ImageError::TooLarge {
            path: path.to_path_buf(),
            size_mib: size as f64 / 1048576.0,
            max_mib: max_bytes as f64 / 1048576.0,
        });
    }
    if !has_dicom_marker(path)? {
        return Ok(Scanned::Skipped {
            path: path.to_path_buf(),
            reason: "not a DICOM file".into(),
        });
    }
    match super::lengths::check_element_lengths(path, size, max_bytes) {
        Ok(()) => {}
        Err(e) if is_dicomdir_name(path) => {
            return Ok(Scanned::Skipped {
                path: path.to_path_buf(),
                reason: format!("unreadable DICOMDIR index ({e})"),
            });
        }
        Err(e) => return Err(e),
    }
    let obj = match OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
    {
        Ok(obj) => obj,
        // a damaged media directory index does not hold image data: note it and go on
        Err(e) if is_dicomdir_name(path) => {
            return Ok(Scanned::Skipped {
                path: path.to_path_buf(),
                reason: format!("unreadable DICOMDIR index ({e})"),
            });
        }
        Err(e) => {
            return Err(ImageError::DicomParse {
                path: path.to_path_buf(),
                message: e.to_string(),
            });
        }
    };
    let sop_class = attr::string(&obj, tags::SOP_CLASS_UID).unwrap_or_else(|| {
        obj.meta()
            .media_storage_sop_class_uid()
            .trim_end_matches('\0')
            .to_string()
    });
    if let Some(kind) = is_non_image_class(&sop_class) {
        return Ok(Scanned::Skipped {
            path: path.to_path_buf(),
            reason: kind.into(),
        });
    }
    if is_localizer(&obj) {
        return Ok(Scanned::Skipped {
            path: path.to_path_buf(),
            reason: "a localizer (scout) image, not part of a volume (ImageType LOCALIZER)".into(),
        });
    }
    let rows = attr::int(&obj, tags::ROWS, "Rows (0028,0010)", path)?;
    let columns = attr::int(&obj, tags::COLUMNS, "Columns (0028,0011)", path)?;
    let (Some(rows), Some(columns)) = (rows, columns) else {
        return Ok(Scanned::Skipped {
            path: path.to_path_buf(),
            reason: "no image (Rows/Columns absent)".into(),
        });
    };
    if rows <= 0 || columns <= 0 {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: "Rows/Columns",
            value: format!("{rows}x{columns}"),
            expected: "positive sizes".into(),
        });
    }
    let transfer_syntax = obj
        .meta()
        .transfer_syntax()
        .trim_end_matches('\0')
        .to_string();
    let header = read_image_header(
        &obj,
        path,
        rows as usize,
        columns as usize,
        transfer_syntax,
        size,
    )?;
    Ok(Scanned::Image(Box::new(header)))
}

/// Whether ImageType's third value is LOCALIZER (the CT and MR image IODs' term for a scout
/// that planned the scan): exports put such images beside the volume, in their own series.
fn is_localizer(obj: &InMemDicomObject) -> bool {
    attr::string(obj, tags::IMAGE_TYPE)
        .is_some_and(|t| t.split('\\').nth(2).map(str::trim) == Some("LOCALIZER"))
}

fn read_image_header(
    obj: &InMemDicomObject,
    path: &Path,
    rows: usize,
    columns: usize,
    transfer_syntax: String,
    file_bytes: u64,
) -> Result<ImageFile, ImageError> {
    let series_uid =
        attr::string(obj, tags::SERIES_INSTANCE_UID).ok_or_else(|| ImageError::MissingTag {
            path: path.to_path_buf(),
            tag: "SeriesInstanceUID (0020,000E)",
            expected: "a UID grouping the slices of one series",
        })?;
    let samples = attr::int(
        obj,
        tags::SAMPLES_PER_PIXEL,
        "SamplesPerPixel (0028,0002)",
        path,
    )?;
    if samples.unwrap_or(1) != 1 {
        return Err(ImageError::Unsupported {
            path: path.to_path_buf(),
            what: format!("SamplesPerPixel {} (colour images)", samples.unwrap_or(1)),
        });
    }
    let photometric =
        attr::string(obj, tags::PHOTOMETRIC_INTERPRETATION).unwrap_or_else(|| "MONOCHROME2".into());
    if photometric != "MONOCHROME1" && photometric != "MONOCHROME2" {
        return Err(ImageError::Unsupported {
            path: path.to_path_buf(),
            what: format!("PhotometricInterpretation {photometric}"),
        });
    }
    let n_frames = attr::int(
        obj,
        tags::NUMBER_OF_FRAMES,
        "NumberOfFrames (0028,0008)",
        path,
    )?
    .unwrap_or(1);
    if n_frames < 1 {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: "NumberOfFrames (0028,0008)",
            value: n_frames.to_string(),
            expected: "at least 1".into(),
        });
    }
    let least = least_frame_bytes(obj, path, rows, columns, &transfer_syntax)?;
    if (n_frames as u64).saturating_mul(least) > file_bytes {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: "NumberOfFrames (0028,0008)",
            value: n_frames.to_string(),
            expected: format!(
                "no more frames than the file's {file_bytes} bytes can hold ({least} bytes or more each)"
            ),
        });
    }
    let root = frame_from(obj, None, None, path)?;
    let shared = attr::first_item(obj, tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE);
    let per_frame = obj
        .get(tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items());
    let frames = match per_frame {
        Some(items) if n_frames > 1 || shared.is_some() => {
            if items.len() != n_frames as usize {
                return Err(ImageError::BadValue {
                    path: path.to_path_buf(),
                    tag: "PerFrameFunctionalGroupsSequence (5200,9230)",
                    value: format!("{} items", items.len()),
                    expected: format!("one item per frame ({n_frames})"),
                });
            }
            items
                .iter()
                .map(|item| frame_from(obj, Some(item), shared, path))
                .collect::<Result<Vec<_>, _>>()?
        }
        _ => vec![root; n_frames as usize],
    };
    let laterality = attr::string(obj, tags::LATERALITY)
        .or_else(|| attr::string(obj, tags::IMAGE_LATERALITY))
        .or_else(|| attr::string(obj, tags::FRAME_LATERALITY));
    let slice_spacing_hint = match attr::float(
        obj,
        tags::SPACING_BETWEEN_SLICES,
        "SpacingBetweenSlices",
        path,
    )? {
        Some(v) => Some(v),
        None => attr::float(obj, tags::SLICE_THICKNESS, "SliceThickness", path)?,
    }
    .filter(|v| *v > 0.0);
    Ok(ImageFile {
        path: path.to_path_buf(),
        series_uid,
        series_number: attr::int(obj, tags::SERIES_NUMBER, "SeriesNumber (0020,0011)", path)
            .ok()
            .flatten(),
        modality: attr::string(obj, tags::MODALITY).unwrap_or_default(),
        transfer_syntax,
        rows,
        columns,
        photometric,
        frames,
        laterality,
        slice_spacing_hint,
    })
}

/// The fewest bytes one frame takes in the file: all its pixels when they are stored as they
/// are (native transfer syntaxes), else the 8-byte header of the item holding its fragment.
/// Checked against the file's size before anything is sized by NumberOfFrames.
fn least_frame_bytes(
    obj: &InMemDicomObject,
    path: &Path,
    rows: usize,
    columns: usize,
    transfer_syntax: &str,
) -> Result<u64, ImageError> {
    use dicom_encoding::TransferSyntaxIndex;
    let native = dicom_transfer_syntax_registry::TransferSyntaxRegistry
        .get(transfer_syntax)
        .is_some_and(|ts| ts.is_codec_free());
    if !native {
        return Ok(8);
    }
    let allocated =
        attr::int(obj, tags::BITS_ALLOCATED, "BitsAllocated (0028,0100)", path)?.unwrap_or(16);
    if !(1..=64).contains(&allocated) {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: "BitsAllocated (0028,0100)",
            value: allocated.to_string(),
            expected: "1 to 64 bits".into(),
        });
    }
    let bits = rows as u64 * columns as u64 * allocated as u64;
    Ok(bits.div_ceil(8))
}

/// Geometry and rescale of one frame: from the per-frame functional group item, else the
/// shared functional group, else the dataset root.
fn frame_from(
    root: &InMemDicomObject,
    per_frame: Option<&InMemDicomObject>,
    shared: Option<&InMemDicomObject>,
    path: &Path,
) -> Result<FrameHeader, ImageError> {
    let groups: Vec<&InMemDicomObject> = per_frame.into_iter().chain(shared).collect();
    let lookup = |seq: dicom_core::Tag| -> Vec<&InMemDicomObject> {
        groups
            .iter()
            .filter_map(|g| attr::first_item(g, seq))
            .chain(std::iter::once(root))
            .collect()
    };
    let position = first_found(&lookup(tags::PLANE_POSITION_SEQUENCE), |o| {
        attr::floats(
            o,
            tags::IMAGE_POSITION_PATIENT,
            "ImagePositionPatient (0020,0032)",
            3,
            path,
        )
    })?
    .map(|v| Vector3::new(v[0], v[1], v[2]));
    let orientation = first_found(&lookup(tags::PLANE_ORIENTATION_SEQUENCE), |o| {
        attr::floats(
            o,
            tags::IMAGE_ORIENTATION_PATIENT,
            "ImageOrientationPatient (0020,0037)",
            6,
            path,
        )
    })?
    .map(|v| [v[0], v[1], v[2], v[3], v[4], v[5]]);
    let pixel_spacing = first_found(&lookup(tags::PIXEL_MEASURES_SEQUENCE), |o| {
        attr::floats(o, tags::PIXEL_SPACING, "PixelSpacing (0028,0030)", 2, path)
    })?
    .map(|v| [v[0], v[1]]);
    if let Some(ps) = pixel_spacing
        && (ps[0] <= 0.0 || ps[1] <= 0.0)
    {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: "PixelSpacing (0028,0030)",
            value: format!("{ps:?}"),
            expected: "two positive spacings in mm".into(),
        });
    }
    let transform = lookup(tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE);
    let slope = first_found(&transform, |o| {
        attr::floats(o, tags::RESCALE_SLOPE, "RescaleSlope (0028,1053)", 1, path)
    })?
    .map_or(1.0, |v| v[0]);
    let intercept = first_found(&transform, |o| {
        attr::floats(
            o,
            tags::RESCALE_INTERCEPT,
            "RescaleIntercept (0028,1052)",
            1,
            path,
        )
    })?
    .map_or(0.0, |v| v[0]);
    Ok(FrameHeader {
        position,
        orientation,
        pixel_spacing,
        rescale: Rescale { slope, intercept },
    })
}

/// The first value `f` finds in `objs`, in order.
fn first_found<F>(objs: &[&InMemDicomObject], f: F) -> Result<Option<Vec<f64>>, ImageError>
where
    F: Fn(&InMemDicomObject) -> Result<Option<Vec<f64>>, ImageError>,
{
    for o in objs {
        if let Some(v) = f(o)? {
            return Ok(Some(v));
        }
    }
    Ok(None)
}
