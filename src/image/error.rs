//! Errors of image ingest: each names the file, the DICOM tag or NIfTI field, and what was
//! expected, so a user can fix the input without a debugger.

use std::path::PathBuf;

/// An input image could not be read as a volume.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: no such file or folder")]
    NotFound { path: PathBuf },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{path}: not a DICOM file (no 'DICM' marker at byte 128) and not a NIfTI file (.nii, .nii.gz)"
    )]
    NotDicom { path: PathBuf },
    #[error("{path}: cannot parse the DICOM file ({message}); is it truncated or corrupt?")]
    DicomParse { path: PathBuf, message: String },
    #[error(
        "{path}: file is {}, above the limit of {} (ingest.max_file_mib)",
        mib(*.size_mib),
        mib(*.max_mib)
    )]
    TooLarge {
        path: PathBuf,
        size_mib: f64,
        max_mib: f64,
    },
    #[error(
        "{path}: its deflated data set inflates to more than {} (ingest.max_file_mib)",
        mib(*.max_mib)
    )]
    InflatesTooLarge { path: PathBuf, max_mib: f64 },
    #[error(
        "{folder}: symlink loop at {}; expected a folder of files (remove the link)",
        link.file_name().map(|n| n.to_string_lossy()).unwrap_or_default()
    )]
    SymlinkLoop { folder: PathBuf, link: PathBuf },
    #[error("{path}: no DICOM image series found{}", skipped_note(.skipped))]
    NoImageSeries { path: PathBuf, skipped: usize },
    #[error(
        "{path}: a volume of {dims} voxels takes {}, above the limit of {} (ingest.max_volume_mib)",
        mib(*.size_mib),
        mib(*.max_mib)
    )]
    VolumeTooLarge {
        path: PathBuf,
        dims: String,
        size_mib: f64,
        max_mib: f64,
    },
    #[error(
        "{path}: the folder holds {count} image series; choose one with --series (in a cohort manifest: series), a UID or a hash prefix:\n{listing}"
    )]
    SeveralSeries {
        path: PathBuf,
        count: usize,
        listing: String,
    },
    #[error(
        "{path}: a NIfTI file holds one volume; --series {wanted:?} (or a cohort manifest's series) picks one of the series of a DICOM folder"
    )]
    SeriesOfNifti { path: PathBuf, wanted: String },
    #[error("{path}: no image series matches --series {wanted:?}; the series are:\n{listing}")]
    SeriesNotFound {
        path: PathBuf,
        wanted: String,
        listing: String,
    },
    #[error("{path}: missing {tag}; expected {expected}")]
    MissingTag {
        path: PathBuf,
        tag: &'static str,
        expected: &'static str,
    },
    #[error("{path}: {tag} is {value}; expected {expected}")]
    BadValue {
        path: PathBuf,
        tag: &'static str,
        value: String,
        expected: String,
    },
    #[error("mixed image sizes in one series: {first} is {first_dims}, {other} is {other_dims}")]
    MixedDims {
        first: PathBuf,
        first_dims: String,
        other: PathBuf,
        other_dims: String,
    },
    #[error(
        "mixed orientations in one series: ImageOrientationPatient of {first} is {first_iop}, of {other} is {other_iop}"
    )]
    MixedOrientation {
        first: PathBuf,
        first_iop: String,
        other: PathBuf,
        other_iop: String,
    },
    #[error(
        "two slices at the same position {position_mm:.3} mm along the slice normal: {first} and {other} (duplicate slice?)"
    )]
    DuplicatePosition {
        first: PathBuf,
        other: PathBuf,
        position_mm: f64,
    },
    #[error(
        "slice spacing is not uniform: a gap of {gap_mm:.3} mm between {before} (at {at_mm:.3} mm along the slice normal) and {after}, where the median gap is {median_mm:.3} mm ({hint})"
    )]
    NonUniformSpacing {
        before: PathBuf,
        after: PathBuf,
        at_mm: f64,
        gap_mm: f64,
        median_mm: f64,
        hint: &'static str,
    },
    #[error(
        "{path}: slice position is {offset_mm:.3} mm off the line through the other slices (ImagePositionPatient); the slices do not stack into one volume"
    )]
    NotStacked { path: PathBuf, offset_mm: f64 },
    #[error("{path}: cannot decode the pixel data ({message})")]
    Decode { path: PathBuf, message: String },
    #[error("{path}: {what} is not supported")]
    Unsupported { path: PathBuf, what: String },
    #[error("{path}: NIfTI field {field} is {value}; expected {expected}")]
    NiftiField {
        path: PathBuf,
        field: &'static str,
        value: String,
        expected: &'static str,
    },
    #[error("{path}: cannot read the NIfTI file ({message})")]
    Nifti { path: PathBuf, message: String },
}

/// A size given in MiB, for a message: whole MiB from 10 MiB, three decimals from 1 MiB, else
/// bytes (a limit below 1 MiB was shown as "0 MiB").
fn mib(size: f64) -> String {
    if size >= 10.0 {
        format!("{size:.0} MiB")
    } else if size >= 1.0 {
        format!("{size:.3} MiB")
    } else {
        format!("{:.0} bytes", size * 1048576.0)
    }
}

fn skipped_note(skipped: &usize) -> String {
    match skipped {
        0 => String::new(),
        n => format!(" ({n} files skipped: non-image objects, localizers or non-DICOM files)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file of 20 KiB over a limit of 4 KiB was "0 MiB above the limit of 0 MiB".
    #[test]
    fn sizes_below_a_mebibyte_are_given_in_bytes() {
        let e = ImageError::TooLarge {
            path: PathBuf::from("a.dcm"),
            size_mib: 20.0 / 1024.0,
            max_mib: 4.0 / 1024.0,
        };
        assert_eq!(
            e.to_string(),
            "a.dcm: file is 20480 bytes, above the limit of 4096 bytes (ingest.max_file_mib)"
        );
        let e = ImageError::VolumeTooLarge {
            path: PathBuf::from("b.nii"),
            dims: "9x9x9".into(),
            size_mib: 3000.4,
            max_mib: 2.5,
        };
        assert!(
            e.to_string()
                .ends_with("takes 3000 MiB, above the limit of 2.500 MiB (ingest.max_volume_mib)"),
            "{e}"
        );
    }
}
