//! Writes a generated phantom as a case folder, in the layout `run` and `batch` read
//! (`pipeline::case`):
//!
//! ```text
//! case-001/
//!   dicom/                 CT Image Storage series, one file per slice (names not in slice
//!                          order), int16 with RescaleIntercept -1024, fake patient identity,
//!                          Laterality/ImageLaterality R or L
//!   image.nii.gz           the same voxels (int16 HU) with the same geometry
//!   landmarks.fcsv         the three landmarks with pick noise (Slicer markups, LPS)
//!   landmarks.mrk.json     the same (Slicer JSON markups)
//!   landmarks.json         the same (ours, with the side)
//!   segmentation/          the truth: malleus/incus/stapes/eardrum.ply (LPS mm) and
//!                          labels.nii.gz (1 malleus, 2 incus, 3 stapes, 4 eardrum)
//!   truth.json             everything the case was made with
//! ```
//!
//! The folder is assembled under a temporary sibling and renamed into place. Nothing in it
//! depends on the time or the machine: the same seed gives the same bytes.

use std::path::{Path, PathBuf};

use super::generator::{PhantomCase, PhantomError};
use crate::ear::{write_fcsv, write_json, write_mrk_json};
use crate::image::dicom::Rescale;
use crate::image::dicom::write::{SeriesIdentity, SliceRescale, uid_from, write_series};
use crate::image::nifti::write_nifti;
use crate::io_util::{io_err, sha256_hex, write_atomic, write_dir_atomic};
use crate::mesh::io::ply::{VertexAttributes, write_ply};

/// Stored value = HU + 1024 (the usual CT rescale), so air is stored near 0.
const RESCALE: Rescale = Rescale {
    slope: 1.0,
    intercept: -1024.0,
};

const FAMILY: [&str; 8] = [
    "MARTIN", "BERNARD", "DUBOIS", "SCHMIDT", "ROSSI", "NOVAK", "JENSEN", "GARCIA",
];
const GIVEN: [&str; 8] = [
    "ANNE", "LUC", "CLARA", "JONAS", "ELENA", "PIOTR", "INGRID", "MATEO",
];

/// A fake but plausible patient identity, derived from the seed (so de-identification can be
/// tested on it).
fn identity(case: &PhantomCase) -> SeriesIdentity {
    let seed = case.truth.seed;
    let h = sha256_hex(format!("otoatlas phantom identity {seed}").as_bytes());
    let byte = |k: usize| usize::from_str_radix(&h[2 * k..2 * k + 2], 16).unwrap_or(0);
    let year = 1940 + byte(2) % 60;
    let month = 1 + byte(3) % 12;
    let day = 1 + byte(4) % 28;
    let uid = |what: &str| uid_from(&format!("otoatlas phantom {seed} {what}"));
    SeriesIdentity {
        study_uid: uid("study"),
        series_uid: uid("series"),
        frame_of_reference_uid: uid("frame"),
        patient_name: format!("{}^{}", FAMILY[byte(0) % 8], GIVEN[byte(1) % 8]),
        patient_id: format!(
            "PH{:06}",
            u32::from_str_radix(&h[10..16], 16).unwrap_or(0) % 1_000_000
        ),
        patient_birth_date: format!("{year:04}{month:02}{day:02}"),
        series_description: format!("otoatlas phantom seed {seed} temporal bone CBCT"),
        laterality: Some(case.truth.side.dicom_code().to_string()),
    }
}

/// Writes `case` as the folder `dir` (replacing an older one) and returns its path.
pub fn write_case(dir: &Path, case: &PhantomCase) -> Result<PathBuf, PhantomError> {
    write_dir_atomic(dir, |tmp| write_parts(tmp, case))?;
    Ok(dir.to_path_buf())
}

fn write_parts(dir: &Path, case: &PhantomCase) -> Result<(), PhantomError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    // the voxels as the DICOM stores them: whole HU
    let mut image = case.image.clone();
    image.data.iter_mut().for_each(|v| *v = v.round());
    write_series(
        &dir.join("dicom"),
        &image,
        &identity(case),
        &SliceRescale::Fixed(RESCALE),
    )?;
    let hu: Vec<i16> = image
        .data
        .iter()
        .map(|v| v.clamp(i16::MIN as f32, i16::MAX as f32) as i16)
        .collect();
    write_nifti(&dir.join("image.nii.gz"), &image, &hu)?;
    let l = &case.picked;
    write_atomic(&dir.join("landmarks.fcsv"), write_fcsv(l).as_bytes())?;
    write_atomic(
        &dir.join("landmarks.mrk.json"),
        write_mrk_json(l).as_bytes(),
    )?;
    write_atomic(
        &dir.join("landmarks.json"),
        write_json(l, Some(case.truth.side)).as_bytes(),
    )?;
    let seg = dir.join("segmentation");
    std::fs::create_dir_all(&seg).map_err(io_err(&seg))?;
    for (name, mesh) in &case.surfaces {
        write_ply(
            &seg.join(format!("{name}.ply")),
            mesh,
            &VertexAttributes::default(),
        )?;
    }
    write_nifti(&seg.join("labels.nii.gz"), &image, &case.labels)?;
    let truth = serde_json::to_string_pretty(&case.truth).map_err(|e| {
        crate::io_util::io_err(&dir.join("truth.json"))(std::io::Error::other(e.to_string()))
    })?;
    Ok(write_atomic(
        &dir.join("truth.json"),
        format!("{truth}\n").as_bytes(),
    )?)
}
