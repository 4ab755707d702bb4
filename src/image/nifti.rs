//! Reading NIfTI-1 (with the `nifti` crate) and NIfTI-2 (a small header parser of our own:
//! the crate reads only 348-byte headers) into a [`Volume`] in LPS millimetres.
//!
//! The affine follows the NIfTI-1 standard: the sform when `sform_code > 0`, else the qform
//! when `qform_code > 0`, else pixdim alone (method 1: origin 0, no centring, unlike nibabel's
//! ANALYZE fallback). Spatial units (`xyzt_units`) are converted to mm, then RAS to LPS by
//! negating the first two world axes, once, here. `scl_slope`/`scl_inter` are applied.

use std::io::Read;
use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Vector3};
use ndarray::{Axis, Ix3, ShapeBuilder};
use nifti::{IntoNdArray, NiftiObject, ReaderOptions};

use crate::image::{ImageError, ImageInfo, LoadedImage, Volume};

/// The header fields geometry and decoding need, from a NIfTI-1 or NIfTI-2 header.
#[derive(Debug, Clone)]
struct Header {
    version: u8,
    dim: [i64; 8],
    pixdim: [f64; 8],
    datatype: i16,
    vox_offset: u64,
    scl_slope: f64,
    scl_inter: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
    xyzt_units: i32,
    little_endian: bool,
}

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

