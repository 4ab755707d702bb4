//! Ingest of DICOM series written by the tests themselves (with dicom-rs): geometry read back
//! exactly for shuffled, oblique, tilted and per-slice-rescaled series; and the bad-input
//! matrix, each case a clear error with exit code 2 and never a panic.

use std::fs;
use std::path::{Path, PathBuf};

use crate::common;
use crate::common::{assert_close, otoatlas, otoatlas_json};
use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use nalgebra::{Matrix3, Rotation3, Vector3};
use otoatlas::config::Config;
use otoatlas::image::dicom::Rescale;
use otoatlas::image::dicom::write::{SeriesIdentity, SliceRescale, uid_from, write_series};
use otoatlas::image::{self, ImageError, Volume};

fn identity(seed: &str) -> SeriesIdentity {
    SeriesIdentity {
        study_uid: uid_from(&format!("{seed}/study")),
        series_uid: uid_from(&format!("{seed}/series")),
        frame_of_reference_uid: uid_from(&format!("{seed}/for")),
        patient_name: "DOE^JANE".into(),
        patient_id: "PHANTOM-0001".into(),
        patient_birth_date: "19700101".into(),
        series_description: format!("test {seed}"),
        laterality: Some("R".into()),
    }
}

/// A volume whose value encodes its voxel index: v = i + 10 j + 100 k - 1000 (integers).
fn pattern(dims: [usize; 3], spacing: [f64; 3], direction: Matrix3<f64>) -> Volume {
    let mut data = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                data.push((i + 10 * j + 100 * k) as f32 - 1000.0);
            }
        }
    }
    Volume {
        dims,
        spacing,
        origin: Vector3::new(-12.5, 30.25, 101.0),
        direction,
        data,
    }
}

const FIXED: SliceRescale = SliceRescale::Fixed(Rescale {
    slope: 1.0,
    intercept: -1024.0,
});

fn read(path: &Path) -> Result<image::LoadedImage, ImageError> {
    image::load(path, None, &Config::default_config().unwrap().ingest)
}

fn assert_same_geometry(a: &Volume, b: &Volume) {
    assert_eq!(a.dims, b.dims);
    assert_close(&a.spacing, &b.spacing, 1e-6, "spacing");
    assert_close(a.origin.as_slice(), b.origin.as_slice(), 1e-5, "origin");
    assert_close(
        &a.direction_row_major(),
        &b.direction_row_major(),
        1e-6,
        "direction",
    );
}

#[test]
fn oblique_series_with_shuffled_names_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let rot = *Rotation3::from_euler_angles(0.4, -0.3, 1.1).matrix();
    let vol = pattern([7, 5, 6], [0.25, 0.3, 0.2], rot);
    let paths = write_series(dir.path(), &vol, &identity("oblique"), &FIXED).unwrap();
    let mut names: Vec<_> = paths
        .iter()
        .map(|p| p.file_name().unwrap().to_owned())
        .collect();
    let in_k_order = names.clone();
    names.sort();
    assert_ne!(names, in_k_order, "file names must not follow slice order");
    let back = read(dir.path()).unwrap();
    assert_same_geometry(&back.volume, &vol);
    assert_eq!(back.volume.data, vol.data);
    assert_eq!(back.info.laterality.as_deref(), Some("R"));
    // the CLI agrees and never prints a patient field or the raw UID
    let (code, json) = otoatlas_json(&["inspect", dir.path().to_str().unwrap()]);
    assert_eq!(code, 0);
    assert_eq!(json["dims"], serde_json::json!([7, 5, 6]));
    let text = json.to_string();
    for secret in [
        "DOE",
        "PHANTOM-0001",
        "19700101",
        &identity("oblique").series_uid,
    ] {
        assert!(!text.contains(secret), "{secret} leaked: {text}");
    }
    assert_eq!(
        json["series_uid_sha256"].as_str().unwrap(),
        otoatlas::io_util::sha256_hex(identity("oblique").series_uid.as_bytes())
    );
}

#[test]
fn gantry_tilt_gives_a_sheared_direction_matrix() {
    let dir = tempfile::tempdir().unwrap();
    // slices stacked 15 degrees off their normal (tilt about the x axis)
    let tilt = 15f64.to_radians();
    let d = Matrix3::from_columns(&[
        Vector3::x(),
        Vector3::y(),
        Vector3::new(0.0, tilt.sin(), tilt.cos()),
    ]);
    let vol = pattern([4, 4, 5], [0.5, 0.5, 0.75], d);
    write_series(dir.path(), &vol, &identity("tilt"), &FIXED).unwrap();
    let back = read(dir.path()).unwrap();
    assert_same_geometry(&back.volume, &vol);
    assert!(back.info.warnings.iter().any(|w| w.contains("gantry tilt")));
}

