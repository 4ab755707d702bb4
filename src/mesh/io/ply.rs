//! PLY surfaces (Turk 1994; the layout MeshLab and meshio use): read ASCII and binary, write
//! binary little-endian, with optional per-vertex `quality` (a scalar, e.g. a deviation) and
//! `red green blue` colours (deviation maps). Polygons are read as triangle fans.

use std::io::BufReader;
use std::path::Path;

use nalgebra::Point3;
use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType,
    ScalarType,
};

use super::{MeshIoError, check_indices, read_bytes, write_bytes};
use crate::mesh::TriMesh;

/// Optional per-vertex data carried by a PLY surface.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VertexAttributes {
    /// The `quality` scalar per vertex.
    pub quality: Option<Vec<f64>>,
    /// `red, green, blue` per vertex.
    pub colors: Option<Vec<[u8; 3]>>,
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// Encodes `mesh` (and `attrs`) as binary little-endian PLY.
pub fn ply_bytes(mesh: &TriMesh, attrs: &VertexAttributes) -> Result<Vec<u8>, String> {
    let n = mesh.vertices.len();
    if attrs.quality.as_ref().is_some_and(|q| q.len() != n) {
        return Err(format!("one quality value per vertex ({n})"));
    }
    if attrs.colors.as_ref().is_some_and(|c| c.len() != n) {
        return Err(format!("one colour per vertex ({n})"));
    }
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    let mut ve = ElementDef::new("vertex".into());
    let mut names: Vec<(&str, ScalarType)> = vec![
        ("x", ScalarType::Double),
        ("y", ScalarType::Double),
        ("z", ScalarType::Double),
    ];
    if attrs.quality.is_some() {
        names.push(("quality", ScalarType::Double));
    }
    if attrs.colors.is_some() {
        names.extend([
            ("red", ScalarType::UChar),
            ("green", ScalarType::UChar),
            ("blue", ScalarType::UChar),
        ]);
    }
    for (name, ty) in names {
        ve.properties
            .add(PropertyDef::new(name.into(), PropertyType::Scalar(ty)));
    }
    ve.count = n;
    ply.header.elements.add(ve);
    let mut fe = ElementDef::new("face".into());
    fe.properties.add(PropertyDef::new(
        "vertex_indices".into(),
        PropertyType::List(ScalarType::UChar, ScalarType::Int),
    ));
    fe.count = mesh.triangles.len();
    ply.header.elements.add(fe);

    let vertices = (0..n)
        .map(|i| {
            let mut e = DefaultElement::new();
            let p = mesh.vertices[i];
            e.insert("x".into(), Property::Double(p.x));
            e.insert("y".into(), Property::Double(p.y));
            e.insert("z".into(), Property::Double(p.z));
            if let Some(q) = &attrs.quality {
                e.insert("quality".into(), Property::Double(q[i]));
            }
            if let Some(c) = &attrs.colors {
                for (k, name) in ["red", "green", "blue"].iter().enumerate() {
                    e.insert((*name).into(), Property::UChar(c[i][k]));
                }
            }
            e
        })
        .collect();
    let faces = mesh
        .triangles
        .iter()
        .map(|t| {
            let mut e = DefaultElement::new();
            e.insert(
                "vertex_indices".into(),
                Property::ListInt(t.iter().map(|&v| v as i32).collect()),
            );
            e
        })
        .collect();
    ply.payload.insert("vertex".into(), vertices);
    ply.payload.insert("face".into(), faces);
    let mut out = Vec::new();
    ply_rs_bw::writer::Writer::new()
        .write_ply(&mut out, &mut ply)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// Writes `mesh` as binary little-endian PLY with optional per-vertex quality and colours.
pub fn write_ply(path: &Path, mesh: &TriMesh, attrs: &VertexAttributes) -> Result<(), MeshIoError> {
    let bytes =
        ply_bytes(mesh, attrs).map_err(|e| MeshIoError::parse(path, "vertex attributes", e))?;
    write_bytes(path, &bytes)
}

/// Reads a PLY surface (ASCII or binary); polygons are split into triangle fans.
pub fn read_ply(path: &Path) -> Result<(TriMesh, VertexAttributes), MeshIoError> {
    let bytes = read_bytes(path)?;
    let ply = ply_rs_bw::parser::Parser::<DefaultElement>::new()
        .read_ply(&mut BufReader::new(bytes.as_slice()))
        .map_err(|e| {
            MeshIoError::parse(
                path,
                "PLY header or body",
                format!("a valid PLY file ({})", parser_message(&e.to_string())),
            )
        })?;
    let empty = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&empty);
    let mut mesh = TriMesh::default();
    let mut quality = Vec::new();
    let mut colors = Vec::new();
    let has = |k: &str| vertices.first().is_some_and(|e| e.contains_key(k));
    let (with_q, with_c) = (has("quality"), has("red") && has("green") && has("blue"));
    for (i, e) in vertices.iter().enumerate() {
        let get = |k: &str| {
            e.get(k).and_then(scalar).ok_or_else(|| {
                MeshIoError::parse(path, format!("vertex {i} property '{k}'"), "a number")
            })
        };
        mesh.vertices
            .push(Point3::new(get("x")?, get("y")?, get("z")?));
        if with_q {
            quality.push(get("quality")?);
        }
        if with_c {
            let c = |k: &str| get(k).map(|v| v.clamp(0.0, 255.0) as u8);
            colors.push([c("red")?, c("green")?, c("blue")?]);
        }
    }
    for (f, e) in ply.payload.get("face").unwrap_or(&empty).iter().enumerate() {
        let list = e
            .get("vertex_indices")
            .or_else(|| e.get("vertex_index"))
            .and_then(Property::to_u32_list)
            .ok_or_else(|| {
                MeshIoError::parse(
                    path,
                    format!("face {f}"),
                    "a 'vertex_indices' list of non-negative integers",
                )
            })?;
        if list.len() < 3 {
            return Err(MeshIoError::parse(
                path,
                format!("face {f}"),
                "at least 3 vertex indices",
            ));
        }
        for k in 1..list.len() - 1 {
            mesh.triangles.push([list[0], list[k], list[k + 1]]);
        }
    }
    check_indices(path, &mesh.triangles, mesh.vertices.len())?;
    let attrs = VertexAttributes {
        quality: with_q.then_some(quality),
        colors: with_c.then_some(colors),
    };
    Ok((mesh, attrs))
}

