//! Ingest against files no one here wrote: the pydicom test corpus (pydicom and pydicom-data
//! wheels) and nibabel's NIfTI-1/NIfTI-2 test images. Expected values were read with pydicom
//! 3.0.2 and nibabel 5.4.2 and are recorded here; compressed files are compared voxel by
//! voxel with their uncompressed twins.

use crate::common;
use crate::common::{assert_close, otoatlas_json, testdata};
use otoatlas::config::Config;
use otoatlas::image::{self, ImageError, LoadedImage};

fn load(rel: &str) -> Option<LoadedImage> {
    let p = testdata(rel)?;
    let cfg = Config::default_config().unwrap();
    Some(image::load(&p, None, &cfg.ingest).unwrap_or_else(|e| panic!("{rel}: {e}")))
}

fn sum(v: &[f32]) -> f64 {
    v.iter().map(|x| *x as f64).sum()
}

const PYD: &str = "pydicom/data/test_files";
const STORE: &str = "data_store/data";

#[test]
fn enhanced_ct_multiframe_geometry_and_rescale_from_functional_groups() {
    let Some(img) = load(&format!("{STORE}/eCT_Supplemental.dcm")) else {
        return;
    };
    let v = &img.volume;
    assert_eq!(v.dims, [512, 512, 2]);
    assert_close(&v.spacing, &[0.388672, 0.388672, 10.0], 1e-9, "spacing");
    // frames at z = -159 and -149 with row direction -x: the slice normal is -z, so the
    // frame at z = -149 comes first along it
    assert_close(v.origin.as_slice(), &[99.5, -301.5, -149.0], 1e-9, "origin");
    assert_close(
        &v.direction_row_major(),
        &[-1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0],
        1e-12,
        "direction",
    );
    // pydicom: frame sums of (stored - 1024), shared PixelValueTransformation
    let plane = 512 * 512;
    assert_eq!(sum(&v.data[..plane]), -170012051.0);
    assert_eq!(sum(&v.data[plane..]), -167609453.0);
    assert_eq!(v.data[v.index(200, 100, 1)], 17.0);
    assert_eq!(img.info.slices, 2);
    assert_eq!(img.info.files, 1);
}

#[test]
fn ct5n_series_is_ordered_by_position_with_spacing_from_positions() {
    let Some(img) = load(&format!("{PYD}/dicomdirtests/98892001/CT5N")) else {
        return;
    };
    let v = &img.volume;
    assert_eq!(v.dims, [16, 16, 5]);
    assert_close(&v.spacing, &[0.488281, 0.488281, 2.5], 1e-9, "spacing");
    assert_close(
        v.origin.as_slice(),
        &[-72.199997, -143.0, -1.2375],
        1e-9,
        "origin",
    );
    // pydicom per-slice sums in increasing z
    let sums: Vec<f64> = v.data.chunks(256).map(sum).collect();
    assert_eq!(sums, vec![-17594.0, -9701.0, -10964.0, -48364.0, -90697.0]);
    assert_eq!(v.data[v.index(5, 3, 2)], 23.0);
}