#[test]
fn per_slice_rescale_is_applied_slice_by_slice() {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([6, 4, 5], [0.2, 0.2, 0.2], Matrix3::identity());
    let per_slice: Vec<Rescale> = (0..5)
        .map(|k| Rescale {
            slope: 0.5 * (1 + k % 3) as f64,
            intercept: -1024.0 + 13.0 * k as f64,
        })
        .collect();
    write_series(
        dir.path(),
        &vol,
        &identity("rescale"),
        &SliceRescale::PerSlice(per_slice.clone()),
    )
    .unwrap();
    let back = read(dir.path()).unwrap();
    for (k, r) in per_slice.iter().enumerate() {
        let n = 24;
        for (a, b) in back.volume.data[k * n..(k + 1) * n]
            .iter()
            .zip(&vol.data[k * n..(k + 1) * n])
        {
            assert!(
                (a - b).abs() as f64 <= r.slope / 2.0 + 1e-6,
                "slice {k}: {a} vs {b}"
            );
        }
    }
}

/// Rewrites one file with `edit` applied to its dataset.
fn edit_file(path: &Path, edit: impl FnOnce(&mut dicom_object::DefaultDicomObject)) {
    let mut obj = dicom_object::open_file(path).unwrap();
    edit(&mut obj);
    obj.write_to_file(path).unwrap();
}

#[test]
fn monochrome1_is_inverted_to_hounsfield() {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([4, 3, 2], [0.3, 0.3, 0.3], Matrix3::identity());
    let paths = write_series(dir.path(), &vol, &identity("mono1"), &FIXED).unwrap();
    for p in &paths {
        edit_file(p, |obj| {
            obj.put(DataElement::new(
                tags::PHOTOMETRIC_INTERPRETATION,
                VR::CS,
                "MONOCHROME1",
            ));
            let bytes = obj
                .element(tags::PIXEL_DATA)
                .unwrap()
                .to_bytes()
                .unwrap()
                .into_owned();
            // MONOCHROME1 stores (lo + hi) - v for signed 16-bit: -1 - v
            let inverted: Vec<u8> = bytes
                .chunks(2)
                .flat_map(|c| (-1 - i16::from_le_bytes([c[0], c[1]])).to_le_bytes())
                .collect();
            obj.put(DataElement::new(
                tags::PIXEL_DATA,
                VR::OW,
                PrimitiveValue::U8(inverted.into()),
            ));
        });
    }
    assert_eq!(read(dir.path()).unwrap().volume.data, vol.data);
}

fn series_dir(seed: &str) -> (tempfile::TempDir, Vec<PathBuf>) {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([4, 4, 6], [0.25, 0.25, 0.5], Matrix3::identity());
    let paths = write_series(dir.path(), &vol, &identity(seed), &FIXED).unwrap();
    (dir, paths)
}

