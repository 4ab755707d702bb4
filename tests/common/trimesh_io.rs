//! Shared by the trimesh cross-check test and the benchmark: writes meshes (OBJ) and weighted
//! samples as text, runs `tests/python/trimesh_check.py` (through `python::run_python`, so it
//! skips, saying why, when python3 or trimesh is missing, unless `OTOATLAS_REQUIRE_PYTHON=1`,
//! in which case that is a failure), and reads its JSON answer. Users declare the sibling
//! modules `python` and `external` next to this one.

use std::fmt::Write as _;
use std::path::Path;

use otoatlas::mesh::TriMesh;
use otoatlas::meshdev::Samples;

use super::python::run_python;

/// One direction as trimesh computed it.
pub struct TrimeshDirected {
    pub mean: f64,
    pub max: f64,
    pub p95: f64,
    pub distances: Vec<f64>,
}

/// Both directions and the wall time of trimesh's closest-point queries.
pub struct TrimeshResult {
    pub test_to_ref: TrimeshDirected,
    pub ref_to_test: TrimeshDirected,
    pub seconds: f64,
    pub version: String,
}

pub fn write_obj(path: &Path, mesh: &TriMesh) {
    let mut s = String::new();
    for v in &mesh.vertices {
        writeln!(s, "v {:.17e} {:.17e} {:.17e}", v.x, v.y, v.z).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

pub fn write_samples(path: &Path, samples: &Samples) {
    let mut s = String::new();
    for (p, w) in samples.points.iter().zip(&samples.weights) {
        writeln!(s, "{:.17e} {:.17e} {:.17e} {:.17e}", p.x, p.y, p.z, w).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

fn directed(v: &serde_json::Value) -> TrimeshDirected {
    TrimeshDirected {
        mean: v["mean"].as_f64().unwrap(),
        max: v["max"].as_f64().unwrap(),
        p95: v["p95"].as_f64().unwrap(),
        distances: v["distances"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d.as_f64().unwrap())
            .collect(),
    }
}

/// Writes the inputs into `dir` and runs the trimesh checker on them.
pub fn run_trimesh_check(
    dir: &Path,
    test: &TriMesh,
    reference: &TriMesh,
    test_samples: &Samples,
    reference_samples: &Samples,
) -> Option<TrimeshResult> {
    let paths = [
        "test.obj",
        "ref.obj",
        "test_samples.txt",
        "ref_samples.txt",
        "out.json",
    ]
    .map(|f| dir.join(f));
    write_obj(&paths[0], test);
    write_obj(&paths[1], reference);
    write_samples(&paths[2], test_samples);
    write_samples(&paths[3], reference_samples);
    run_python(
        "trimesh_check.py",
        &paths,
        &["numpy", "scipy", "rtree", "trimesh"],
    )?;
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&paths[4]).unwrap()).unwrap();
    Some(TrimeshResult {
        test_to_ref: directed(&json["test_to_ref"]),
        ref_to_test: directed(&json["ref_to_test"]),
        seconds: json["seconds"].as_f64().unwrap(),
        version: json["trimesh"].as_str().unwrap_or("?").to_string(),
    })
}
