//! Landmark files in every supported format, against the coordinates they were written with:
//! Slicer `.fcsv` (LPS, RAS, legacy numeric codes, Slicer 5's extra columns, reordered
//! columns, quoted labels), `.mrk.json`, our `landmarks.json` and plain CSV; the writers' output
//! read back; the errors that name file, line and expectation; and the prompt from a pipe.

use std::fs;
use std::path::PathBuf;

use nalgebra::{Point3, Vector3};
use otoatlas::ear::{LandmarkFileError, read_landmarks, write_fcsv, write_json, write_mrk_json};
use otoatlas::image::{Sampler, Volume};
use otoatlas::register::landmarks::{LandmarkError, PromptInput, prompt_landmarks};
use otoatlas::register::{Landmarks, Side};

fn expected() -> Landmarks {
    Landmarks {
        umbo: Point3::new(12.5, -30.25, 101.0),
        incudomalleolar: Point3::new(14.0, -27.0, 106.5),
        incudostapedial: Point3::new(10.75, -26.5, 103.25),
    }
}

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let p = dir.path().join(name);
    fs::write(&p, text).unwrap();
    p
}

fn assert_points(l: &Landmarks, e: &Landmarks) {
    for (a, b) in l.points().iter().zip(e.points()) {
        assert!((a - b).norm() < 1e-9, "{a} vs {b}");
    }
}

#[test]
fn fcsv_lps_ras_legacy_codes_and_slicer5_extra_columns() {
    let dir = tempfile::tempdir().unwrap();
    let header = "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n";
    let lps = format!(
        "# Markups fiducial file version = 5.6\n# CoordinateSystem = LPS\n{header}\
         1,12.5,-30.25,101,0,0,0,1,1,1,0,Umbo,,,2,0\n\
         2,14,-27,106.5,0,0,0,1,1,1,0,IMJ,,,2,0\n\
         3,10.75,-26.5,103.25,0,0,0,1,1,1,0,\"incudostapedial joint\",\"a, quoted, desc\",,2,0\n"
    );
    assert_points(
        &read_landmarks(&write(&dir, "a.fcsv", &lps))
            .unwrap()
            .landmarks,
        &expected(),
    );
    // the same points in RAS, by name and by the legacy code 0
    let ras = lps
        .replace("CoordinateSystem = LPS", "CoordinateSystem = RAS")
        .replace("12.5,-30.25", "-12.5,30.25")
        .replace("14,-27", "-14,27")
        .replace("10.75,-26.5", "-10.75,26.5");
    assert_points(
        &read_landmarks(&write(&dir, "b.fcsv", &ras))
            .unwrap()
            .landmarks,
        &expected(),
    );
    let legacy = ras.replace("CoordinateSystem = RAS", "CoordinateSystem = 0");
    assert_points(
        &read_landmarks(&write(&dir, "c.fcsv", &legacy))
            .unwrap()
            .landmarks,
        &expected(),
    );
    let legacy_lps = lps.replace("CoordinateSystem = LPS", "CoordinateSystem = 1");
    assert_points(
        &read_landmarks(&write(&dir, "d.fcsv", &legacy_lps))
            .unwrap()
            .landmarks,
        &expected(),
    );
}

#[test]
fn fcsv_columns_are_read_by_the_header_not_by_position() {
    let dir = tempfile::tempdir().unwrap();
    let text = "# CoordinateSystem = LPS\n# columns = label,z,y,x\n\
                ISJ,103.25,-26.5,10.75\nother point,0,0,0\numbo,101,-30.25,12.5\nIncudomalleolar,106.5,-27,14\n";
    assert_points(
        &read_landmarks(&write(&dir, "r.fcsv", text))
            .unwrap()
            .landmarks,
        &expected(),
    );
}