/// Runs `inspect` on `path` and checks exit code 2, no panic, and a message containing `needle`.
fn assert_bad_input(path: &Path, needle: &str) {
    let out = otoatlas(&["inspect", path.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains(needle), "expected {needle:?} in: {stderr}");
}

#[test]
fn removed_slice_is_a_missing_slice_error_naming_the_neighbours() {
    let (dir, paths) = series_dir("gap");
    fs::remove_file(&paths[3]).unwrap();
    let err = read(dir.path()).unwrap_err();
    assert!(matches!(err, ImageError::NonUniformSpacing { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains(&paths[2].file_name().unwrap().to_string_lossy().to_string()),
        "{msg}"
    );
    assert!(
        msg.contains(&paths[4].file_name().unwrap().to_string_lossy().to_string()),
        "{msg}"
    );
    assert_bad_input(dir.path(), "missing slice");
}

#[test]
fn duplicate_position_is_an_error() {
    let (dir, paths) = series_dir("dup");
    let copy = dir.path().join("copy.dcm");
    fs::copy(&paths[2], &copy).unwrap();
    edit_file(&copy, |obj| {
        obj.put(DataElement::new(
            tags::SOP_INSTANCE_UID,
            VR::UI,
            uid_from("another"),
        ));
    });
    assert!(matches!(
        read(dir.path()).unwrap_err(),
        ImageError::DuplicatePosition { .. }
    ));
    assert_bad_input(dir.path(), "same position");
}

#[test]
fn mixed_orientation_and_mixed_dims_are_errors() {
    let (dir, paths) = series_dir("mixed-o");
    edit_file(&paths[1], |obj| {
        obj.put(DataElement::new(
            tags::IMAGE_ORIENTATION_PATIENT,
            VR::DS,
            PrimitiveValue::Strs(
                ["0", "1", "0", "1", "0", "0"]
                    .map(String::from)
                    .into_iter()
                    .collect(),
            ),
        ));
    });
    assert_bad_input(dir.path(), "mixed orientations");

    let (dir, paths) = series_dir("mixed-d");
    edit_file(&paths[1], |obj| {
        obj.put(DataElement::new(
            tags::COLUMNS,
            VR::US,
            PrimitiveValue::from(2u16),
        ));
    });
    assert_bad_input(dir.path(), "mixed image sizes");
}

#[test]
fn two_series_in_one_folder_need_a_choice() {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([4, 4, 3], [0.25, 0.25, 0.5], Matrix3::identity());
    write_series(&dir.path().join("a"), &vol, &identity("first"), &FIXED).unwrap();
    write_series(&dir.path().join("b"), &vol, &identity("second"), &FIXED).unwrap();
    assert_bad_input(dir.path(), "2 image series");
    let uid = identity("second").series_uid;
    let (code, json) = otoatlas_json(&["inspect", dir.path().to_str().unwrap(), "--series", &uid]);
    assert_eq!(code, 0);
    assert_eq!(json["slices"], 3);
    let prefix = &otoatlas::io_util::sha256_hex(uid.as_bytes())[..10];
    let (code, json2) =
        otoatlas_json(&["inspect", dir.path().to_str().unwrap(), "--series", prefix]);
    assert_eq!(code, 0);
    assert_eq!(json2["series_uid_sha256"], json["series_uid_sha256"]);
}

/// A scout beside the volume, as scanner exports put it: one slice in a series of its own,
/// ImageType ORIGINAL\PRIMARY\LOCALIZER. It made the folder "2 image series" and asked for a
/// choice; it is skipped with a note, and the volume is read as if alone. The same slice
/// marked AXIAL is a second series and still needs a choice.
#[test]
fn a_localizer_beside_the_series_is_skipped_with_a_note() {
    let (dir, _) = series_dir("volume");
    let scout = pattern([4, 4, 1], [0.5, 0.5, 1.0], Matrix3::identity());
    let scouts = write_series(
        &dir.path().join("scout"),
        &scout,
        &identity("scout"),
        &FIXED,
    )
    .unwrap();
    let mark = |types: [&str; 3]| {
        edit_file(&scouts[0], |obj| {
            obj.put(DataElement::new(
                tags::IMAGE_TYPE,
                VR::CS,
                PrimitiveValue::Strs(types.map(String::from).to_vec().into()),
            ));
        })
    };
    mark(["ORIGINAL", "PRIMARY", "LOCALIZER"]);
    let back = read(dir.path()).unwrap();
    assert_eq!(back.volume.dims, [4, 4, 6]);
    assert_eq!(back.info.notes.len(), 1, "{:?}", back.info.notes);
    assert!(
        back.info.notes[0].contains("localizer"),
        "{:?}",
        back.info.notes
    );
    mark(["ORIGINAL", "PRIMARY", "AXIAL"]);
    assert_bad_input(dir.path(), "2 image series");
}

#[test]
fn truncated_file_is_named() {
    let (dir, paths) = series_dir("trunc");
    let bytes = fs::read(&paths[2]).unwrap();
    // cut inside the pixel data
    fs::write(&paths[2], &bytes[..bytes.len() - 10]).unwrap();
    let name = paths[2].file_name().unwrap().to_string_lossy().to_string();
    assert_bad_input(dir.path(), &name);
    // cut inside the header
    fs::write(&paths[2], &bytes[..300]).unwrap();
    assert_bad_input(dir.path(), &name);
}

#[test]
fn non_dicom_and_empty_inputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    assert_bad_input(dir.path(), "no DICOM image series found");
    let txt = dir.path().join("notes.txt");
    fs::write(&txt, "not an image").unwrap();
    assert_bad_input(
        dir.path(),
        "no DICOM image series found (1 files skipped: non-image objects, localizers or non-DICOM files)",
    );
    assert_bad_input(&txt, "not a DICOM file");
    assert_bad_input(&dir.path().join("absent"), "no such file or folder");
    let nii = dir.path().join("broken.nii");
    fs::write(&nii, vec![0u8; 100]).unwrap();
    assert_bad_input(&nii, "sizeof_hdr");
}

#[test]
fn a_stray_file_beside_a_series_is_skipped_with_a_note() {
    let (dir, _) = series_dir("stray");
    fs::write(dir.path().join("README"), "export notes").unwrap();
    let back = read(dir.path()).unwrap();
    assert_eq!(back.volume.dims, [4, 4, 6]);
    assert_eq!(back.info.notes.len(), 1);
}

#[test]
fn bad_config_is_exit_code_two_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("bad.toml");
    fs::write(
        &cfg,
        otoatlas::config::DEFAULT_TOML.replace("[ingest]", "[ingest]\nmax_file_gib = 3"),
    )
    .unwrap();
    let out = otoatlas(&["inspect", ".", "--config", cfg.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr.contains("max_file_gib") && stderr.contains("bad.toml"),
        "{stderr}"
    );
}

#[test]
fn nifti_writer_round_trips_oblique_geometry_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let rot = *Rotation3::from_euler_angles(-0.3, 0.2, 2.0).matrix();
    let vol = pattern([6, 5, 4], [0.125, 0.25, 0.3], rot);
    let values: Vec<i16> = vol.data.iter().map(|v| *v as i16).collect();
    for name in ["v.nii", "v.nii.gz"] {
        let path = dir.path().join(name);
        otoatlas::image::nifti::write_nifti(&path, &vol, &values).unwrap();
        let back = read(&path).unwrap();
        assert_same_geometry(&back.volume, &vol);
        assert_eq!(back.volume.data, vol.data);
    }
    // byte-identical on a second write (no timestamp in the gzip stream)
    let again = dir.path().join("again.nii.gz");
    otoatlas::image::nifti::write_nifti(&again, &vol, &values).unwrap();
    assert_eq!(
        fs::read(&again).unwrap(),
        fs::read(dir.path().join("v.nii.gz")).unwrap()
    );
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        3,
        "no temporary left behind"
    );
}