fn read_bytes(path: &Path, max_bytes: u64) -> Result<Vec<u8>, ImageError> {
    let io = |source| ImageError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let reader: Box<dyn Read> = if gz {
        Box::new(flate2::read::GzDecoder::new(file))
    } else {
        Box::new(file)
    };
    reader
        .take(max_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max_bytes {
        return Err(ImageError::TooLarge {
            path: path.to_path_buf(),
            size_mib: bytes.len() as f64 / 1048576.0,
            max_mib: max_bytes as f64 / 1048576.0,
        });
    }
    Ok(bytes)
}

/// Reads a NIfTI-1 or NIfTI-2 file (`.nii`, `.nii.gz`, or an `.hdr`/`.img` pair for NIfTI-1).
pub fn read_nifti(path: &Path, max_bytes: u64) -> Result<LoadedImage, ImageError> {
    if !path.is_file() {
        return Err(ImageError::NotFound {
            path: path.to_path_buf(),
        });
    }
    let bytes = read_bytes(path, max_bytes)?;
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
    let (header, data) = match (sizeof_hdr(true), sizeof_hdr(false)) {
        (Some(540), _) | (_, Some(540)) => {
            let h = parse_nifti2(&bytes, path)?;
            let data = decode_raw(&bytes, &h, path)?;
            (h, data)
        }
        (Some(348), _) | (_, Some(348)) => read_nifti1(path)?,
        _ => {
            return Err(field_err(
                path,
                "sizeof_hdr",
                format!("{:?}", sizeof_hdr(true)),
                "348 (NIfTI-1) or 540 (NIfTI-2)",
            ));
        }
    };
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

fn read_nifti1(path: &Path) -> Result<(Header, Vec<f32>), ImageError> {
    let nerr = |e: nifti::NiftiError| ImageError::Nifti {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let obj = ReaderOptions::new().read_file(path).map_err(nerr)?;
    let h = obj.header();
    let header = Header {
        version: 1,
        dim: h.dim.map(i64::from),
        pixdim: h.pixdim.map(f64::from),
        datatype: h.datatype,
        vox_offset: h.vox_offset.max(0.0) as u64,
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
    let array = obj.into_volume().into_ndarray::<f32>().map_err(nerr)?;
    let mut array = array;
    while array.ndim() > 3 {
        let last = array.ndim() - 1;
        array = array.index_axis_move(Axis(last), 0);
    }
    let array = array
        .into_dimensionality::<Ix3>()
        .map_err(|e| ImageError::Nifti {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    // reversed axes iterate with i fastest, then j, then k: our layout
    let data: Vec<f32> = array.t().iter().copied().collect();
    Ok((header, data))
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

fn parse_nifti2(b: &[u8], path: &Path) -> Result<Header, ImageError> {
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

/// Converts the leading bytes of one voxel to a value (little-endian flag).
type Convert = fn([u8; 8], bool) -> f64;

/// Decodes the first 3-D volume of raw voxel bytes (NIfTI-2 path), applying scl_slope/inter.
fn decode_raw(b: &[u8], h: &Header, path: &Path) -> Result<Vec<f32>, ImageError> {
    let n: usize = (1..=3).map(|k| h.dim[k].max(1) as usize).product();
    let (size, conv): (usize, Convert) = match h.datatype {
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
        other => {
            return Err(field_err(
                path,
                "datatype",
                other.to_string(),
                "a scalar integer or float type",
            ));
        }
    };
    let start = h.vox_offset as usize;
    let end = start + n * size;
    if end > b.len() {
        return Err(ImageError::Nifti {
            path: path.to_path_buf(),
            message: format!(
                "voxel data needs {end} bytes, the file has {} (truncated?)",
                b.len()
            ),
        });
    }
    let (slope, inter) = if h.scl_slope != 0.0 && h.scl_slope.is_finite() {
        (
            h.scl_slope,
            if h.scl_inter.is_finite() {
                h.scl_inter
            } else {
                0.0
            },
        )
    } else {
        (1.0, 0.0)
    };
    Ok(b[start..end]
        .chunks_exact(size)
        .map(|c| {
            let mut a = [0u8; 8];
            a[..size].copy_from_slice(c);
            (conv(a, h.little_endian) * slope + inter) as f32
        })
        .collect())
}

type Geometry = (
    [usize; 3],
    [f64; 3],
    Vector3<f64>,
    Matrix3<f64>,
    Vec<String>,
);

/// The voxel-to-world affine (RAS, file units) per the NIfTI-1 standard's three methods.
fn ras_affine(
    h: &Header,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Matrix4<f64>, ImageError> {
    if h.sform_code > 0 {
        let s = &h.srow;
        return Ok(Matrix4::new(
            s[0][0], s[0][1], s[0][2], s[0][3], s[1][0], s[1][1], s[1][2], s[1][3], s[2][0],
            s[2][1], s[2][2], s[2][3], 0.0, 0.0, 0.0, 1.0,
        ));
    }
    let pix = [h.pixdim[1], h.pixdim[2], h.pixdim[3]];
    if pix.iter().any(|p| !p.is_finite() || *p == 0.0) {
        return Err(field_err(
            path,
            "pixdim[1..3]",
            format!("{pix:?}"),
            "non-zero voxel sizes",
        ));
    }
    if pix.iter().any(|p| *p < 0.0) {
        warnings.push("negative pixdim: absolute values used".into());
    }
    let [dx, dy, dz] = pix.map(f64::abs);
    if h.qform_code > 0 {
        let [b, c, d] = h.quatern;
        let a2 = 1.0 - (b * b + c * c + d * d);
        let (a, b, c, d) = if a2 > 1e-7 {
            (a2.sqrt(), b, c, d)
        } else {
            let n = (b * b + c * c + d * d).sqrt();
            if n == 0.0 {
                return Err(field_err(
                    path,
                    "quatern_b/c/d",
                    format!("{:?}", h.quatern),
                    "a unit quaternion",
                ));
            }
            (0.0, b / n, c / n, d / n)
        };
        let r = Matrix3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        );
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let m = r * Matrix3::from_diagonal(&Vector3::new(dx, dy, qfac * dz));
        let mut out = Matrix4::identity();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&m);
        out.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::from(h.qoffset));
        return Ok(out);
    }
    warnings
        .push("no sform or qform (both codes 0): pixdim only, origin 0 (NIfTI method 1)".into());
    Ok(Matrix4::from_diagonal(&nalgebra::Vector4::new(
        dx, dy, dz, 1.0,
    )))
}

fn geometry(h: &Header, path: &Path) -> Result<Geometry, ImageError> {
    let mut warnings = Vec::new();
    let mut affine = ras_affine(h, path, &mut warnings)?;
    let to_mm = match h.xyzt_units & 0x07 {
        1 => 1000.0,
        3 => 0.001,
        _ => 1.0,
    };
    let ras_to_lps = Matrix4::from_diagonal(&nalgebra::Vector4::new(-to_mm, -to_mm, to_mm, 1.0));
    affine = ras_to_lps * affine;
    let m = affine.fixed_view::<3, 3>(0, 0).into_owned();
    let mut spacing = [0.0; 3];
    let mut direction = Matrix3::zeros();
    for (c, s) in spacing.iter_mut().enumerate() {
        let col = m.column(c);
        let norm = col.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(field_err(
                path,
                "affine",
                format!("{affine}"),
                "three non-degenerate voxel axes",
            ));
        }
        *s = norm;
        direction.set_column(c, &(col / norm));
    }
    if direction.determinant().abs() < 1e-6 {
        return Err(field_err(
            path,
            "affine",
            format!("{affine}"),
            "linearly independent voxel axes",
        ));
    }
    let dims = [1, 2, 3].map(|k| {
        if h.dim[0] >= k as i64 {
            h.dim[k].max(1) as usize
        } else {
            1
        }
    });
    let origin = affine.fixed_view::<3, 1>(0, 3).into_owned();
    Ok((dims, spacing, origin, direction, warnings))
}

/// The world-to-file affine of `geometry` in NIfTI's RAS convention (LPS negated on x, y).
fn ras_affine_of(geometry: &Volume) -> Matrix4<f64> {
    let mut lps = Matrix4::identity();
    lps.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&geometry.index_to_world_matrix());
    lps.fixed_view_mut::<3, 1>(0, 3).copy_from(&geometry.origin);
    Matrix4::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0)) * lps
}

/// Writes `data` (i fastest, the dims of `geometry`) as a NIfTI-1 file with the geometry's
/// affine in both sform and qform (scanner-anatomical, mm). Compressed when the name ends in
/// `.gz`. Written atomically: a temporary folder beside the target, then a rename. The gzip
/// stream carries no timestamp, so equal inputs give equal bytes.
pub fn write_nifti<T>(path: &Path, geometry: &Volume, data: &[T]) -> Result<(), crate::Error>
where
    T: nifti::DataElement + bytemuck::Pod + Clone,
{
    let io = |source: std::io::Error| crate::Error::Io {
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
