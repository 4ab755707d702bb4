//! Decoding pixel data into Hounsfield units: each file opened and decoded once (in parallel),
//! stored values taken raw and rescaled with that frame's own slope/intercept, MONOCHROME1
//! inverted within BitsStored so that larger always means denser.

use std::io::Read;
use std::path::Path;

use dicom_dictionary_std::tags;
use dicom_object::OpenFileOptions;
use dicom_pixeldata::{ConvertOptions, ModalityLutOption, PixelDecoder};
use rayon::prelude::*;

use super::scan::{ImageFile, Rescale};
use super::tags as attr;
use crate::image::ImageError;
use dicom_object::InMemDicomObject;

fn decode_err(path: &Path) -> impl Fn(String) -> ImageError + '_ {
    move |message| ImageError::Decode {
        path: path.to_path_buf(),
        message,
    }
}

/// Fills `data` (i fastest, one plane per k) with the frames listed in `order`.
pub fn decode_series(
    files: &[ImageFile],
    order: &[(usize, usize)],
    data: &mut [f32],
    on_plane: &(dyn Fn() + Sync),
) -> Result<(), ImageError> {
    let plane = files[0].rows * files[0].columns;
    // group the output planes by file so that each file is decoded once
    let mut per_file: Vec<Vec<(usize, &mut [f32])>> =
        (0..files.len()).map(|_| Vec::new()).collect();
    for ((file, frame), chunk) in order.iter().zip(data.chunks_mut(plane)) {
        per_file[*file].push((*frame, chunk));
    }
    per_file
        .into_par_iter()
        .enumerate()
        .filter(|(_, jobs)| !jobs.is_empty())
        .try_for_each(|(fi, jobs)| decode_file(&files[fi], jobs, on_plane))
}

