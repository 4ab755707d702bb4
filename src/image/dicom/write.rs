//! Writing a [`Volume`] as a DICOM CT series (CT Image Storage, one file per slice, int16 with
//! rescale slope/intercept, explicit VR little endian). Used by the phantom generator and the
//! tests; file names are hashes so that they never follow slice order.

use std::path::{Path, PathBuf};

use dicom_core::value::PrimitiveValue;
use dicom_core::{DataElement, VR, dicom_value};
use dicom_dictionary_std::{tags, uids};
use dicom_object::{FileMetaTableBuilder, InMemDicomObject};
use rayon::prelude::*;

use super::Rescale;
use crate::image::ImageError;
use crate::image::Volume;
use crate::io_util::sha256_hex;

/// Identity of the written series. The patient fields are written as given (phantoms use fake
/// but plausible values so de-identification can be tested).
#[derive(Debug, Clone)]
pub struct SeriesIdentity {
    pub study_uid: String,
    pub series_uid: String,
    pub frame_of_reference_uid: String,
    pub patient_name: String,
    pub patient_id: String,
    pub patient_birth_date: String,
    pub series_description: String,
    /// "R" or "L", written as Laterality and ImageLaterality when set.
    pub laterality: Option<String>,
}

/// How each slice's stored int16 values map to HU.
#[derive(Debug, Clone)]
pub enum SliceRescale {
    /// One slope/intercept for every slice.
    Fixed(Rescale),
    /// One slope/intercept per slice, in k order.
    PerSlice(Vec<Rescale>),
}

/// A DICOM UID (root 2.25, UUID-derived form) made deterministically from `seed`.
pub fn uid_from(seed: &str) -> String {
    let hex = sha256_hex(seed.as_bytes());
    let n = u128::from_str_radix(&hex[..30], 16).unwrap_or(0);
    format!("2.25.{n}")
}

/// A decimal string (DS) of at most 16 characters.
pub fn format_ds(v: f64) -> String {
    for precision in (0..=10).rev() {
        let s = format!("{v:.precision$}");
        let s = if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        };
        let s = if s == "-0" { "0".to_string() } else { s };
        if s.len() <= 16 {
            return s;
        }
    }
    format!("{v:.6e}")
}

fn ds(values: &[f64]) -> PrimitiveValue {
    PrimitiveValue::Strs(values.iter().map(|v| format_ds(*v)).collect())
}

fn write_err(path: &Path, message: String) -> ImageError {
    ImageError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(message),
    }
}

