//! Wavefront OBJ surfaces: read `v` and `f` records (1-based or negative relative indices,
//! `v/vt/vn` forms, polygons split into triangle fans; other records ignored), write `v`/`f`.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use super::{MeshIoError, check_indices, read_text, write_bytes};
use crate::mesh::TriMesh;

/// Writes `mesh` as OBJ (full precision, 1-based indices).
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), MeshIoError> {
    let mut s = String::from("# otoatlas surface (mm)\n");
    for p in &mesh.vertices {
        let _ = writeln!(s, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    write_bytes(path, s.as_bytes())
}

/// Reads the `v` and `f` records of an OBJ file.
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshIoError> {
    let text = read_text(path)?;
    let mut mesh = TriMesh::default();
    let mut face = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let at = |what: &str| format!("line {} ({what})", i + 1);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    *slot = words
                        .next()
                        .and_then(|w| w.parse::<f64>().ok())
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| {
                            MeshIoError::parse(
                                path,
                                at("v"),
                                format!(
                                    "three finite coordinates, coordinate {} missing or invalid",
                                    k + 1
                                ),
                            )
                        })?;
                }
                mesh.vertices.push(Point3::from(c));
            }
            Some("f") => {
                face.clear();
                for w in words {
                    let index = w
                        .split('/')
                        .next()
                        .and_then(|s| s.parse::<i64>().ok())
                        .ok_or_else(|| {
                            MeshIoError::parse(
                                path,
                                at("f"),
                                format!("vertex indices, found '{w}'"),
                            )
                        })?;
                    let n = mesh.vertices.len() as i64;
                    let resolved = match index {
                        k if k > 0 => k - 1,
                        k if k < 0 => n + k,
                        _ => -1,
                    };
                    if resolved < 0 || resolved >= n || resolved > u32::MAX as i64 {
                        return Err(MeshIoError::parse(
                            path,
                            at("f"),
                            format!(
                                "an index of one of the {n} vertices defined so far, found {index}"
                            ),
                        ));
                    }
                    face.push(resolved as u32);
                }
                if face.len() < 3 {
                    return Err(MeshIoError::parse(path, at("f"), "at least 3 vertices"));
                }
                for k in 1..face.len() - 1 {
                    mesh.triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    check_indices(path, &mesh.triangles, mesh.vertices.len())?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::{cube_surface, shared_anatomy};
    use crate::mesh::topology::surface_topology;

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.obj");
        let mut mesh = cube_surface();
        mesh.vertices[3] = Point3::new(0.1 + 0.2, 1.0 / 3.0, 1e-17);
        write_obj(&path, &mesh).unwrap();
        assert_eq!(read_obj(&path).unwrap(), mesh);
    }

    #[test]
    fn polygons_negative_indices_and_slashes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.obj");
        std::fs::write(&path, "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nusemtl a\nf 1//1 2//1 3//1 4//1\nf -4/1 -2 -1\n").unwrap();
        let m = read_obj(&path).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn bad_records_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.obj");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 x 0\n").unwrap();
        let e = read_obj(&path).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("coordinate 2"), "{e}");
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n").unwrap();
        let e = read_obj(&path).unwrap_err().to_string();
        assert!(e.contains("line 4") && e.contains("found 4"), "{e}");
        std::fs::write(&path, "v 0 0 0\nf 1 1\n").unwrap();
        assert!(read_obj(&path).is_err());
    }

    #[test]
    fn reads_the_sofa_malleus() {
        let Some(path) = shared_anatomy("sofa-ossicles/malleus.obj") else {
            return;
        };
        let m = read_obj(&path).unwrap();
        assert_eq!((m.vertices.len(), m.triangles.len()), (1876, 3748));
        assert!(
            (m.signed_volume() - 10.51).abs() < 0.01,
            "{}",
            m.signed_volume()
        );
        let topo = surface_topology(&m);
        assert!(topo.is_closed_oriented_manifold());
        assert_eq!(topo.euler, 2);
    }
}