/// Coordinates a file states in metres were read as millimetres (1000 times too small); now
/// they are converted, with a note, and a unit that is not a length is refused by name.
#[test]
fn coordinates_in_metres_are_converted_and_unknown_units_refused() {
    let dir = tempfile::tempdir().unwrap();
    let json = r#"{"units":"m","umbo":[0.0125,-0.03025,0.101],
        "incudomalleolar":[0.014,-0.027,0.1065],"incudostapedial":[0.01075,-0.0265,0.10325]}"#;
    let read = read_landmarks(&write(&dir, "l.json", json)).unwrap();
    assert_points(&read.landmarks, &expected());
    assert!(
        read.notes.iter().any(|n| n.contains("converted to mm")),
        "{:?}",
        read.notes
    );
    let mrk = r#"{"markups":[{"coordinateSystem":"LPS","coordinateUnits":"m","controlPoints":[
        {"label":"umbo","position":[0.0125,-0.03025,0.101]},
        {"label":"IMJ","position":[0.014,-0.027,0.1065]},
        {"label":"ISJ","position":[0.01075,-0.0265,0.10325]}]}]}"#;
    let read = read_landmarks(&write(&dir, "m.mrk.json", mrk)).unwrap();
    assert_points(&read.landmarks, &expected());
    let furlong = json.replace(r#""units":"m""#, r#""units":"furlong""#);
    let err = read_landmarks(&write(&dir, "f.json", &furlong)).unwrap_err();
    assert!(
        err.to_string()
            .contains(r#"units "furlong": expected mm, cm, m or um"#),
        "{err}"
    );
}

#[test]
fn mrk_json_json_and_csv() {
    let dir = tempfile::tempdir().unwrap();
    let mrk = r#"{"markups":[{"type":"Fiducial","coordinateSystem":"RAS","controlPoints":[
        {"label":"umbo","position":[-12.5,30.25,101.0]},
        {"label":"IMJ","position":[-14.0,27.0,106.5]},
        {"label":"ISJ","position":[-10.75,26.5,103.25]}]}]}"#;
    assert_points(
        &read_landmarks(&write(&dir, "m.mrk.json", mrk))
            .unwrap()
            .landmarks,
        &expected(),
    );
    let json = r#"{"coordinate_system":"LPS","side":"left","umbo":[12.5,-30.25,101],
        "incudomalleolar":[14,-27,106.5],"incudostapedial":[10.75,-26.5,103.25]}"#;
    let read = read_landmarks(&write(&dir, "l.json", json)).unwrap();
    assert_points(&read.landmarks, &expected());
    assert_eq!(read.side, Some(Side::Left));
    let csv = "label,x,y,z\numbo,12.5,-30.25,101\nIMJ, 14, -27, 106.5\nISJ,10.75,-26.5,103.25\n";
    assert_points(
        &read_landmarks(&write(&dir, "p.csv", csv))
            .unwrap()
            .landmarks,
        &expected(),
    );
}

#[test]
fn a_coordinate_that_rounds_to_zero_is_written_without_a_sign() {
    let mut l = expected();
    l.umbo = Point3::new(-0.00001, -2.5, 1e-12);
    let text = write_fcsv(&l);
    assert!(text.contains("\n1,0.0000,-2.5000,0.0000,"), "{text}");
    assert!(!text.contains("-0.0000"), "{text}");
}

#[test]
fn writers_round_trip_through_the_readers() {
    let dir = tempfile::tempdir().unwrap();
    let e = expected();
    assert_points(
        &read_landmarks(&write(&dir, "w.fcsv", &write_fcsv(&e)))
            .unwrap()
            .landmarks,
        &e,
    );
    assert_points(
        &read_landmarks(&write(&dir, "w.mrk.json", &write_mrk_json(&e)))
            .unwrap()
            .landmarks,
        &e,
    );
    let j = read_landmarks(&write(&dir, "w.json", &write_json(&e, Some(Side::Right)))).unwrap();
    assert_points(&j.landmarks, &e);
    assert_eq!(j.side, Some(Side::Right));
}

