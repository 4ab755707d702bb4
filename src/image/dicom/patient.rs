//! The patient-identifying fields of a DICOM series (PatientName, PatientID,
//! PatientBirthDate, InstitutionName, AccessionNumber). Ingest never reads them; only
//! `run --keep-phi` does, to carry them into the package on the user's explicit request.

use std::path::Path;

use dicom_dictionary_std::tags;
use dicom_object::OpenFileOptions;
use serde::{Deserialize, Serialize};

use super::scan::{has_dicom_marker, list_files};
use super::tags as attr;
use crate::image::ImageError;
use crate::io_util::sha256_hex;

/// Who the images are of, as the first DICOM file of the series says (absent fields: None).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatientIdentity {
    pub patient_name: Option<String>,
    pub patient_id: Option<String>,
    pub patient_birth_date: Option<String>,
    pub institution_name: Option<String>,
    pub accession_number: Option<String>,
}

/// The identity in the first DICOM file (in path order) at `path`, a folder or a file, of the
/// series whose SeriesInstanceUID has the SHA-256 `series_uid_sha256` (`ImageInfo`'s: the
/// series ingest read, in a folder that may hold others, of other patients too); of any series
/// when `None`. `None` when there is no such file (a NIfTI image carries no identity).
pub fn read_patient_identity(
    path: &Path,
    series_uid_sha256: Option<&str>,
) -> Result<Option<PatientIdentity>, ImageError> {
    let files = if path.is_dir() {
        list_files(path)?
    } else {
        vec![path.to_path_buf()]
    };
    for file in files {
        if !has_dicom_marker(&file)? {
            continue;
        }
        let obj = OpenFileOptions::new()
            .read_until(tags::PIXEL_DATA)
            .open_file(&file)
            .map_err(|e| ImageError::DicomParse {
                path: file.clone(),
                message: e.to_string(),
            })?;
        let series = attr::string(&obj, tags::SERIES_INSTANCE_UID);
        let wanted = |digest: &str| series.is_some_and(|uid| sha256_hex(uid.as_bytes()) == digest);
        if !series_uid_sha256.is_none_or(wanted) {
            continue;
        }
        return Ok(Some(PatientIdentity {
            patient_name: attr::string(&obj, tags::PATIENT_NAME),
            patient_id: attr::string(&obj, tags::PATIENT_ID),
            patient_birth_date: attr::string(&obj, tags::PATIENT_BIRTH_DATE),
            institution_name: attr::string(&obj, tags::INSTITUTION_NAME),
            accession_number: attr::string(&obj, tags::ACCESSION_NUMBER),
        }));
    }
    Ok(None)
}
