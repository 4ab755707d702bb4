//! Small meshes and file locations shared by the format tests.

use std::path::PathBuf;

use nalgebra::Point3;

use crate::mesh::{TetMesh, TriMesh};

/// Unit cube surface with outward triangles (12 triangles, volume 1).
pub fn cube_surface() -> TriMesh {
    let v = |i: u32| Point3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64);
    TriMesh {
        vertices: (0..8).map(v).collect(),
        triangles: vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ],
    }
}

/// Unit cube as 6 positive tets (Kuhn), regions 1,1,1,2,2,2, with non-integer coordinates.
pub fn kuhn_cube() -> TetMesh {
    let nodes = (0..8)
        .map(|i| {
            Point3::new(
                (i & 1) as f64 * 1.25 + 0.1,
                ((i >> 1) & 1) as f64 * 0.75 - 0.3,
                ((i >> 2) & 1) as f64 * 1.5 + 1e-7,
            )
        })
        .collect();
    let mut m = TetMesh {
        nodes,
        tets: [[1, 3], [1, 5], [2, 3], [2, 6], [4, 5], [4, 6]]
            .iter()
            .map(|p| [0, p[0], p[1], 7])
            .collect(),
        regions: vec![1, 1, 1, 2, 2, 2],
    };
    m.orient_positive();
    m
}

/// A file under the test anatomy folder, `$OTOATLAS_SHARED_DIR/anatomy` (docs/anatomy.md,
/// "Test anatomy"; `scripts/test.sh` sets the variable). `None` (with a note) when the variable
/// is unset or the file absent, unless `OTOATLAS_REQUIRE_SHARED=1` (set in CI), which makes
/// its absence a failure.
pub fn shared_anatomy(rel: &str) -> Option<PathBuf> {
    let p = std::env::var_os("OTOATLAS_SHARED_DIR")
        .map(|shared| PathBuf::from(shared).join("anatomy").join(rel))
        .filter(|p| p.exists());
    let require = std::env::var("OTOATLAS_REQUIRE_SHARED").as_deref() == Ok("1");
    assert!(
        p.is_some() || !require,
        "anatomy/{rel} is missing under $OTOATLAS_SHARED_DIR and OTOATLAS_REQUIRE_SHARED=1"
    );
    if p.is_none() {
        eprintln!("skipped: anatomy/{rel} not found under $OTOATLAS_SHARED_DIR");
    }
    p
}

/// Runs a python3 snippet that imports `module`; `None` (skip) when unavailable, unless
/// OTOATLAS_REQUIRE_PYTHON=1.
pub fn python_with(module: &str, script: &str, args: &[&str]) -> Option<String> {
    let require = std::env::var("OTOATLAS_REQUIRE_PYTHON").as_deref() == Ok("1");
    let probe = std::process::Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output();
    if !matches!(&probe, Ok(o) if o.status.success()) {
        assert!(
            !require,
            "python3 with {module} is required (OTOATLAS_REQUIRE_PYTHON=1)"
        );
        eprintln!("skipped: python3 with {module} not available");
        return None;
    }
    let out = std::process::Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(String::from_utf8(out.stdout).unwrap())
}
