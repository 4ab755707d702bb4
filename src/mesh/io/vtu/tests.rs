//! VTU round trips, bad files and the SOFA ossicles.

use super::*;
use crate::mesh::io::test_meshes::{kuhn_cube, shared_anatomy};
use crate::mesh::io::{CellArray, VolumeMesh};
use crate::mesh::tet::BoundaryOf;
use crate::mesh::topology::surface_topology;

/// Kuhn cube with its boundary triangles (region 7) and two material arrays.
pub(crate) fn sample() -> (VolumeMesh, Vec<CellArray>) {
    let tets = kuhn_cube();
    let b = tets.boundary(BoundaryOf::Whole);
    let triangles: Vec<[u32; 3]> = b.node_triangles();
    let n = tets.tets.len() + triangles.len();
    let mesh = VolumeMesh {
        triangle_regions: vec![7; triangles.len()],
        triangles,
        tets,
    };
    let arrays = vec![
        CellArray {
            name: "density".into(),
            values: (0..n).map(|i| 1.2e-3 + i as f64 * 1e-5).collect(),
        },
        CellArray {
            name: "young_modulus".into(),
            values: (0..n).map(|i| 1.41e10 / (i + 1) as f64).collect(),
        },
    ];
    (mesh, arrays)
}

#[test]
fn ascii_and_base64_round_trips_are_exact() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, arrays) = sample();
    for (name, enc) in [
        ("a.vtu", VtuEncoding::Ascii),
        ("b.vtu", VtuEncoding::Base64),
    ] {
        let path = dir.path().join(name);
        write_vtu(&path, &mesh, &arrays, enc).unwrap();
        let (back, back_arrays) = read_vtu(&path).unwrap();
        assert_eq!(back, mesh);
        assert_eq!(back_arrays, arrays);
    }
}

#[test]
fn inconsistent_arrays_are_refused() {
    let (mesh, mut arrays) = sample();
    arrays[1].values.pop();
    let e = vtu_string(&mesh, &arrays, VtuEncoding::Ascii).unwrap_err();
    assert!(e.contains("young_modulus"), "{e}");
}

#[test]
fn bad_files_name_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.vtu");
    let (mesh, arrays) = sample();
    let good = vtu_string(&mesh, &arrays, VtuEncoding::Ascii).unwrap();
    let cases = [
        (
            good.replace("<Points>", "<Pts>")
                .replace("</Points>", "</Pts>"),
            "<Points>",
        ),
        (good.replacen(">\n10 10", ">\n10 12", 1), "cell type"),
        (
            good.replacen("NumberOfPoints=\"8\"", "NumberOfPoints=\"9\"", 1),
            "coordinates",
        ),
        (
            good.replacen("type=\"UnstructuredGrid\"", "type=\"PolyData\"", 1),
            "UnstructuredGrid",
        ),
        (
            good.replacen("format=\"ascii\">", "format=\"appended\">", 1),
            "appended",
        ),
        (good.replacen("\n0 1 3 7", "\n0 1 3 x7", 1), "found 'x7'"),
        (good.replacen("\n0 1 3 7", "\n0 1 3 70", 1), "0..8"),
        (good[..good.len() / 2].to_string(), "VTKFile"),
    ];
    for (text, needle) in cases {
        std::fs::write(&path, &text).unwrap();
        let e = read_vtu(&path).unwrap_err().to_string();
        assert!(e.contains("bad.vtu") && e.contains(needle), "{needle}: {e}");
    }
}

#[test]
fn reads_sofa_ossicles() {
    let Some(path) = shared_anatomy("sofa-ossicles/Ossicles.vtu") else {
        return;
    };
    let m = read_vtu_tets(&path).unwrap();
    assert_eq!((m.nodes.len(), m.tets.len()), (1733, 5058));
    assert_eq!(m.inverted_count(), 0);
    assert!((m.volume() - 27.15).abs() < 0.01, "{}", m.volume());
    // Independent facts about the file (docs/anatomy.md, "Test anatomy"): 3412 boundary
    // triangles, 18 non-manifold edges, Euler characteristic −3.
    let b = m.boundary(BoundaryOf::Whole);
    assert_eq!(b.surface.triangles.len(), 3412);
    let topo = surface_topology(&b.surface);
    assert_eq!(topo.non_manifold_edges, 18);
    assert_eq!(topo.euler, -3);
    // read as a surface (a chain folder's `Ossicles.vtu`): that boundary, outward, enclosing
    // the tetrahedra's volume
    let surface = crate::mesh::io::read_surface(&path).unwrap();
    assert_eq!(surface.triangles.len(), 3412);
    assert!(
        (surface.signed_volume() - m.volume()).abs() < 1e-9,
        "{} vs {}",
        surface.signed_volume(),
        m.volume()
    );
}

/// A VTU of tetrahedra only is read as a surface by its tetrahedra's boundary: the box's
/// 12 triangles, facing outward (enclosing the tetrahedra's volume); with triangle cells,
/// those.
#[test]
fn a_vtu_of_tetrahedra_is_read_as_their_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.vtu");
    let tets = kuhn_cube();
    write_vtu(
        &path,
        &VolumeMesh::from_tets(tets.clone()),
        &[],
        VtuEncoding::Ascii,
    )
    .unwrap();
    let surface = crate::mesh::io::read_surface(&path).unwrap();
    assert_eq!(surface.triangles.len(), 12);
    assert_eq!(surface.vertices.len(), 8);
    assert!((surface.signed_volume() - tets.volume()).abs() < 1e-9);
    assert!(tets.volume() > 1.0);
    let (mut mesh, _) = sample();
    mesh.triangles.truncate(5);
    mesh.triangle_regions.truncate(5);
    write_vtu(&path, &mesh, &[], VtuEncoding::Ascii).unwrap();
    assert_eq!(
        crate::mesh::io::read_surface(&path)
            .unwrap()
            .triangles
            .len(),
        5
    );
}