/// The PLY parser's message in one line: its first line and the text it could not parse,
/// without the grammar's internal state it appends.
fn parser_message(message: &str) -> String {
    let mut lines = message.lines();
    let first = lines.next().unwrap_or_default().trim_end_matches('.');
    match lines.find_map(|l| l.trim().strip_prefix("String: ")) {
        Some(text) => format!("{first}: {}", text.trim_matches(['\'', '\n'])),
        None => first.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::cube_surface;

    /// The parser's error was three lines ending in its grammar's Debug text
    /// (`Error: ParseError { location: LineCol { .. }, expected: ExpectedSet { .. } }`).
    #[test]
    fn a_bad_header_line_is_named_in_one_line_without_debug_text() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex x\nend_header\n",
        )
        .unwrap();
        let message = read_ply(&path).unwrap_err().to_string();
        assert!(
            message.ends_with("(Line 3: Couldn't parse line: element vertex x)"),
            "{message}"
        );
        assert!(
            !message.contains('\n') && !message.contains("ParseError"),
            "{message}"
        );
    }

    #[test]
    fn binary_round_trip_with_quality_and_colours() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cube.ply");
        let mesh = cube_surface();
        let attrs = VertexAttributes {
            quality: Some((0..8).map(|i| i as f64 * 0.125 - 0.3).collect()),
            colors: Some((0..8).map(|i| [i as u8 * 30, 255 - i as u8, 7]).collect()),
        };
        write_ply(&path, &mesh, &attrs).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
        let (back, back_attrs) = read_ply(&path).unwrap();
        assert_eq!(back, mesh);
        assert_eq!(back_attrs, attrs);
        let (plain, none) = {
            write_ply(&path, &mesh, &VertexAttributes::default()).unwrap();
            read_ply(&path).unwrap()
        };
        assert_eq!(plain, mesh);
        assert_eq!(none, VertexAttributes::default());
    }

    #[test]
    fn ascii_with_a_quad_is_read_as_a_fan() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("quad.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float quality\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0.5\n1 0 0 1\n1 1 0 2\n0 1 0 3\n4 0 1 2 3\n",
        )
        .unwrap();
        let (m, a) = read_ply(&path).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!((m.area() - 1.0).abs() < 1e-12);
        assert_eq!(a.quality, Some(vec![0.5, 1.0, 2.0, 3.0]));
    }

    #[test]
    fn bad_files_are_errors_naming_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
        )
        .unwrap();
        let e = read_ply(&path).unwrap_err().to_string();
        assert!(e.contains("bad.ply") && e.contains("'y'"), "{e}");
        std::fs::write(&path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 5\n").unwrap();
        let e = read_ply(&path).unwrap_err().to_string();
        assert!(e.contains("triangle 0"), "{e}");
        std::fs::write(&path, b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nend_header\n\x01").unwrap();
        assert!(read_ply(&path).is_err());
        assert!(matches!(
            read_ply(&dir.path().join("missing.ply")),
            Err(MeshIoError::Io { .. })
        ));
    }
}