#[test]
fn pydicom_and_nibabel_read_what_we_write() {
    let dir = tempfile::tempdir().unwrap();
    let rot = *Rotation3::from_euler_angles(0.7, -0.4, 0.25).matrix();
    let vol = pattern([9, 7, 5], [0.2, 0.15, 0.3], rot);
    write_series(
        &dir.path().join("dicom"),
        &vol,
        &identity("independent"),
        &FIXED,
    )
    .unwrap();
    let values: Vec<i16> = vol.data.iter().map(|v| *v as i16).collect();
    let nii = dir.path().join("image.nii.gz");
    otoatlas::image::nifti::write_nifti(&nii, &vol, &values).unwrap();
    let probes: Vec<[f64; 4]> = [(0, 0, 0), (8, 6, 4), (3, 2, 1)]
        .iter()
        .map(|&(i, j, k)| {
            [
                i as f64,
                j as f64,
                k as f64,
                vol.data[vol.index(i, j, k)] as f64,
            ]
        })
        .collect();
    let expected = serde_json::json!({
        "dims": vol.dims,
        "spacing": vol.spacing,
        "origin": vol.origin.as_slice(),
        "direction": vol.direction_row_major(),
        "sum": vol.data.iter().map(|v| *v as f64).sum::<f64>(),
        "probes": probes,
    });
    let exp = dir.path().join("expected.json");
    fs::write(&exp, expected.to_string()).unwrap();
    common::python::run_python(
        "check_volume.py",
        &[
            exp.to_str().unwrap(),
            dir.path().join("dicom").to_str().unwrap(),
            nii.to_str().unwrap(),
        ],
        &["pydicom", "nibabel", "numpy"],
    );
}

#[test]
fn a_frame_count_beyond_the_file_is_refused_before_anything_is_sized_by_it() {
    let (dir, paths) = series_dir("frames");
    // a billion frames in a 1 KB slice: the earlier reader allocated 128 GB and aborted
    edit_file(&paths[1], |obj| {
        obj.put(DataElement::new(
            tags::NUMBER_OF_FRAMES,
            VR::IS,
            "1000000000",
        ));
    });
    assert_bad_input(dir.path(), "NumberOfFrames (0028,0008) is 1000000000");
}

