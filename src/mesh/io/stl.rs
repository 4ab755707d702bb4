//! STL surfaces: read binary or ASCII (crate `stl_io`, which also merges equal corners into
//! shared vertices), write binary (`stl_io`) or ASCII. STL stores single precision.

use std::fmt::Write as _;
use std::io::Cursor;
use std::path::Path;

use nalgebra::Point3;

use super::{MeshIoError, read_bytes, write_bytes};
use crate::mesh::TriMesh;

/// STL flavour to write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StlEncoding {
    Binary,
    Ascii,
}

fn stl_triangles(mesh: &TriMesh) -> Vec<stl_io::Triangle> {
    (0..mesh.triangles.len())
        .map(|t| {
            let n = mesh.area_normal2(t).try_normalize(0.0).unwrap_or_default();
            let v = |p: Point3<f64>| stl_io::Vector::new([p.x as f32, p.y as f32, p.z as f32]);
            stl_io::Triangle {
                normal: stl_io::Vector::new([n.x as f32, n.y as f32, n.z as f32]),
                vertices: mesh.corners(t).map(v),
            }
        })
        .collect()
}

/// Writes `mesh` as STL.
pub fn write_stl(path: &Path, mesh: &TriMesh, encoding: StlEncoding) -> Result<(), MeshIoError> {
    let triangles = stl_triangles(mesh);
    let bytes = match encoding {
        StlEncoding::Binary => {
            let mut out = Vec::new();
            stl_io::write_stl(&mut out, triangles.iter()).map_err(|source| MeshIoError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            out
        }
        StlEncoding::Ascii => {
            let mut s = String::from("solid otoatlas\n");
            for t in &triangles {
                let n = t.normal.0;
                let _ = writeln!(
                    s,
                    "  facet normal {:e} {:e} {:e}\n    outer loop",
                    n[0], n[1], n[2]
                );
                for v in &t.vertices {
                    let _ = writeln!(s, "      vertex {:e} {:e} {:e}", v.0[0], v.0[1], v.0[2]);
                }
                s.push_str("    endloop\n  endfacet\n");
            }
            s.push_str("endsolid otoatlas\n");
            s.into_bytes()
        }
    };
    write_bytes(path, &bytes)
}

/// Reads a binary or ASCII STL file into an indexed surface.
pub fn read_stl(path: &Path) -> Result<TriMesh, MeshIoError> {
    let bytes = read_bytes(path)?;
    let indexed = stl_io::read_stl(&mut Cursor::new(bytes)).map_err(|e| {
        MeshIoError::parse(
            path,
            "STL body",
            format!("a binary or ASCII STL file ({e})"),
        )
    })?;
    let vertices = indexed
        .vertices
        .iter()
        .map(|v| Point3::new(v.0[0] as f64, v.0[1] as f64, v.0[2] as f64))
        .collect::<Vec<_>>();
    let mut triangles = Vec::with_capacity(indexed.faces.len());
    for (f, face) in indexed.faces.iter().enumerate() {
        let tri = face.vertices.map(|v| u32::try_from(v).unwrap_or(u32::MAX));
        if tri.iter().any(|&v| v as usize >= vertices.len()) {
            return Err(MeshIoError::parse(
                path,
                format!("facet {f}"),
                "vertices inside the file",
            ));
        }
        triangles.push(tri);
    }
    Ok(TriMesh {
        vertices,
        triangles,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::cube_surface;

    #[test]
    fn binary_and_ascii_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mut mesh = cube_surface();
        for p in &mut mesh.vertices {
            *p = Point3::new(p.x * 0.5 + 3.25, p.y * 2.0, p.z - 1.5);
        }
        for (name, enc) in [
            ("b.stl", StlEncoding::Binary),
            ("a.stl", StlEncoding::Ascii),
        ] {
            let path = dir.path().join(name);
            write_stl(&path, &mesh, enc).unwrap();
            let back = read_stl(&path).unwrap();
            // Coordinates are exact in f32; corners merged back to 8 vertices.
            assert_eq!(back.vertices.len(), 8);
            assert_eq!(back.triangles.len(), 12);
            assert!((back.signed_volume() - 1.0).abs() < 1e-9);
            for t in 0..12 {
                assert_eq!(back.corners(t), mesh.corners(t));
            }
        }
        let head = std::fs::read(dir.path().join("a.stl")).unwrap();
        assert!(head.starts_with(b"solid otoatlas\n"));
    }

    #[test]
    fn garbage_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.stl");
        std::fs::write(
            &path,
            "solid x\n facet normal 0 0 1\n outer loop\n vertex 1 2\n",
        )
        .unwrap();
        let e = read_stl(&path).unwrap_err().to_string();
        assert!(e.contains("bad.stl"), "{e}");
        // Binary header announcing 5 facets, none present.
        let mut truncated = vec![0u8; 84];
        truncated[80] = 5;
        std::fs::write(&path, truncated).unwrap();
        assert!(read_stl(&path).is_err());
    }
}