#[test]
fn errors_name_file_line_and_expectation() {
    let dir = tempfile::tempdir().unwrap();
    let missing = write(&dir, "m.csv", "umbo,1,2,3\nIMJ,4,5,6\n");
    let err = read_landmarks(&missing).unwrap_err();
    assert!(
        matches!(
            err,
            LandmarkFileError::Missing {
                name: "incudostapedial",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("m.csv"));
    let dup = write(
        &dir,
        "d.csv",
        "umbo,1,2,3\nIMJ,4,5,6\nISJ,7,8,9\nUmbo,1,1,1\n",
    );
    assert!(matches!(
        read_landmarks(&dup).unwrap_err(),
        LandmarkFileError::Duplicate {
            first: 1,
            second: 4,
            ..
        }
    ));
    let bad = write(&dir, "b.fcsv", "# CoordinateSystem = LPS\numbo,1,2,x\n");
    let err = read_landmarks(&bad).unwrap_err().to_string();
    assert!(
        err.contains("b.fcsv:2") && err.contains("expected a number"),
        "{err}"
    );
    let frame = write(&dir, "f.fcsv", "# CoordinateSystem = XYZ\n");
    assert!(
        read_landmarks(&frame)
            .unwrap_err()
            .to_string()
            .contains("expected LPS, RAS, 0 or 1")
    );
    assert!(matches!(
        read_landmarks(&write(&dir, "x.txt", "")).unwrap_err(),
        LandmarkFileError::UnknownFormat { .. }
    ));
    let not_json = write(&dir, "n.json", "{ umbo: [1,2,3] ");
    assert!(
        read_landmarks(&not_json)
            .unwrap_err()
            .to_string()
            .contains("n.json:1")
    );
}

#[test]
fn prompt_from_a_pipe_reasks_on_bad_input_and_accepts_voxels() {
    let volume = Volume {
        dims: [20, 20, 20],
        spacing: [0.5, 0.5, 0.5],
        origin: Vector3::new(10.0, -32.0, 100.0),
        direction: nalgebra::Matrix3::identity(),
        data: (0..8000).map(|v| v as f32).collect(),
    };
    let sampler = Sampler::new(&volume).unwrap();
    let answers = "12.5 -30.25 101\nnonsense\n500 0 0\nv 8 10 13\n10.75, -26.5, 103.25\n";
    let mut input = std::io::Cursor::new(answers);
    let mut echo = Vec::new();
    let l = prompt_landmarks(
        PromptInput::Lines {
            input: &mut input,
            echo: &mut echo,
        },
        &sampler,
        None,
    )
    .unwrap();
    assert_points(&l, &expected());
    let echo = String::from_utf8(echo).unwrap();
    assert!(echo.contains("expected three numbers"), "{echo}");
    assert!(echo.contains("outside the image"), "{echo}");
    // voxel (8, 10, 13) at 0.5 mm from the origin is (14, -27, 106.5); its value 8 + 20*10 + 400*13
    assert!(echo.contains("intensity 5408"), "{echo}");
    // a pipe that ends early is an error, not a hang or a panic
    let mut short = std::io::Cursor::new("12.5 -30.25 101\n");
    let mut sink = Vec::new();
    let err = prompt_landmarks(
        PromptInput::Lines {
            input: &mut short,
            echo: &mut sink,
        },
        &sampler,
        None,
    )
    .unwrap_err();
    assert!(matches!(err, LandmarkError::PromptEnded));
}

#[test]
fn landmarks_command_reads_a_pipe_and_writes_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    let volume = Volume {
        dims: [16, 16, 16],
        spacing: [0.5, 0.5, 0.5],
        origin: Vector3::new(10.0, -32.0, 100.0),
        direction: nalgebra::Matrix3::identity(),
        data: vec![100.0; 4096],
    };
    let identity = otoatlas::image::dicom::write::SeriesIdentity {
        study_uid: "2.25.1".into(),
        series_uid: "2.25.2".into(),
        frame_of_reference_uid: "2.25.3".into(),
        patient_name: "DOE^JOHN".into(),
        patient_id: "X1".into(),
        patient_birth_date: "19600101".into(),
        series_description: "lm".into(),
        laterality: Some("L".into()),
    };
    let rescale =
        otoatlas::image::dicom::write::SliceRescale::Fixed(otoatlas::image::dicom::Rescale {
            slope: 1.0,
            intercept: 0.0,
        });
    otoatlas::image::dicom::write::write_series(
        &dir.path().join("dicom"),
        &volume,
        &identity,
        &rescale,
    )
    .unwrap();
    let out = crate::common::otoatlas_with_stdin(
        &["landmarks", dir.path().to_str().unwrap(), "--quiet"],
        b"12.5 -30.25 101\nv 8 10 13\n10.75 -26.5 103.25\n",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in ["landmarks.fcsv", "landmarks.json"] {
        let read = read_landmarks(&dir.path().join(name)).unwrap();
        assert_points(&read.landmarks, &expected());
    }
    // the side comes from the DICOM Laterality
    let json = read_landmarks(&dir.path().join("landmarks.json")).unwrap();
    assert_eq!(json.side, Some(Side::Left));
    // asked again without --out, the case's picks are kept (it replaced them unasked) ...
    let picks = std::fs::read(dir.path().join("landmarks.fcsv")).unwrap();
    let again = b"1 2 3\n4 5 6\n7 8 9\n";
    let out = crate::common::otoatlas_with_stdin(
        &["landmarks", dir.path().to_str().unwrap(), "--quiet"],
        again,
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("holds landmarks already, which are replaced only on request"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("landmarks.fcsv")).unwrap(),
        picks
    );
    // ... and replaced where --out names them
    let fcsv = dir.path().join("landmarks.fcsv");
    let out = crate::common::otoatlas_with_stdin(
        &[
            "landmarks",
            dir.path().to_str().unwrap(),
            "--out",
            fcsv.to_str().unwrap(),
            "--quiet",
        ],
        b"12.5 -30.25 101\nv 8 10 13\n10.75 -26.5 103.5\n",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_ne!(std::fs::read(&fcsv).unwrap(), picks);
    // a file --out does not name but would write beside it is kept when it stands alone ...
    let lone = dir.path().join("other.json");
    std::fs::write(&lone, b"{\"not\": \"ours\"}").unwrap();
    let to = |out: &std::path::Path| {
        crate::common::otoatlas_with_stdin(
            &[
                "landmarks",
                dir.path().to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--quiet",
            ],
            b"12.5 -30.25 101\nv 8 10 13\n10.75 -26.5 103.25\n",
        )
    };
    let out = to(&dir.path().join("other.fcsv"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("other.json, which exists without"),
        "{stderr}"
    );
    assert!(!dir.path().join("other.fcsv").exists());
    assert_eq!(std::fs::read(&lone).unwrap(), b"{\"not\": \"ours\"}");
    // ... and replaced where --out names it, its companion written beside it
    let out = to(&lone);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in ["other.json", "other.fcsv"] {
        let read = read_landmarks(&dir.path().join(name)).unwrap();
        assert_points(&read.landmarks, &expected());
    }
}

/// An endless input (`/dev/zero` given as the landmark file, or piped into the prompt) is
/// refused after a bounded read instead of growing until the kernel kills the process; a
/// UTF-8 byte-order mark (as some editors save) is not part of the first column's name.
#[test]
fn endless_inputs_are_refused_and_a_byte_order_mark_is_ignored() {
    // /dev/zero under a landmark extension: a symlink to it
    let zero = std::path::Path::new("/dev/zero");
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("zero.fcsv");
    std::os::unix::fs::symlink(zero, &link).unwrap();
    let err = read_landmarks(&link).unwrap_err().to_string();
    assert!(err.contains("larger than 16 MiB"), "{err}");

    let volume = Volume {
        dims: [4, 4, 4],
        spacing: [1.0; 3],
        origin: Vector3::zeros(),
        direction: nalgebra::Matrix3::identity(),
        data: vec![0.0; 64],
    };
    let sampler = Sampler::new(&volume).unwrap();
    let mut endless = std::io::BufReader::new(std::io::repeat(0));
    let mut sink = Vec::new();
    let err = prompt_landmarks(
        PromptInput::Lines {
            input: &mut endless,
            echo: &mut sink,
        },
        &sampler,
        None,
    )
    .unwrap_err();
    assert!(matches!(err, LandmarkError::PromptEnded));

    let fcsv = "\u{feff}# Markups fiducial file version = 5.6\n# CoordinateSystem = LPS\n\
        # columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n\
        1,12.5,-30.25,101,0,0,0,1,1,1,0,Umbo,,\n\
        2,14,-27,106.5,0,0,0,1,1,1,0,IMJ,,\n\
        3,10.75,-26.5,103.25,0,0,0,1,1,1,0,ISJ,,\n";
    let l = read_landmarks(&write(&dir, "bom.fcsv", fcsv)).unwrap();
    assert_points(&l.landmarks, &expected());
}