/// `otoatlas inspect DIR` within a 1 GiB address space (`prlimit`): asserts exit code 2 and
/// returns stderr.
fn inspect_refused_within_1_gib(dir: &Path) -> String {
    let out = std::process::Command::new("prlimit")
        .arg(format!("--as={}", 1u64 << 30))
        .arg(env!("CARGO_BIN_EXE_otoatlas"))
        .args(["inspect", dir.to_str().unwrap()])
        .output()
        .expect("prlimit (util-linux)");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    stderr
}

/// Three slices whose transfer syntax says explicit VR big endian over a little-endian body:
/// every element length reads as gigabytes. The `dicom` crate reserved about 4 GB per file
/// (7.5 GB for the three, scanned in parallel) before failing; now the lengths are checked
/// against the file first, and the folder is refused within a 1 GiB address space.
#[test]
fn a_transfer_syntax_lying_about_byte_order_is_refused_before_any_allocation() {
    let (dir, paths) = series_dir("byteorder");
    for path in &paths[..3] {
        let mut bytes = fs::read(path).unwrap();
        let little = b"1.2.840.10008.1.2.1\0";
        let at = bytes
            .windows(little.len())
            .position(|w| w == little)
            .expect("an explicit VR little endian slice");
        bytes[at..at + little.len()].copy_from_slice(b"1.2.840.10008.1.2.2\0");
        fs::write(path, bytes).unwrap();
    }
    let stderr = inspect_refused_within_1_gib(dir.path());
    assert!(
        stderr.contains("element length") && stderr.contains("is its transfer syntax right?"),
        "{stderr}"
    );
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
}

/// Rewrites the series in Deflated Explicit VR Little Endian (the data set after the file meta
/// group is one raw deflate stream).
fn deflate_series(paths: &[PathBuf]) {
    for p in paths {
        edit_file(p, |obj| {
            obj.meta_mut().set_transfer_syntax(
                &dicom_transfer_syntax_registry::entries::DEFLATED_EXPLICIT_VR_LITTLE_ENDIAN,
            );
        });
        let bytes = fs::read(p).unwrap();
        assert!(
            bytes.windows(22).any(|w| w == b"1.2.840.10008.1.2.1.99"),
            "{} was not written deflated",
            p.display()
        );
    }
}

/// Where a file's data set starts: after the meta group, whose length (0002,0000) is the first
/// element after the preamble.
fn data_set_start(bytes: &[u8]) -> usize {
    assert_eq!(&bytes[128..132], b"DICM");
    assert_eq!(&bytes[132..136], &[2, 0, 0, 0], "(0002,0000) first");
    144 + u32::from_le_bytes(bytes[140..144].try_into().unwrap()) as usize
}

/// Inflates the deflated data set of `path`, appends `extra` (explicit VR little endian
/// elements) and deflates it again.
fn append_to_deflated(path: &Path, extra: &[u8]) {
    use std::io::{Read, Write};
    let bytes = fs::read(path).unwrap();
    let start = data_set_start(&bytes);
    let mut body = Vec::new();
    flate2::read::DeflateDecoder::new(&bytes[start..])
        .read_to_end(&mut body)
        .unwrap();
    body.extend_from_slice(extra);
    let mut out = bytes[..start].to_vec();
    let mut encoder = flate2::write::DeflateEncoder::new(&mut out, flate2::Compression::fast());
    encoder.write_all(&body).unwrap();
    encoder.finish().unwrap();
    fs::write(path, out).unwrap();
}

/// The header of a private OB element (7FE1,1010), after the pixel data, claiming `len` bytes.
fn private_ob_header(len: u32) -> Vec<u8> {
    let mut header = vec![0xE1, 0x7F, 0x10, 0x10, b'O', b'B', 0, 0];
    header.extend_from_slice(&len.to_le_bytes());
    header
}

#[test]
fn a_deflated_series_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([5, 4, 3], [0.2, 0.25, 0.3], Matrix3::identity());
    let paths = write_series(dir.path(), &vol, &identity("deflated"), &FIXED).unwrap();
    deflate_series(&paths);
    let loaded = read(dir.path()).unwrap();
    assert_eq!(loaded.info.transfer_syntax, "1.2.840.10008.1.2.1.99");
    assert_same_geometry(&loaded.volume, &vol);
    assert_eq!(loaded.volume.data, vol.data);
}

