//! The NIfTI header fields the reader needs: NIfTI-1's 348 bytes parsed by the `nifti` crate,
//! NIfTI-2's 540 by our own parser (the crate reads only NIfTI-1), either byte order, and the
//! dimensions checked before anything else is read.

use std::path::Path;

use super::field_err;
use crate::image::ImageError;

/// The header fields geometry and decoding need, from a NIfTI-1 or NIfTI-2 header.
#[derive(Debug, Clone)]
pub(super) struct Header {
    pub(super) version: u8,
    /// Voxels after the header in the same file (`n+1`, `n+2`), not in a `.img` beside it.
    pub(super) single_file: bool,
    /// NIfTI-1's bits per voxel, which must agree with `datatype`.
    pub(super) bitpix: Option<i16>,
    pub(super) dim: [i64; 8],
    pub(super) pixdim: [f64; 8],
    pub(super) datatype: i16,
    pub(super) vox_offset: u64,
    pub(super) scl_slope: f64,
    pub(super) scl_inter: f64,
    pub(super) qform_code: i32,
    pub(super) sform_code: i32,
    pub(super) quatern: [f64; 3],
    pub(super) qoffset: [f64; 3],
    pub(super) srow: [[f64; 4]; 3],
    pub(super) xyzt_units: i32,
    pub(super) little_endian: bool,
}

/// The NIfTI-1 header (348 bytes, either byte order), parsed by the `nifti` crate.
pub(super) fn parse_nifti1(b: &[u8], path: &Path) -> Result<Header, ImageError> {
    let head = b
        .get(..348)
        .ok_or_else(|| field_err(path, "header", format!("{} bytes", b.len()), "348 bytes"))?;
    let h = nifti::NiftiHeader::from_reader(head).map_err(|e| ImageError::Nifti {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let single_file = match &h.magic {
        b"n+1\0" => true,
        b"ni1\0" => false,
        other => {
            return Err(field_err(
                path,
                "magic",
                format!("{:?}", String::from_utf8_lossy(other)),
                "\"n+1\" (single file) or \"ni1\" (.hdr/.img pair)",
            ));
        }
    };
    let header = Header {
        version: 1,
        single_file,
        bitpix: Some(h.bitpix),
        dim: h.dim.map(i64::from),
        pixdim: h.pixdim.map(f64::from),
        datatype: h.datatype,
        vox_offset: if h.vox_offset.is_finite() {
            h.vox_offset.max(0.0) as u64
        } else {
            u64::MAX
        },
        scl_slope: h.scl_slope as f64,
        scl_inter: h.scl_inter as f64,
        qform_code: h.qform_code as i32,
        sform_code: h.sform_code as i32,
        quatern: [h.quatern_b, h.quatern_c, h.quatern_d].map(f64::from),
        qoffset: [h.quatern_x, h.quatern_y, h.quatern_z].map(f64::from),
        srow: [h.srow_x, h.srow_y, h.srow_z].map(|r| r.map(f64::from)),
        xyzt_units: h.xyzt_units as i32,
        little_endian: matches!(h.endianness, nifti::Endianness::Little),
    };
    check_dims(&header, path)?;
    Ok(header)
}

fn check_dims(h: &Header, path: &Path) -> Result<(), ImageError> {
    if !(1..=7).contains(&h.dim[0]) {
        return Err(field_err(path, "dim[0]", h.dim[0].to_string(), "1 to 7"));
    }
    for k in 1..=3 {
        if h.dim[0] >= k as i64 && h.dim[k] < 1 {
            return Err(field_err(
                path,
                "dim[1..3]",
                format!("{:?}", &h.dim[1..4]),
                "positive sizes",
            ));
        }
    }
    Ok(())
}

pub(super) fn parse_nifti2(b: &[u8], path: &Path) -> Result<Header, ImageError> {
    if b.len() < 540 {
        return Err(field_err(
            path,
            "header",
            format!("{} bytes", b.len()),
            "540 bytes",
        ));
    }
    let le = i32::from_le_bytes([b[0], b[1], b[2], b[3]]) == 540;
    let arr8 = |o: usize| -> [u8; 8] {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[o..o + 8]);
        a
    };
    let i64_at = |o: usize| {
        if le {
            i64::from_le_bytes(arr8(o))
        } else {
            i64::from_be_bytes(arr8(o))
        }
    };
    let f64_at = |o: usize| {
        if le {
            f64::from_le_bytes(arr8(o))
        } else {
            f64::from_be_bytes(arr8(o))
        }
    };
    let i32_at = |o: usize| {
        let a = [b[o], b[o + 1], b[o + 2], b[o + 3]];
        if le {
            i32::from_le_bytes(a)
        } else {
            i32::from_be_bytes(a)
        }
    };
    let i16_at = |o: usize| {
        let a = [b[o], b[o + 1]];
        if le {
            i16::from_le_bytes(a)
        } else {
            i16::from_be_bytes(a)
        }
    };
    if &b[4..8] != b"n+2\0" {
        return Err(field_err(
            path,
            "magic",
            format!("{:?}", &b[4..12]),
            "\"n+2\" (single-file NIfTI-2)",
        ));
    }
    let h = Header {
        version: 2,
        single_file: true,
        bitpix: None,
        dim: std::array::from_fn(|k| i64_at(16 + 8 * k)),
        pixdim: std::array::from_fn(|k| f64_at(104 + 8 * k)),
        datatype: i16_at(12),
        vox_offset: i64_at(168).max(0) as u64,
        scl_slope: f64_at(176),
        scl_inter: f64_at(184),
        qform_code: i32_at(344),
        sform_code: i32_at(348),
        quatern: [f64_at(352), f64_at(360), f64_at(368)],
        qoffset: [f64_at(376), f64_at(384), f64_at(392)],
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f64_at(400 + 32 * r + 8 * c))),
        xyzt_units: i32_at(500),
        little_endian: le,
    };
    check_dims(&h, path)?;
    Ok(h)
}