fn decode_file(
    file: &ImageFile,
    jobs: Vec<(usize, &mut [f32])>,
    on_plane: &(dyn Fn() + Sync),
) -> Result<(), ImageError> {
    let path = file.path.as_path();
    let err = decode_err(path);
    let obj = OpenFileOptions::new()
        .open_file(path)
        .map_err(|e| ImageError::DicomParse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    if obj.get(tags::PIXEL_DATA).is_none() {
        return Err(ImageError::MissingTag {
            path: path.to_path_buf(),
            tag: "PixelData (7FE0,0010)",
            expected: "the image's pixel data (is the file truncated?)",
        });
    }
    let stored_to_hu = StoredToHu::new(&obj, file)?;
    if let Some(bytes) = native_16bit_pixels(&obj, file)? {
        let plane = file.rows * file.columns;
        for (frame, out) in jobs {
            let start = frame * plane * 2;
            let Some(frame_bytes) = bytes.get(start..start + plane * 2) else {
                return Err(err(format!(
                    "PixelData holds {} bytes, frame {frame} needs bytes {start}..{}",
                    bytes.len(),
                    start + plane * 2
                )));
            };
            let rescale = file.frames[frame].rescale;
            for (o, c) in out.iter_mut().zip(frame_bytes.chunks_exact(2)) {
                *o = stored_to_hu.convert(u16::from_le_bytes([c[0], c[1]]), rescale);
            }
            on_plane();
        }
        return Ok(());
    }
    check_deflated_frames(&obj, file)?;
    let decoded = obj.decode_pixel_data().map_err(|e| err(e.to_string()))?;
    if decoded.rows() as usize != file.rows || decoded.columns() as usize != file.columns {
        return Err(err(format!(
            "decoded size {}x{} differs from Rows/Columns {}x{}",
            decoded.columns(),
            decoded.rows(),
            file.columns,
            file.rows
        )));
    }
    let frames = decoded.number_of_frames() as usize;
    let raw_options = ConvertOptions::new().with_modality_lut(ModalityLutOption::None);
    for (frame, out) in jobs {
        if frame >= frames {
            return Err(err(format!(
                "frame {frame} requested, the file decodes {frames} frames"
            )));
        }
        let raw: Vec<i64> = decoded
            .to_vec_frame_with_options(frame as u32, &raw_options)
            .map_err(|e| err(e.to_string()))?;
        if raw.len() != out.len() {
            return Err(err(format!(
                "frame {frame} decodes to {} samples, expected {}",
                raw.len(),
                out.len()
            )));
        }
        let rescale = file.frames[frame].rescale;
        for (o, &v) in out.iter_mut().zip(&raw) {
            *o = stored_to_hu.rescale(v, rescale);
        }
        on_plane();
    }
    Ok(())
}

/// Deflated Image Frame Compression: the `dicom` crate inflates each fragment without a bound,
/// so each is inflated here first, counting only, and one that holds more than a frame of
/// Rows x Columns x SamplesPerPixel x BitsAllocated is refused before it is decoded.
fn check_deflated_frames(obj: &InMemDicomObject, file: &ImageFile) -> Result<(), ImageError> {
    const DEFLATED_IMAGE_FRAME: &str = "1.2.840.10008.1.2.8.1";
    if file.transfer_syntax != DEFLATED_IMAGE_FRAME {
        return Ok(());
    }
    let path = file.path.as_path();
    let int = |tag, name| attr::int(obj, tag, name, path);
    let allocated = int(tags::BITS_ALLOCATED, "BitsAllocated (0028,0100)")?.unwrap_or(16);
    let samples = int(tags::SAMPLES_PER_PIXEL, "SamplesPerPixel (0028,0002)")?.unwrap_or(1);
    let frame_bytes = (file.rows * file.columns) as u64
        * samples.clamp(1, 4) as u64
        * (allocated.clamp(1, 64) as u64).div_ceil(8);
    let Some(fragments) = obj
        .get(tags::PIXEL_DATA)
        .and_then(|e| e.value().fragments())
    else {
        return Ok(());
    };
    for (i, fragment) in fragments.iter().enumerate() {
        let mut frame = flate2::read::DeflateDecoder::new(&fragment[..]).take(frame_bytes + 1);
        let inflated = std::io::copy(&mut frame, &mut std::io::sink())
            .map_err(|e| decode_err(path)(format!("fragment {i} does not inflate: {e}")))?;
        if inflated > frame_bytes {
            return Err(ImageError::BadValue {
                path: path.to_path_buf(),
                tag: "PixelData (7FE0,0010)",
                value: format!("fragment {i} inflating to more than {frame_bytes} bytes"),
                expected: format!(
                    "one frame of {} x {} x {} samples of {allocated} bits",
                    file.columns, file.rows, samples
                ),
            });
        }
    }
    Ok(())
}

/// Stored pixel value to HU: BitsStored masking and sign extension, MONOCHROME1 inversion
/// within the stored range (so that larger always means denser), then the frame's rescale.
struct StoredToHu {
    bits_stored: u32,
    signed: bool,
    monochrome1: bool,
}

impl StoredToHu {
    fn new(obj: &InMemDicomObject, file: &ImageFile) -> Result<StoredToHu, ImageError> {
        let path = file.path.as_path();
        let bits_stored =
            attr::int(obj, tags::BITS_STORED, "BitsStored (0028,0101)", path)?.unwrap_or(16);
        if !(1..=32).contains(&bits_stored) {
            return Err(ImageError::BadValue {
                path: path.to_path_buf(),
                tag: "BitsStored (0028,0101)",
                value: bits_stored.to_string(),
                expected: "1 to 32".into(),
            });
        }
        let representation = attr::int(
            obj,
            tags::PIXEL_REPRESENTATION,
            "PixelRepresentation (0028,0103)",
            path,
        )?;
        Ok(StoredToHu {
            bits_stored: bits_stored as u32,
            signed: representation == Some(1),
            monochrome1: file.photometric == "MONOCHROME1",
        })
    }

    /// A raw 16-bit container value to HU.
    #[inline]
    fn convert(&self, container: u16, r: Rescale) -> f32 {
        let bits = self.bits_stored.min(16);
        let v = if self.signed {
            let shift = 16 - bits;
            (((container << shift) as i16) >> shift) as i64
        } else {
            (container & (((1u32 << bits) - 1) as u16)) as i64
        };
        self.rescale(v, r)
    }

    /// A stored value (already sign-extended) to HU.
    #[inline]
    fn rescale(&self, v: i64, r: Rescale) -> f32 {
        let stored = if self.monochrome1 {
            let (lo, hi) = if self.signed {
                (
                    -(1i64 << (self.bits_stored - 1)),
                    (1i64 << (self.bits_stored - 1)) - 1,
                )
            } else {
                (0, (1i64 << self.bits_stored) - 1)
            };
            lo + hi - v
        } else {
            v
        };
        (stored as f64 * r.slope + r.intercept) as f32
    }
}

/// The raw PixelData bytes when they are native (not encapsulated) little-endian 16-bit
/// samples: the common CT case, converted without an intermediate decode.
fn native_16bit_pixels<'a>(
    obj: &'a InMemDicomObject,
    file: &ImageFile,
) -> Result<Option<std::borrow::Cow<'a, [u8]>>, ImageError> {
    const NATIVE_LE: [&str; 2] = ["1.2.840.10008.1.2", "1.2.840.10008.1.2.1"];
    if !NATIVE_LE.contains(&file.transfer_syntax.as_str()) {
        return Ok(None);
    }
    let allocated = attr::int(
        obj,
        tags::BITS_ALLOCATED,
        "BitsAllocated (0028,0100)",
        &file.path,
    )?;
    if allocated != Some(16) {
        return Ok(None);
    }
    let Some(elem) = obj.get(tags::PIXEL_DATA) else {
        return Ok(None);
    };
    match elem.value() {
        dicom_core::DicomValue::Primitive(_) => Ok(elem.to_bytes().ok()),
        _ => Ok(None),
    }
}