/// A deflated data set is inflated under `ingest.max_file_mib`: a slice whose 64 KB of deflate
/// inflate to 64 MiB is refused under a cap of 8 MiB (the `dicom` crate inflated whatever the
/// stream held, so a small file could take any amount of memory).
#[test]
fn a_deflate_bomb_is_refused_at_the_file_cap() {
    let (dir, paths) = series_dir("deflate-bomb");
    deflate_series(&paths);
    let size = 64u32 << 20;
    let mut extra = private_ob_header(size);
    extra.resize(extra.len() + size as usize, 0);
    append_to_deflated(&paths[2], &extra);
    assert!(fs::metadata(&paths[2]).unwrap().len() < 1 << 20);
    let mut cfg = Config::default_config().unwrap().ingest;
    cfg.max_file_mib = 8.0;
    let err = image::load(dir.path(), None, &cfg).unwrap_err();
    assert!(matches!(err, ImageError::InflatesTooLarge { .. }), "{err}");
    let message = err.to_string();
    assert!(
        message.contains("inflates to more than 8.000 MiB (ingest.max_file_mib)")
            && message.contains(paths[2].file_name().unwrap().to_str().unwrap()),
        "{message}"
    );
    // within the default cap the same slice reads, its extra element ignored
    let loaded = read(dir.path()).unwrap();
    assert_eq!(loaded.volume.dims, [4, 4, 6]);
}

/// An element inside a deflated data set claiming 3 GiB of the few bytes left: refused from
/// the inflated bytes within a 1 GiB address space, as for a file that is not deflated.
#[test]
fn a_length_lying_inside_a_deflated_data_set_is_refused_before_any_allocation() {
    let (dir, paths) = series_dir("deflate-lie");
    deflate_series(&paths);
    let mut extra = private_ob_header(3 << 30);
    extra.extend_from_slice(&[0; 16]);
    append_to_deflated(&paths[1], &extra);
    let stderr = inspect_refused_within_1_gib(dir.path());
    assert!(
        stderr.contains("element length is 3221225472 bytes"),
        "{stderr}"
    );
}

/// Rewrites a slice in Deflated Image Frame Compression, its pixel data one fragment: the
/// frame's bytes deflated, followed by `padding` zero bytes inside the same stream.
fn deflate_frame(path: &Path, padding: usize) {
    use std::io::Write;
    edit_file(path, |obj| {
        let mut frame = obj
            .element(tags::PIXEL_DATA)
            .unwrap()
            .to_bytes()
            .unwrap()
            .into_owned();
        frame.resize(frame.len() + padding, 0);
        let mut encoder =
            flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::fast());
        encoder.write_all(&frame).unwrap();
        let mut fragment = encoder.finish().unwrap();
        fragment.resize(fragment.len().next_multiple_of(2), 0);
        obj.meta_mut().set_transfer_syntax(
            &dicom_transfer_syntax_registry::entries::DEFLATED_IMAGE_FRAME_COMPRESSION,
        );
        obj.put(DataElement::new(
            tags::PIXEL_DATA,
            VR::OB,
            dicom_core::value::PixelFragmentSequence::new(vec![], vec![fragment]),
        ));
    });
}

#[test]
fn deflated_image_frames_read_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([5, 4, 3], [0.2, 0.25, 0.3], Matrix3::identity());
    let paths = write_series(dir.path(), &vol, &identity("deflated-frames"), &FIXED).unwrap();
    for p in &paths {
        deflate_frame(p, 0);
    }
    let loaded = read(dir.path()).unwrap();
    assert_eq!(loaded.info.transfer_syntax, "1.2.840.10008.1.2.8.1");
    assert_eq!(loaded.volume.data, vol.data);
}

/// A deflated frame of 4 x 4 pixels whose fragment inflates to 64 MiB is refused before it is
/// decoded (the `dicom` crate inflates a fragment whatever it holds).
#[test]
fn a_deflated_frame_holding_more_than_a_frame_is_refused() {
    let (dir, paths) = series_dir("deflated-frame-bomb");
    for (k, p) in paths.iter().enumerate() {
        deflate_frame(p, if k == 3 { 64 << 20 } else { 0 });
    }
    assert_bad_input(
        dir.path(),
        "PixelData (7FE0,0010) is fragment 0 inflating to more than 32 bytes; expected one frame of 4 x 4 x 1 samples of 16 bits",
    );
}