/// Writes `volume` into `dir` as one file per slice and returns the file paths in k order.
pub fn write_series(
    dir: &Path,
    volume: &Volume,
    identity: &SeriesIdentity,
    rescale: &SliceRescale,
) -> Result<Vec<PathBuf>, ImageError> {
    std::fs::create_dir_all(dir).map_err(|source| ImageError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let [nx, ny, nz] = volume.dims;
    let d = volume.direction;
    let iop = [
        d[(0, 0)],
        d[(1, 0)],
        d[(2, 0)],
        d[(0, 1)],
        d[(1, 1)],
        d[(2, 1)],
    ];
    let paths: Vec<PathBuf> = (0..nz)
        .map(|k| {
            let name = &sha256_hex(format!("{}/{k}", identity.series_uid).as_bytes())[..16];
            dir.join(format!("{}.dcm", name.to_ascii_uppercase()))
        })
        .collect();
    (0..nz).into_par_iter().try_for_each(|k| {
        let r = match rescale {
            SliceRescale::Fixed(r) => *r,
            SliceRescale::PerSlice(v) => v.get(k).copied().unwrap_or(Rescale {
                slope: 1.0,
                intercept: 0.0,
            }),
        };
        let plane = &volume.data[k * nx * ny..(k + 1) * nx * ny];
        let mut bytes = Vec::with_capacity(plane.len() * 2);
        for &hu in plane {
            let stored = ((hu as f64 - r.intercept) / r.slope).round();
            let stored = stored.clamp(i16::MIN as f64, i16::MAX as f64) as i16;
            bytes.extend_from_slice(&stored.to_le_bytes());
        }
        let position = volume.index_to_world(nalgebra::Vector3::new(0.0, 0.0, k as f64));
        let sop_uid = uid_from(&format!("{}/sop/{k}", identity.series_uid));
        let mut elements = vec![
            DataElement::new(tags::SPECIFIC_CHARACTER_SET, VR::CS, "ISO_IR 100"),
            DataElement::new(
                tags::IMAGE_TYPE,
                VR::CS,
                dicom_value!(Strs, ["ORIGINAL", "PRIMARY", "AXIAL"]),
            ),
            DataElement::new(tags::SOP_CLASS_UID, VR::UI, uids::CT_IMAGE_STORAGE),
            DataElement::new(tags::SOP_INSTANCE_UID, VR::UI, sop_uid.as_str()),
            DataElement::new(tags::STUDY_DATE, VR::DA, "20260101"),
            // Type 2 attributes of the CT Image IOD: present, empty when unknown (dciodvfy)
            DataElement::new(tags::STUDY_TIME, VR::TM, "000000"),
            DataElement::new(tags::ACCESSION_NUMBER, VR::SH, ""),
            DataElement::new(tags::REFERRING_PHYSICIAN_NAME, VR::PN, ""),
            DataElement::new(tags::PATIENT_SEX, VR::CS, ""),
            DataElement::new(tags::KVP, VR::DS, ""),
            DataElement::new(tags::PATIENT_POSITION, VR::CS, ""),
            DataElement::new(tags::STUDY_ID, VR::SH, "1"),
            DataElement::new(tags::ACQUISITION_NUMBER, VR::IS, ""),
            DataElement::new(tags::POSITION_REFERENCE_INDICATOR, VR::LO, ""),
            DataElement::new(tags::MODALITY, VR::CS, "CT"),
            DataElement::new(tags::MANUFACTURER, VR::LO, "otoatlas phantom"),
            DataElement::new(
                tags::SERIES_DESCRIPTION,
                VR::LO,
                identity.series_description.as_str(),
            ),
            DataElement::new(tags::PATIENT_NAME, VR::PN, identity.patient_name.as_str()),
            DataElement::new(tags::PATIENT_ID, VR::LO, identity.patient_id.as_str()),
            DataElement::new(
                tags::PATIENT_BIRTH_DATE,
                VR::DA,
                identity.patient_birth_date.as_str(),
            ),
            DataElement::new(tags::SLICE_THICKNESS, VR::DS, ds(&[volume.spacing[2]])),
            DataElement::new(
                tags::STUDY_INSTANCE_UID,
                VR::UI,
                identity.study_uid.as_str(),
            ),
            DataElement::new(
                tags::SERIES_INSTANCE_UID,
                VR::UI,
                identity.series_uid.as_str(),
            ),
            DataElement::new(tags::SERIES_NUMBER, VR::IS, "1"),
            DataElement::new(tags::INSTANCE_NUMBER, VR::IS, format!("{}", k + 1)),
            DataElement::new(
                tags::IMAGE_POSITION_PATIENT,
                VR::DS,
                ds(&[position.x, position.y, position.z]),
            ),
            DataElement::new(tags::IMAGE_ORIENTATION_PATIENT, VR::DS, ds(&iop)),
            DataElement::new(
                tags::FRAME_OF_REFERENCE_UID,
                VR::UI,
                identity.frame_of_reference_uid.as_str(),
            ),
            DataElement::new(tags::SAMPLES_PER_PIXEL, VR::US, dicom_value!(U16, [1])),
            DataElement::new(tags::PHOTOMETRIC_INTERPRETATION, VR::CS, "MONOCHROME2"),
            DataElement::new(tags::ROWS, VR::US, dicom_value!(U16, [ny as u16])),
            DataElement::new(tags::COLUMNS, VR::US, dicom_value!(U16, [nx as u16])),
            DataElement::new(
                tags::PIXEL_SPACING,
                VR::DS,
                ds(&[volume.spacing[1], volume.spacing[0]]),
            ),
            DataElement::new(tags::BITS_ALLOCATED, VR::US, dicom_value!(U16, [16])),
            DataElement::new(tags::BITS_STORED, VR::US, dicom_value!(U16, [16])),
            DataElement::new(tags::HIGH_BIT, VR::US, dicom_value!(U16, [15])),
            DataElement::new(tags::PIXEL_REPRESENTATION, VR::US, dicom_value!(U16, [1])),
            DataElement::new(tags::RESCALE_INTERCEPT, VR::DS, ds(&[r.intercept])),
            DataElement::new(tags::RESCALE_SLOPE, VR::DS, ds(&[r.slope])),
            DataElement::new(tags::RESCALE_TYPE, VR::LO, "HU"),
            DataElement::new(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U8(bytes.into())),
        ];
        // Image Laterality only: Laterality (0020,0060) must be absent beside it (Type 2C)
        if let Some(side) = &identity.laterality {
            elements.push(DataElement::new(
                tags::IMAGE_LATERALITY,
                VR::CS,
                side.as_str(),
            ));
        }
        let obj = InMemDicomObject::from_element_iter(elements);
        let path = &paths[k];
        let file = obj
            .with_meta(FileMetaTableBuilder::new().transfer_syntax(uids::EXPLICIT_VR_LITTLE_ENDIAN))
            .map_err(|e| write_err(path, e.to_string()))?;
        file.write_to_file(path)
            .map_err(|e| write_err(path, e.to_string()))
    })?;
    Ok(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ds_values_fit_sixteen_characters() {
        for v in [
            0.1 + 0.2,
            -123456.789012345,
            1e-9,
            0.0,
            -0.0,
            98765432.123456,
        ] {
            let s = format_ds(v);
            assert!(s.len() <= 16, "{s}");
            let back: f64 = s.parse().unwrap();
            assert!((back - v).abs() <= 1e-6 * v.abs().max(1.0), "{v} -> {s}");
        }
    }

    #[test]
    fn uids_are_valid_and_deterministic() {
        let a = uid_from("x");
        assert_eq!(a, uid_from("x"));
        assert_ne!(a, uid_from("y"));
        assert!(a.len() <= 64 && a.chars().all(|c| c.is_ascii_digit() || c == '.'));
    }
}
