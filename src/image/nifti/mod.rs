//! Reading NIfTI-1 (header parsed by the `nifti` crate) and NIfTI-2 (a small header parser of
//! our own: the crate reads only 348-byte headers) into a [`Volume`] in LPS millimetres. The
//! voxels are decoded here for both: the sizes a header claims are checked (datatype against
//! bitpix, data against the bytes present and the memory budget) before anything is read,
//! which the crate's reader does not do (it panics or allocates on a lying header).
//!
//! The affine follows the NIfTI-1 standard: the sform when `sform_code > 0`, else the qform
//! when `qform_code > 0`, else pixdim alone (method 1: origin 0, no centring, unlike nibabel's
//! ANALYZE fallback). Spatial units (`xyzt_units`) are converted to mm, then RAS to LPS by
//! negating the first two world axes, once, here. `scl_slope`/`scl_inter` are applied.
//!
//! Here: finding and opening the files, reading only as many bytes as the header claims, and
//! writing; the header's fields (`header`), the voxels' decoding (`voxels`) and the affine
//! (`affine`) each have their own module.

mod affine;
mod header;
mod voxels;

use std::io::Read;
use std::path::Path;

use ndarray::ShapeBuilder;

use crate::image::IngestConfig;
use crate::image::{ImageError, ImageInfo, LoadedImage, Volume};
use affine::{geometry, ras_affine_of};
use header::{parse_nifti1, parse_nifti2};
use voxels::{decode_raw, voxel_layout};

fn field_err(
    path: &Path,
    field: &'static str,
    value: String,
    expected: &'static str,
) -> ImageError {
    ImageError::NiftiField {
        path: path.to_path_buf(),
        field,
        value,
        expected,
    }
}

/// True if `path` names a NIfTI file by its extension.
pub fn is_nifti_path(path: &Path) -> bool {
    let name = path.to_string_lossy().to_ascii_lowercase();
    name.ends_with(".nii") || name.ends_with(".nii.gz") || name.ends_with(".hdr")
}

/// Bytes in MiB, for messages.
const MIB: f64 = 1048576.0;