/// A symlink loop in a DICOM folder was followed by the input hashing at the end of a run
/// (exit 1, after minutes of work, with the loop expanded 40 levels in the message); now ingest
/// refuses it first, naming the folder and the link (exit 2).
#[test]
fn a_symlink_loop_in_a_dicom_folder_is_bad_input_named_once() {
    for (a, b) in [("loop1", "loop2"), ("self", ".")] {
        let (dir, _) = series_dir("links");
        std::os::unix::fs::symlink(b, dir.path().join(a)).unwrap();
        if b != "." {
            std::os::unix::fs::symlink(a, dir.path().join(b)).unwrap();
        }
        let out = otoatlas(&["--quiet", "inspect", dir.path().to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        let named = format!("{}: symlink loop at ", dir.path().display());
        assert!(stderr.contains(&named), "{stderr}");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
        assert!(!stderr.contains(&format!("{a}/{a}")), "{stderr}");
    }
}

/// Byte patches of a file: (offset, bytes written there).
type Patches = Vec<(usize, Vec<u8>)>;

/// Writes a small valid NIfTI-1 file and applies `patches` to it.
fn patched_nifti(dir: &Path, name: &str, patches: &[(usize, Vec<u8>)]) -> PathBuf {
    let vol = pattern([6, 5, 4], [0.25, 0.25, 0.25], Matrix3::identity());
    let values: Vec<i16> = vol.data.iter().map(|v| *v as i16).collect();
    let path = dir.join(name);
    otoatlas::image::nifti::write_nifti(&path, &vol, &values).unwrap();
    let mut bytes = fs::read(&path).unwrap();
    for (offset, patch) in patches {
        bytes[*offset..*offset + patch.len()].copy_from_slice(patch);
    }
    fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn nifti_headers_that_lie_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // NIfTI-1 header offsets: dim 40, datatype 70, bitpix 72, scl_slope 112, scl_inter 116,
    // sform_code 254, srow_x 280
    let cases: [(&str, Patches, &str); 5] = [
        // the nifti crate panicked on these two
        (
            "bitpix.nii",
            vec![(72, 8i16.to_le_bytes().to_vec())],
            "bitpix",
        ),
        (
            "complex.nii",
            vec![(70, 32i16.to_le_bytes().to_vec())],
            "datatype",
        ),
        (
            "nan_inter.nii",
            vec![
                (112, 1f32.to_le_bytes().to_vec()),
                (116, f32::NAN.to_le_bytes().to_vec()),
            ],
            "scl_inter",
        ),
        (
            "nan_origin.nii",
            vec![
                (254, 1i16.to_le_bytes().to_vec()),
                (292, f32::NAN.to_le_bytes().to_vec()),
            ],
            "affine",
        ),
        // 30000^3 voxels claimed: refused by the memory budget before any voxel is read
        (
            "huge.nii",
            vec![
                (42, 30000i16.to_le_bytes().to_vec()),
                (44, 30000i16.to_le_bytes().to_vec()),
                (46, 30000i16.to_le_bytes().to_vec()),
            ],
            "ingest.max_volume_mib",
        ),
    ];
    for (name, patches, needle) in cases {
        let path = patched_nifti(d, name, &patches);
        assert_bad_input(&path, needle);
        // one line (the affine was printed as a matrix over five)
        let out = otoatlas(&["--quiet", "inspect", path.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    }
}

/// A .nii.gz whose header claims a small volume but whose stream inflates to 3 GB: only the
/// bytes the header claims are inflated, so the file reads within a 1 GB address space (the
/// earlier reader inflated up to `max_file_mib`, 4 GB, before looking at the header).
#[test]
fn a_gzip_bomb_is_inflated_only_as_far_as_its_header_claims() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let plain = patched_nifti(dir.path(), "small.nii", &[]);
    let bomb = dir.path().join("bomb.nii.gz");
    let mut gz = flate2::write::GzEncoder::new(
        fs::File::create(&bomb).unwrap(),
        flate2::Compression::fast(),
    );
    gz.write_all(&fs::read(&plain).unwrap()).unwrap();
    let zeros = vec![0u8; 1 << 20];
    for _ in 0..3072 {
        gz.write_all(&zeros).unwrap();
    }
    gz.finish().unwrap();
    let exe = env!("CARGO_BIN_EXE_otoatlas");
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 1048576 && exec '{exe}' inspect '{}' --json",
            bomb.display()
        ))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(info["dims"], serde_json::json!([6, 5, 4]), "{info}");
}

/// nibabel writes a big-endian NIfTI-1 with scaling, an .hdr/.img pair and a gzipped NIfTI-2;
/// otoatlas reads each as nibabel does (geometry in LPS, every value).
#[test]
fn nifti_variants_written_by_nibabel_read_as_nibabel_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let Some(stdout) = common::python::run_python(
        "write_nifti_variants.py",
        &[dir.path()],
        &["nibabel", "numpy"],
    ) else {
        return;
    };
    let report: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let report = report.as_object().unwrap();
    assert_eq!(report.len(), 3);
    for (name, want) in report {
        let img = read(&dir.path().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let v = &img.volume;
        let dims: Vec<usize> = serde_json::from_value(want["dims"].clone()).unwrap();
        assert_eq!(v.dims.to_vec(), dims, "{name}");
        let affine: Vec<Vec<f64>> = serde_json::from_value(want["affine_ras"].clone()).unwrap();
        let m = v.index_to_world_matrix();
        let flip = [-1.0, -1.0, 1.0];
        for r in 0..3 {
            let row: Vec<f64> = (0..3).map(|c| m[(r, c)]).collect();
            let expected: Vec<f64> = (0..3).map(|c| flip[r] * affine[r][c]).collect();
            assert_close(&row, &expected, 1e-6, name);
            assert_close(&[v.origin[r]], &[flip[r] * affine[r][3]], 1e-6, name);
        }
        let sum: f64 = v.data.iter().map(|x| *x as f64).sum();
        assert_close(&[sum], &[want["sum"].as_f64().unwrap()], 1e-6, name);
        for probe in want["voxels"].as_array().unwrap() {
            let p: [f64; 4] = serde_json::from_value(probe.clone()).unwrap();
            let value = v.data[v.index(p[0] as usize, p[1] as usize, p[2] as usize)] as f64;
            assert_close(&[value], &[p[3]], 1e-6, name);
        }
    }
}

/// A patient's name planted in every free-text field of two series in one folder (the
/// several-series error listed each SeriesDescription, and one held the patient's name):
/// nothing of it reaches `inspect`'s error, listing, output or JSON.
#[test]
fn free_text_of_the_dicom_never_reaches_a_message_or_output() {
    const NAME: &str = "DOE^JANE PLANTED 1234567";
    let dir = tempfile::tempdir().unwrap();
    let vol = pattern([4, 4, 6], [0.25, 0.25, 0.5], Matrix3::identity());
    let text_fields = [
        (tags::PATIENT_NAME, VR::PN),
        (tags::PATIENT_ID, VR::LO),
        (tags::SERIES_DESCRIPTION, VR::LO),
        (tags::STUDY_DESCRIPTION, VR::LO),
        (tags::PROTOCOL_NAME, VR::LO),
        (tags::INSTITUTION_NAME, VR::LO),
        (tags::REFERRING_PHYSICIAN_NAME, VR::PN),
        (tags::OPERATORS_NAME, VR::PN),
        (tags::IMAGE_COMMENTS, VR::LT),
        (tags::BODY_PART_EXAMINED, VR::CS),
        (tags::STATION_NAME, VR::SH),
    ];
    for seed in ["phi-a", "phi-b"] {
        let paths = write_series(&dir.path().join(seed), &vol, &identity(seed), &FIXED).unwrap();
        for p in &paths {
            edit_file(p, |obj| {
                for (tag, vr) in text_fields {
                    obj.put(DataElement::new(tag, vr, NAME));
                }
            });
        }
    }
    let planted = ["DOE", "JANE", "PLANTED", "1234567"];
    let clean = |what: &str, text: &str| {
        let upper = text.to_ascii_uppercase();
        for p in planted {
            assert!(!upper.contains(p), "{what} holds {p:?}: {text}");
        }
    };
    let out = otoatlas(&["inspect", dir.path().to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("2 image series"), "{stderr}");
    clean("the several-series error", &stderr);
    // pick one by its listed hash: the description is in no output either
    let hash = stderr
        .lines()
        .find_map(|l| l.split_whitespace().next().filter(|w| w.len() == 16))
        .unwrap()
        .to_string();
    for extra in [None, Some("--json")] {
        let mut args = vec!["inspect", dir.path().to_str().unwrap(), "--series", &hash];
        args.extend(extra);
        let out = otoatlas(&args);
        assert!(out.status.success());
        clean("inspect's output", &String::from_utf8_lossy(&out.stdout));
        clean("inspect's log", &String::from_utf8_lossy(&out.stderr));
    }
}
