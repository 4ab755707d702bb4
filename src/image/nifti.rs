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

use std::io::Read;
use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Vector3};
use ndarray::ShapeBuilder;

use crate::image::IngestConfig;
use crate::image::{ImageError, ImageInfo, LoadedImage, Volume};

/// The header fields geometry and decoding need, from a NIfTI-1 or NIfTI-2 header.
#[derive(Debug, Clone)]
struct Header {
    version: u8,
    /// Voxels after the header in the same file (`n+1`, `n+2`), not in a `.img` beside it.
    single_file: bool,
    /// NIfTI-1's bits per voxel, which must agree with `datatype`.
    bitpix: Option<i16>,
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

/// A matrix on one line, rows separated by `;` (error messages are one line).
fn one_line(m: &Matrix4<f64>) -> String {
    let rows: Vec<String> = m
        .row_iter()
        .map(|r| {
            r.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    format!("[{}]", rows.join("; "))
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

/// The NIfTI-1 header (348 bytes, either byte order), parsed by the `nifti` crate.
fn parse_nifti1(b: &[u8], path: &Path) -> Result<Header, ImageError> {
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
struct VoxelLayout {
    dims: [u64; 3],
    /// Bytes per voxel.
    size: usize,
    convert: Convert,
}

impl VoxelLayout {
    fn voxels(&self) -> u64 {
        self.dims.iter().fold(1u64, |n, d| n.saturating_mul(*d))
    }
}

/// The layout of the first 3-D volume, checked against the datatype (and NIfTI-1's bitpix,
/// which must agree with it) before anything is read.
fn voxel_layout(h: &Header, path: &Path) -> Result<VoxelLayout, ImageError> {
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
fn decode_raw(
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
    if affine.iter().any(|v| !v.is_finite()) {
        return Err(field_err(
            path,
            "affine",
            one_line(&affine),
            "finite numbers (origin and voxel axes)",
        ));
    }
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
                one_line(&affine),
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
            one_line(&affine),
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
