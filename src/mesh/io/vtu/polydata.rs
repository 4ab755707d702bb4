//! VTP writer: a triangle surface as VTK XML PolyData with Float64 point data arrays, the form
//! in which ParaView and VTK keep a per-vertex scalar (PLY's non-standard vertex properties,
//! such as `quality`, are dropped by VTK's PLY reader).

use std::fmt::Write as _;
use std::path::Path;

use super::VtuEncoding;
use super::write::{Data, cell_arrays, data_array, escape};
use crate::mesh::TriMesh;
use crate::mesh::io::{MeshIoError, write_bytes};

/// The VTP document for `mesh` with the point data `arrays` (name, one value per vertex); the
/// first array is the active scalars. `Err` names an array of the wrong length.
pub fn vtp_string(
    mesh: &TriMesh,
    arrays: &[(&str, &[f64])],
    encoding: VtuEncoding,
) -> Result<String, String> {
    let points = mesh.vertices.len();
    if let Some((name, values)) = arrays.iter().find(|(_, v)| v.len() != points) {
        return Err(format!(
            "point array {name} has {} values for {points} points",
            values.len()
        ));
    }
    let mut out = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <PolyData>\n",
    );
    let _ = writeln!(
        out,
        "    <Piece NumberOfPoints=\"{points}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{}\">",
        mesh.triangles.len()
    );
    match arrays.first() {
        Some((name, _)) => {
            let _ = writeln!(out, "      <PointData Scalars=\"{}\">", escape(name));
        }
        None => out.push_str("      <PointData>\n"),
    }
    for (name, values) in arrays {
        data_array(&mut out, name, 1, Data::F64(values), encoding);
    }
    out.push_str("      </PointData>\n      <Points>\n");
    let coords: Vec<f64> = mesh.vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    data_array(&mut out, "Points", 3, Data::F64(&coords), encoding);
    out.push_str("      </Points>\n      <Polys>\n");
    let connectivity: Vec<i64> = mesh
        .triangles
        .iter()
        .flat_map(|t| t.iter().map(|&v| i64::from(v)))
        .collect();
    let offsets: Vec<i64> = (1..=mesh.triangles.len()).map(|i| 3 * i as i64).collect();
    cell_arrays(&mut out, &connectivity, &offsets, encoding);
    out.push_str("      </Polys>\n    </Piece>\n  </PolyData>\n</VTKFile>\n");
    Ok(out)
}

/// Writes `mesh` with its point data `arrays` as VTP (inline base64).
pub fn write_vtp(
    path: &Path,
    mesh: &TriMesh,
    arrays: &[(&str, &[f64])],
) -> Result<(), MeshIoError> {
    let text = vtp_string(mesh, arrays, VtuEncoding::Base64)
        .map_err(|e| MeshIoError::parse(path, "point data", e))?;
    write_bytes(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    #[test]
    fn a_point_array_of_the_wrong_length_is_refused() {
        let mesh = TriMesh {
            vertices: vec![
                Point3::origin(),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2]],
        };
        let text = vtp_string(
            &mesh,
            &[("deviation_mm", &[0.5, -0.25, 0.0])],
            VtuEncoding::Ascii,
        )
        .unwrap();
        assert!(
            text.contains("<PointData Scalars=\"deviation_mm\">"),
            "{text}"
        );
        assert!(text.contains("NumberOfPolys=\"1\""), "{text}");
        let err = vtp_string(&mesh, &[("deviation_mm", &[0.5])], VtuEncoding::Ascii).unwrap_err();
        assert_eq!(err, "point array deviation_mm has 1 values for 3 points");
    }
}
