//! Decoding pixel data into Hounsfield units: each file opened and decoded once (in parallel),
//! stored values taken raw and rescaled with that frame's own slope/intercept, MONOCHROME1
//! inverted within BitsStored so that larger always means denser.

use std::path::Path;

use dicom_dictionary_std::tags;
use dicom_object::OpenFileOptions;
use dicom_pixeldata::{ConvertOptions, ModalityLutOption, PixelDecoder};
use rayon::prelude::*;

use super::scan::{ImageFile, Rescale};
use crate::image::ImageError;

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
    let bits_stored = decoded.bits_stored().clamp(1, 32) as u32;
    let signed = matches!(
        decoded.pixel_representation(),
        dicom_pixeldata::PixelRepresentation::Signed
    );
    let monochrome1 = file.photometric == "MONOCHROME1";
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
        let Rescale { slope, intercept } = file.frames[frame].rescale;
        // MONOCHROME1: the minimum stored value is white; invert within the stored range
        let (lo, hi) = if signed {
            (
                -(1i64 << (bits_stored - 1)),
                (1i64 << (bits_stored - 1)) - 1,
            )
        } else {
            (0, (1i64 << bits_stored) - 1)
        };
        for (o, &v) in out.iter_mut().zip(&raw) {
            let stored = if monochrome1 { lo + hi - v } else { v };
            *o = (stored as f64 * slope + intercept) as f32;
        }
        on_plane();
    }
    Ok(())
}
