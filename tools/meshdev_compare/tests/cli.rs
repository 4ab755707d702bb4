//! The tool end to end on analytic shapes: concentric spheres (distance = radius difference,
//! up to the tessellation's chord error), a label-map reference, the deviation map, and usage
//! errors.

use std::path::Path;
use std::process::Command;

use nalgebra::{Matrix3, Point3, Vector3};
use otoatlas::image::Volume;
use otoatlas::image::nifti::write_nifti;
use otoatlas::io_util::write_atomic;
use otoatlas::mesh::io::ply::{VertexAttributes, ply_bytes, read_ply};
use otoatlas::mesh::shapes::icosphere;

fn tool(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_meshdev_compare"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn write_ply(path: &Path, radius: f64) {
    let mesh = icosphere(Point3::new(1.0, 2.0, 3.0), radius, 5);
    write_atomic(
        path,
        &ply_bytes(&mesh, &VertexAttributes::default()).unwrap(),
    )
    .unwrap();
}

#[test]
fn concentric_spheres_per_structure_with_a_deviation_map() {
    let dir = tempfile::tempdir().unwrap();
    let (reference, test) = (dir.path().join("ref"), dir.path().join("test"));
    std::fs::create_dir_all(&reference).unwrap();
    std::fs::create_dir_all(&test).unwrap();
    write_ply(&reference.join("malleus.ply"), 1.1);
    write_ply(&test.join("malleus.ply"), 1.0);
    write_ply(&test.join("incus.ply"), 0.5);
    let map = dir.path().join("dev.ply");
    let (code, stdout, stderr) = tool(&[
        reference.to_str().unwrap(),
        test.to_str().unwrap(),
        "--json",
        "--map",
        map.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let m = &json["structures"]["malleus"];
    // icosphere level 5: chord error below 0.1 % of the radius
    for key in [
        "masd",
        "assd",
        "mean_test_to_ref",
        "mean_ref_to_test",
        "meshdev_mean",
    ] {
        let v = m[key].as_f64().unwrap();
        assert!((v - 0.1).abs() < 0.002, "{key} = {v}");
    }
    assert!(
        (m["bias"].as_f64().unwrap() + 0.1).abs() < 0.002,
        "inside the reference: negative"
    );
    assert_eq!(json["unpaired"], serde_json::json!(["test incus"]));
    let (mesh, attrs) = read_ply(&map).unwrap();
    let quality = attrs.quality.unwrap();
    assert_eq!(quality.len(), mesh.vertices.len());
    assert!(quality.iter().all(|q| (q + 0.1).abs() < 0.002));
}

#[test]
fn label_map_reference_and_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    // label 2 (incus) is a ball of radius 1 mm sampled at 0.05 mm
    let n = 50;
    let mut v = Volume {
        dims: [n; 3],
        spacing: [0.05; 3],
        origin: Vector3::new(-1.25, -1.25, -1.25),
        direction: Matrix3::identity(),
        data: vec![0.0; n * n * n],
    };
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = v.index_to_world(Vector3::new(i as f64, j as f64, k as f64));
                if p.norm() < 1.0 {
                    let idx = v.index(i, j, k);
                    v.data[idx] = 2.0;
                }
            }
        }
    }
    let labels: Vec<u8> = v.data.iter().map(|x| *x as u8).collect();
    let nii = dir.path().join("labels.nii.gz");
    write_nifti(&nii, &v, &labels).unwrap();
    let test = dir.path().join("incus.ply");
    write_atomic(
        &test,
        &ply_bytes(
            &icosphere(Point3::origin(), 1.0, 5),
            &VertexAttributes::default(),
        )
        .unwrap(),
    )
    .unwrap();
    let (code, stdout, stderr) = tool(&[
        nii.to_str().unwrap(),
        test.to_str().unwrap(),
        "--json",
        "--tolerance",
        "0.05",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let masd = json["structures"]["incus"]["masd"].as_f64().unwrap();
    // the label surface is a voxel approximation: within half a voxel of the true sphere
    assert!(masd < 0.025, "masd {masd}");
    let (code, _, stderr) = tool(&[
        nii.to_str().unwrap(),
        test.to_str().unwrap(),
        "--labels",
        "1=malleus",
    ]);
    assert_eq!(code, 2);
    assert!(stderr.contains("no structure pairs"), "{stderr}");
    let (code, _, stderr) = tool(&[
        dir.path().join("absent.ply").to_str().unwrap(),
        test.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{stderr}");
}
