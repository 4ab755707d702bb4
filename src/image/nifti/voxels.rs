//! The first 3-D volume's voxels: the datatype's size checked against bitpix, then the
//! stored bytes decoded to values with scl_slope/scl_inter applied.

use std::path::Path;

use super::field_err;
use super::header::Header;
use crate::image::ImageError;

/// Converts the leading bytes of one voxel to a value (little-endian flag).
type Convert = fn([u8; 8], bool) -> f64;

/// Bytes per voxel and their conversion, for the scalar datatypes read.
fn voxel_type(datatype: i16) -> Option<(usize, Convert)> {
    Some(match datatype {
        2 => (1, |a, _| a[0] as f64),
        256 => (1, |a, _| a[0] as i8 as f64),
        4 => (2, |a, le| {
            let v = [a[0], a[1]];
            (if le {
                i16::from_le_bytes(v)
            } else {
                i16::from_be_bytes(v)
            }) as f64
        }),
        512 => (2, |a, le| {
            let v = [a[0], a[1]];
            (if le {
                u16::from_le_bytes(v)
            } else {
                u16::from_be_bytes(v)
            }) as f64
        }),
        8 => (4, |a, le| {
            let v = [a[0], a[1], a[2], a[3]];
            (if le {
                i32::from_le_bytes(v)
            } else {
                i32::from_be_bytes(v)
            }) as f64
        }),
        768 => (4, |a, le| {
            let v = [a[0], a[1], a[2], a[3]];
            (if le {
                u32::from_le_bytes(v)
            } else {
                u32::from_be_bytes(v)
            }) as f64
        }),
        16 => (4, |a, le| {
            let v = [a[0], a[1], a[2], a[3]];
            (if le {
                f32::from_le_bytes(v)
            } else {
                f32::from_be_bytes(v)
            }) as f64
        }),
        64 => (8, |a, le| {
            if le {
                f64::from_le_bytes(a)
            } else {
                f64::from_be_bytes(a)
            }
        }),
        _ => return None,
    })
}

/// The first 3-D volume's sizes and how its voxels are stored.
pub(super) struct VoxelLayout {
    pub(super) dims: [u64; 3],
    /// Bytes per voxel.
    pub(super) size: usize,
    convert: Convert,
}

impl VoxelLayout {
    pub(super) fn voxels(&self) -> u64 {
        self.dims.iter().fold(1u64, |n, d| n.saturating_mul(*d))
    }
}

/// The layout of the first 3-D volume, checked against the datatype (and NIfTI-1's bitpix,
/// which must agree with it) before anything is read.
pub(super) fn voxel_layout(h: &Header, path: &Path) -> Result<VoxelLayout, ImageError> {
    let Some((size, convert)) = voxel_type(h.datatype) else {
        return Err(field_err(
            path,
            "datatype",
            h.datatype.to_string(),
            "a scalar integer or float type (2, 4, 8, 16, 64, 256, 512, 768)",
        ));
    };
    if let Some(bitpix) = h.bitpix
        && i64::from(bitpix) != 8 * size as i64
    {
        return Err(ImageError::NiftiField {
            path: path.to_path_buf(),
            field: "bitpix",
            value: format!("{bitpix} with datatype {}", h.datatype),
            expected: "8 x the datatype's bytes per voxel",
        });
    }
    Ok(VoxelLayout {
        dims: [1, 2, 3].map(|k| h.dim[k].max(1) as u64),
        size,
        convert,
    })
}

/// Decodes the first 3-D volume (laid out as `layout`, at `vox_offset` in `b`), applying
/// scl_slope/inter.
pub(super) fn decode_raw(
    b: &[u8],
    h: &Header,
    layout: &VoxelLayout,
    path: &Path,
) -> Result<Vec<f32>, ImageError> {
    let (size, conv) = (layout.size, layout.convert);
    let start = h.vox_offset;
    let end = start.saturating_add(layout.voxels().saturating_mul(size as u64));
    if end > b.len() as u64 {
        return Err(ImageError::Nifti {
            path: path.to_path_buf(),
            message: format!(
                "voxel data needs {end} bytes, the file has {} (truncated?)",
                b.len()
            ),
        });
    }
    let (start, end) = (start as usize, end as usize);
    // scl_slope 0 (or not a number) means no scaling, as nibabel and the standard read it
    let (slope, inter) = if h.scl_slope != 0.0 && h.scl_slope.is_finite() {
        if !h.scl_inter.is_finite() {
            return Err(ImageError::NiftiField {
                path: path.to_path_buf(),
                field: "scl_inter",
                value: h.scl_inter.to_string(),
                expected: "a finite intercept when scl_slope scales the voxels",
            });
        }
        (h.scl_slope, h.scl_inter)
    } else {
        (1.0, 0.0)
    };
    let data: Vec<f32> = b[start..end]
        .chunks_exact(size)
        .map(|c| {
            let mut a = [0u8; 8];
            a[..size].copy_from_slice(c);
            (conv(a, h.little_endian) * slope + inter) as f32
        })
        .collect();
    let bad = data.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        return Err(ImageError::Nifti {
            path: path.to_path_buf(),
            message: format!(
                "{bad} of {} voxels are not finite numbers (NaN or infinite intensities)",
                data.len()
            ),
        });
    }
    Ok(data)
}