/// The file's bytes as stored, inflated when its name ends in `.gz`.
fn open_reader(path: &Path) -> Result<Box<dyn Read>, ImageError> {
    let file = std::fs::File::open(path).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    Ok(if gz {
        Box::new(flate2::read::GzDecoder::new(std::io::BufReader::new(file)))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// Appends to `bytes` from `reader` until it holds `n` bytes or the stream ends: a gzip
/// stream is never inflated beyond what is asked for.
fn read_up_to(
    reader: &mut dyn Read,
    bytes: &mut Vec<u8>,
    n: u64,
    path: &Path,
) -> Result<(), ImageError> {
    let want = n.saturating_sub(bytes.len() as u64);
    reader
        .take(want)
        .read_to_end(bytes)
        .map_err(|source| ImageError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(())
}

/// The image file of an ANALYZE-style pair (`x.hdr` → `x.img`, else `x.img.gz`).
fn pair_image(path: &Path) -> Result<std::path::PathBuf, ImageError> {
    let img = path.with_extension("img");
    let gz = path.with_extension("img.gz");
    [img, gz]
        .into_iter()
        .find(|p| p.is_file())
        .ok_or_else(|| ImageError::NotFound {
            path: path.with_extension("img"),
        })
}

/// Reads a NIfTI-1 or NIfTI-2 file (`.nii`, `.nii.gz`, or an `.hdr`/`.img` pair for NIfTI-1).
/// The header is read first; the sizes it claims are checked against `ingest.max_file_mib`
/// and `ingest.max_volume_mib` before any voxel is read, and no more bytes than it claims are
/// read (or inflated).
pub fn read_nifti(path: &Path, cfg: &IngestConfig) -> Result<LoadedImage, ImageError> {
    if !path.is_file() {
        return Err(ImageError::NotFound {
            path: path.to_path_buf(),
        });
    }
    let mut reader = open_reader(path)?;
    let mut bytes = Vec::new();
    read_up_to(&mut reader, &mut bytes, 540, path)?;
    let sizeof_hdr = |le: bool| {
        bytes.get(0..4).map(|b| {
            let a = [b[0], b[1], b[2], b[3]];
            if le {
                i32::from_le_bytes(a)
            } else {
                i32::from_be_bytes(a)
            }
        })
    };
    let header = match (sizeof_hdr(true), sizeof_hdr(false)) {
        (Some(540), _) | (_, Some(540)) => parse_nifti2(&bytes, path)?,
        (Some(348), _) | (_, Some(348)) => parse_nifti1(&bytes, path)?,
        _ => {
            return Err(field_err(
                path,
                "sizeof_hdr",
                match sizeof_hdr(true) {
                    Some(v) => v.to_string(),
                    None => format!("absent ({} bytes in the file)", bytes.len()),
                },
                "348 (NIfTI-1) or 540 (NIfTI-2)",
            ));
        }
    };
    let layout = voxel_layout(&header, path)?;
    super::check_volume_budget(path, layout.dims, cfg)?;
    let needed = header
        .vox_offset
        .saturating_add(layout.voxels().saturating_mul(layout.size as u64));
    let max_file = (cfg.max_file_mib * MIB) as u64;
    if needed > max_file {
        return Err(ImageError::TooLarge {
            path: path.to_path_buf(),
            size_mib: needed as f64 / MIB,
            max_mib: cfg.max_file_mib,
        });
    }
    // the voxels: after the header in a single file, at vox_offset in the pair's image file
    let data_path = match header.version {
        1 if !header.single_file => {
            let img = pair_image(path)?;
            reader = open_reader(&img)?;
            bytes.clear();
            img
        }
        _ => path.to_path_buf(),
    };
    read_up_to(&mut reader, &mut bytes, needed, &data_path)?;
    let data = decode_raw(&bytes, &header, &layout, &data_path)?;
    let (dims, spacing, origin, direction, warnings) = geometry(&header, path)?;
    let mut warnings = warnings;
    let extra: i64 = header.dim[4..=(header.dim[0].clamp(3, 7) as usize)]
        .iter()
        .map(|d| (*d).max(1))
        .product();
    if extra > 1 {
        warnings.push(format!(
            "{extra} volumes in the file (4-D or more): the first is read"
        ));
    }
    let volume = Volume {
        dims,
        spacing,
        origin,
        direction,
        data,
    };
    Ok(LoadedImage {
        volume,
        info: ImageInfo {
            format: format!("nifti{}", header.version),
            modality: String::new(),
            transfer_syntax: String::new(),
            transfer_syntax_name: String::new(),
            slices: dims[2],
            files: 1,
            series_uid_sha256: None,
            laterality: None,
            warnings,
            notes: Vec::new(),
        },
    })
}

/// Writes `data` (i fastest, the dims of `geometry`) as a NIfTI-1 file with the geometry's
/// affine in both sform and qform (scanner-anatomical, mm). Compressed when the name ends in
/// `.gz`. Written atomically: a temporary folder beside the target, then a rename. The gzip
/// stream carries no timestamp, so equal inputs give equal bytes.
pub fn write_nifti<T>(path: &Path, geometry: &Volume, data: &[T]) -> Result<(), ImageError>
where
    T: nifti::DataElement + bytemuck::Pod + Clone,
{
    let io = |source: std::io::Error| ImageError::Io {
        path: path.to_path_buf(),
        source,
    };
    let [nx, ny, nz] = geometry.dims;
    if data.len() != nx * ny * nz {
        return Err(io(std::io::Error::other(format!(
            "{} values for dims {:?}",
            data.len(),
            geometry.dims
        ))));
    }
    let array = ndarray::Array3::from_shape_vec((nx, ny, nz).f(), data.to_vec())
        .map_err(|e| io(std::io::Error::other(e.to_string())))?;
    let mut pixdim = [1.0f32; 8];
    for a in 0..3 {
        pixdim[a + 1] = geometry.spacing[a] as f32;
    }
    let mut header = nifti::NiftiHeader {
        pixdim,
        xyzt_units: 2, // mm
        ..Default::default()
    };
    let affine = ras_affine_of(geometry);
    header.set_sform(&affine, nifti::XForm::ScannerAnat);
    header.set_qform(&affine, nifti::XForm::ScannerAnat);
    let name = path
        .file_name()
        .ok_or_else(|| io(std::io::Error::other("no file name")))?;
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let tmp_dir = parent.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::create_dir_all(&tmp_dir).map_err(io)?;
    let tmp = tmp_dir.join(name);
    let gz = name.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let result = nifti::writer::WriterOptions::new(&tmp)
        .reference_header(&header)
        .compress(gz)
        .write_nifti(&array)
        .map_err(|e| io(std::io::Error::other(e.to_string())))
        .and_then(|_| std::fs::rename(&tmp, path).map_err(io));
    let _ = std::fs::remove_dir_all(&tmp_dir);
    result
}