#[test]
fn ct2_series_with_a_gap_is_a_clear_error() {
    let Some(p) = testdata(&format!("{PYD}/dicomdirtests/77654033/CT2")) else {
        return;
    };
    let cfg = Config::default_config().unwrap();
    let err = image::load(&p, None, &cfg.ingest).unwrap_err();
    match &err {
        ImageError::NonUniformSpacing {
            gap_mm, median_mm, ..
        } => {
            assert!((gap_mm - 202.5).abs() < 1e-3, "{err}");
            assert!((median_mm - 1.25).abs() < 1e-3, "{err}");
        }
        other => panic!("expected a spacing error, got {other}"),
    }
    assert!(err.to_string().contains("17106"), "names the file: {err}");
    let (code, json) = otoatlas_json(&["inspect", p.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(json["error"].as_str().unwrap().contains("missing slice"));
}

#[test]
fn folder_with_many_series_lists_them_and_series_picks_one() {
    let Some(p) = testdata(&format!("{PYD}/dicomdirtests")) else {
        return;
    };
    let path = p.to_str().unwrap();
    let (code, json) = otoatlas_json(&["inspect", path]);
    assert_eq!(code, 2);
    let msg = json["error"].as_str().unwrap();
    // 13 series of images (pydicom counts them so); 98892001/CT2N's two slices are
    // localizers (ImageType LOCALIZER), skipped
    assert!(msg.contains("12 image series"), "{msg}");
    assert!(msg.contains("887a203c8fb65565"), "{msg}");
    // the listed hash prefix selects CT5N
    let (code, json) = otoatlas_json(&["inspect", path, "--series", "887a203c8fb65565"]);
    assert_eq!(code, 0, "{json}");
    assert_eq!(json["dims"], serde_json::json!([16, 16, 5]));
    let (code, _) = otoatlas_json(&["inspect", path, "--series", "ffffffff"]);
    assert_eq!(code, 2);
    let ct2n = testdata(&format!("{PYD}/dicomdirtests/98892001/CT2N")).unwrap();
    let (code, json) = otoatlas_json(&["inspect", ct2n.to_str().unwrap()]);
    assert_eq!(code, 2, "{json}");
    let msg = json["error"].as_str().unwrap();
    assert!(
        msg.contains("no DICOM image series found (2 files skipped: non-image objects, localizers"),
        "{msg}"
    );
}

fn assert_same_voxels(a: &LoadedImage, b: &LoadedImage, what: &str) {
    assert_eq!(a.volume.dims, b.volume.dims, "{what}");
    assert_eq!(a.volume.data, b.volume.data, "{what}: voxels differ");
}

#[test]
fn jpeg2000_lossless_equals_uncompressed() {
    let (Some(j2k), Some(unc)) = (
        load(&format!("{STORE}/693_J2KR.dcm")),
        load(&format!("{STORE}/693_UNCR.dcm")),
    ) else {
        return;
    };
    assert_eq!(j2k.info.transfer_syntax, "1.2.840.10008.1.2.4.90");
    assert_same_voxels(&j2k, &unc, "693 J2KR vs UNCR");
    assert_eq!(sum(&unc.volume.data), -271466631.0); // pydicom
}

#[test]
fn jpeg2000_lossy_matches_its_decoded_twin() {
    let (Some(j2k), Some(unc)) = (
        load(&format!("{PYD}/693_J2KI.dcm")),
        load(&format!("{STORE}/693_UNCI.dcm")),
    ) else {
        return;
    };
    assert_eq!(j2k.info.transfer_syntax, "1.2.840.10008.1.2.4.91");
    assert_eq!(sum(&unc.volume.data), -270617240.0); // pydicom
    // 693_UNCI is the decoded image of the lossy stream: equal up to codec rounding
    let max_diff = j2k
        .volume
        .data
        .iter()
        .zip(&unc.volume.data)
        .map(|(a, b)| (a - b).abs())
        .fold(0f32, f32::max);
    assert!(max_diff <= 1.0, "max difference {max_diff} HU");
}

#[test]
fn emri_small_multiframe_set_decodes_identically_in_every_syntax() {
    let Some(reference) = load(&format!("{STORE}/emri_small.dcm")) else {
        return;
    };
    assert_eq!(reference.volume.dims, [64, 64, 10]);
    assert_eq!(sum(&reference.volume.data), 4493276.0); // pydicom
    assert_eq!(sum(&reference.volume.data[3 * 4096..4 * 4096]), 461117.0);
    assert_eq!(
        reference.volume.data[reference.volume.index(20, 10, 3)],
        180.0
    );
    // no positions in these files: assumed geometry, said in the warnings
    assert!(
        reference
            .info
            .warnings
            .iter()
            .any(|w| w.contains("assumed"))
    );
    assert_close(
        &reference.volume.spacing[2..],
        &[1.2],
        1e-12,
        "SpacingBetweenSlices",
    );
    for (file, ts) in [
        ("emri_small_RLE.dcm", "1.2.840.10008.1.2.5"),
        ("emri_small_jpeg_2k_lossless.dcm", "1.2.840.10008.1.2.4.90"),
        ("emri_small_jpeg_ls_lossless.dcm", "1.2.840.10008.1.2.4.80"),
        ("emri_small_big_endian.dcm", "1.2.840.10008.1.2.2"),
    ] {
        let Some(other) = load(&format!("{STORE}/{file}")) else {
            return;
        };
        assert_eq!(other.info.transfer_syntax, ts, "{file}");
        assert_same_voxels(&other, &reference, file);
    }
}

/// nibabel's affine (RAS) for each file, as printed by nibabel 5.4.2, and the voxel sum of the
/// first volume from `get_fdata()`.
struct NibabelTruth {
    file: &'static str,
    format: &'static str,
    dims: [usize; 3],
    affine_ras: [[f64; 4]; 3],
    sum: f64,
}

const NIBABEL: &[NibabelTruth] = &[
    NibabelTruth {
        file: "anatomical.nii",
        format: "nifti1",
        dims: [33, 41, 25],
        affine_ras: [
            [-2.0, 0.0, 0.0, 32.0],
            [0.0, 2.0, 0.0, -40.0],
            [0.0, 0.0, 2.0, -16.0],
        ],
        sum: 284166082.0,
    },
    NibabelTruth {
        file: "example4d.nii.gz",
        format: "nifti1",
        dims: [128, 96, 24],
        affine_ras: [
            [
                -2.0,
                6.714715653593746e-19,
                9.081024511081715e-18,
                117.8551025390625,
            ],
            [
                -6.714715653593746e-19,
                1.9737114906311035,
                -0.35552823543548584,
                -35.72294235229492,
            ],
            [
                8.25548088896093e-18,
                0.3232076168060303,
                2.171081781387329,
                -7.248798370361328,
            ],
        ],
        sum: f64::NAN,
    },
    NibabelTruth {
        file: "example_nifti2.nii.gz",
        format: "nifti2",
        dims: [32, 20, 12],
        affine_ras: [
            [
                -2.0,
                6.714715653593746e-19,
                9.081024511081715e-18,
                117.8551025390625,
            ],
            [
                -6.714715653593746e-19,
                1.9737114906311035,
                -0.35552823543548584,
                -35.72294235229492,
            ],
            [
                8.25548088896093e-18,
                0.3232076168060303,
                2.171081781387329,
                -7.248798370361328,
            ],
        ],
        sum: f64::NAN,
    },
    NibabelTruth {
        file: "reoriented_anat_moved.nii",
        format: "nifti1",
        dims: [21, 26, 22],
        affine_ras: [
            [4.0, 0.0, 0.0, -35.29789733886719],
            [0.0, 4.0, 0.0, -47.97758483886719],
            [0.0, 0.0, 4.0, -27.599409103393555],
        ],
        sum: 32739769.449157715,
    },
    NibabelTruth {
        file: "standard.nii.gz",
        format: "nifti1",
        dims: [4, 5, 7],
        affine_ras: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 3.0, 0.0, 0.0],
            [0.0, 0.0, 2.0, 0.0],
        ],
        sum: 7650.0,
    },
];

