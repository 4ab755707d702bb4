//! Independent reader check: files written here are read back by Python's `meshio`
//! (skipped without python3 + meshio unless OTOATLAS_REQUIRE_PYTHON=1).

use super::ply::{VertexAttributes, write_ply};
use super::test_meshes::{cube_surface, python_with};
use super::vtu::{VtuEncoding, write_vtu};
use super::{CellArray, VolumeMesh, gmsh::write_msh};
use crate::mesh::tet::BoundaryOf;

const SCRIPT: &str = r#"
import sys, json, meshio
import numpy as np
out = {}
for path in sys.argv[1:]:
    m = meshio.read(path)
    cells = {b.type: len(b.data) for b in m.cells}
    data = {k: [float(np.asarray(a, dtype=float).sum()) for a in v] for k, v in m.cell_data.items()}
    pdata = {k: float(np.asarray(v, dtype=float).sum()) for k, v in m.point_data.items()}
    vol = 0.0
    for b in m.cells:
        if b.type == "tetra":
            p = m.points[b.data]
            vol += float(np.sum(np.einsum("ij,ij->i", p[:,1]-p[:,0], np.cross(p[:,2]-p[:,0], p[:,3]-p[:,0]))) / 6.0)
    out[path.rsplit("/", 1)[-1]] = {"points": len(m.points), "cells": cells, "cell_data": data, "point_data": pdata, "volume": vol}
print(json.dumps(out))
"#;

#[test]
fn meshio_reads_what_we_write() {
    let dir = tempfile::tempdir().unwrap();
    let mut tets = crate::mesh::mesher::lattice::Lattice::new(
        &nalgebra::Point3::new(0., 0., 0.),
        &nalgebra::Point3::new(1., 1., 1.),
        0.5,
        0,
    );
    // A small lattice block, two regions split at x = 0.5.
    let regions: Vec<u16> = tets
        .tets
        .iter()
        .map(|t| {
            let x: f64 = t.iter().map(|&v| tets.nodes[v as usize].x).sum::<f64>() / 4.0;
            if x < 0.5 { 1 } else { 2 }
        })
        .collect();
    let tet_mesh = crate::mesh::TetMesh {
        nodes: std::mem::take(&mut tets.nodes),
        tets: std::mem::take(&mut tets.tets),
        regions,
    };
    let b = tet_mesh.boundary(BoundaryOf::Whole);
    let triangles: Vec<[u32; 3]> = b.node_triangles();
    let volume = tet_mesh.volume();
    let mesh = VolumeMesh {
        triangle_regions: vec![3; triangles.len()],
        triangles,
        tets: tet_mesh,
    };
    let n = mesh.cell_count();
    let density = CellArray {
        name: "density".into(),
        values: (0..n).map(|i| 1000.0 + i as f64).collect(),
    };
    let expected_density: f64 = density.values.iter().sum();
    let expected_region: f64 = mesh.cell_regions().map(f64::from).sum();
    let arrays = [density];
    let vtu_a = dir.path().join("a.vtu");
    let vtu_b = dir.path().join("b.vtu");
    let msh = dir.path().join("c.msh");
    let ply = dir.path().join("d.ply");
    write_vtu(&vtu_a, &mesh, &arrays, VtuEncoding::Ascii).unwrap();
    write_vtu(&vtu_b, &mesh, &arrays, VtuEncoding::Base64).unwrap();
    write_msh(&msh, &mesh, &Default::default()).unwrap();
    let attrs = VertexAttributes {
        quality: Some((0..8).map(|i| i as f64 * 0.5).collect()),
        colors: Some(vec![[10, 20, 30]; 8]),
    };
    write_ply(&ply, &cube_surface(), &attrs).unwrap();
    let paths: Vec<String> = [&vtu_a, &vtu_b, &msh, &ply]
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let args: Vec<&str> = paths.iter().map(String::as_str).collect();
    let Some(json) = python_with("meshio", SCRIPT, &args) else {
        return;
    };
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let (n_tets, n_tris) = (mesh.tets.tets.len() as u64, mesh.triangles.len() as u64);
    for name in ["a.vtu", "b.vtu", "c.msh"] {
        let f = &v[name];
        assert_eq!(f["points"], mesh.tets.nodes.len() as u64, "{name}");
        assert_eq!(f["cells"]["tetra"], n_tets, "{name}");
        assert_eq!(f["cells"]["triangle"], n_tris, "{name}");
        assert!(
            (f["volume"].as_f64().unwrap() - volume).abs() < 1e-12,
            "{name}"
        );
    }
    for name in ["a.vtu", "b.vtu"] {
        let d = &v[name]["cell_data"];
        let sum = |k: &str| {
            d[k].as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .sum::<f64>()
        };
        assert_eq!(sum("region"), expected_region, "{name}");
        assert!((sum("density") - expected_density).abs() < 1e-6, "{name}");
    }
    let phys = &v["c.msh"]["cell_data"]["gmsh:physical"];
    let phys_sum: f64 = phys
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .sum();
    assert_eq!(phys_sum, expected_region);
    let p = &v["d.ply"];
    assert_eq!(p["points"], 8);
    assert_eq!(p["cells"]["triangle"], 12);
    assert_eq!(p["point_data"]["quality"], 14.0);
    assert_eq!(p["point_data"]["red"], 80.0);
}