#[test]
fn nifti_affines_match_nibabel_after_ras_to_lps() {
    for t in NIBABEL {
        let Some(img) = load(&format!("nibabel/tests/data/{}", t.file)) else {
            return;
        };
        let v = &img.volume;
        assert_eq!(img.info.format, t.format, "{}", t.file);
        assert_eq!(v.dims, t.dims, "{}", t.file);
        // LPS = diag(-1, -1, 1) RAS
        let flip = [-1.0, -1.0, 1.0];
        let m = v.index_to_world_matrix();
        for r in 0..3 {
            for c in 0..3 {
                let expected = flip[r] * t.affine_ras[r][c];
                assert!(
                    (m[(r, c)] - expected).abs() < 1e-5,
                    "{} affine[{r}][{c}]: {} vs {expected}",
                    t.file,
                    m[(r, c)]
                );
            }
            let expected = flip[r] * t.affine_ras[r][3];
            assert!(
                (v.origin[r] - expected).abs() < 1e-5,
                "{} origin[{r}]",
                t.file
            );
        }
        if t.sum.is_finite() {
            let s = sum(&v.data);
            assert!(
                (s - t.sum).abs() <= 1e-5 * t.sum.abs(),
                "{}: sum {s} vs {}",
                t.file,
                t.sum
            );
        }
    }
}

#[test]
fn nifti_scl_slope_is_applied() {
    // functional.nii: int16 with scl_slope/inter; nibabel's first voxel 4004.137202501297
    let Some(img) = load("nibabel/tests/data/functional.nii") else {
        return;
    };
    assert!((img.volume.data[0] as f64 - 4004.137202501297).abs() < 1e-2);
}

/// Decompresses `input` with a dcmtk tool (Debian package dcmtk, an independent decoder) into
/// `output`; `None` when dcmtk is absent (see `common::program`).
fn dcmtk(
    tool: &str,
    args: &[&str],
    input: &std::path::Path,
    output: &std::path::Path,
) -> Option<()> {
    let status = std::process::Command::new(common::program(tool, "dcmtk")?)
        .args(args)
        .arg(input)
        .arg(output)
        .status()
        .unwrap_or_else(|e| panic!("run {tool}: {e}"));
    assert!(
        status.success(),
        "{tool} failed ({status}) on {}",
        input.display()
    );
    Some(())
}

#[test]
fn jpeg_lossless_and_deflated_decode_like_dcmtk() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = Config::default_config().unwrap();
    for (rel, tool, args, ts) in [
        (
            format!("{STORE}/JPEG-LL.dcm"),
            "dcmdjpeg",
            &[][..],
            "1.2.840.10008.1.2.4.70",
        ),
        (
            format!("{PYD}/image_dfl.dcm"),
            "dcmconv",
            &["+te"][..],
            "1.2.840.10008.1.2.1.99",
        ),
    ] {
        let Some(input) = testdata(&rel) else { return };
        let plain = dir.path().join("plain.dcm");
        let Some(()) = dcmtk(tool, args, &input, &plain) else {
            return;
        };
        let ours = image::load(&input, None, &cfg.ingest).unwrap();
        let theirs = image::load(&plain, None, &cfg.ingest).unwrap();
        assert_eq!(ours.info.transfer_syntax, ts);
        assert_eq!(theirs.info.transfer_syntax, "1.2.840.10008.1.2.1");
        assert_same_voxels(&ours, &theirs, &rel);
        assert!(sum(&ours.volume.data) > 0.0, "{rel}: an image, not zeros");
    }
}
