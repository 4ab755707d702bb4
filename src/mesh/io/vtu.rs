//! VTK XML UnstructuredGrid (`.vtu`, VTK file formats 1.0): write tets (cell type 10) and
//! triangles (type 5) with an Int32 `region` cell array and any Float64 cell arrays, as ASCII or
//! inline base64 binary (UInt64 byte-count header and data encoded as one block, uncompressed);
//! read ASCII or inline base64 files of tets and triangles (any numeric array types).

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;
use nalgebra::Point3;

use super::xml::{DataArray, Element, attr, elements, line_of};
use super::{CellArray, MeshIoError, VolumeMesh, read_text, write_bytes};
use crate::mesh::TetMesh;

const VTK_TRIANGLE: u8 = 5;
const VTK_TETRA: u8 = 10;

/// How `DataArray` contents are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VtuEncoding {
    Ascii,
    /// Inline base64 of (UInt64 byte count, little-endian values).
    Base64,
}

enum Data<'a> {
    F64(&'a [f64]),
    I64(&'a [i64]),
    I32(&'a [i32]),
    U8(&'a [u8]),
}

impl Data<'_> {
    fn vtk_type(&self) -> &'static str {
        match self {
            Data::F64(_) => "Float64",
            Data::I64(_) => "Int64",
            Data::I32(_) => "Int32",
            Data::U8(_) => "UInt8",
        }
    }

    fn ascii(&self, out: &mut String) {
        fn join<T: std::fmt::Display>(out: &mut String, v: &[T]) {
            for (i, x) in v.iter().enumerate() {
                out.push(if i % 12 == 0 { '\n' } else { ' ' });
                let _ = write!(out, "{x}");
            }
        }
        match self {
            Data::F64(v) => join(out, v),
            Data::I64(v) => join(out, v),
            Data::I32(v) => join(out, v),
            Data::U8(v) => join(out, v),
        }
        out.push('\n');
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            Data::F64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I64(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::I32(v) => v.iter().flat_map(|x| x.to_le_bytes()).collect(),
            Data::U8(v) => v.to_vec(),
        }
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn data_array(out: &mut String, name: &str, components: usize, data: Data, encoding: VtuEncoding) {
    let format = match encoding {
        VtuEncoding::Ascii => "ascii",
        VtuEncoding::Base64 => "binary",
    };
    let _ = write!(
        out,
        "        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{components}\" format=\"{format}\">",
        data.vtk_type(),
        escape(name)
    );
    match encoding {
        VtuEncoding::Ascii => data.ascii(out),
        VtuEncoding::Base64 => {
            let raw = data.bytes();
            let mut block = (raw.len() as u64).to_le_bytes().to_vec();
            block.extend_from_slice(&raw);
            out.push('\n');
            out.push_str(&STANDARD.encode(block));
            out.push('\n');
        }
    }
    out.push_str("        </DataArray>\n");
}

/// The VTU document for `mesh` with extra cell `arrays`; `Err` names an inconsistency.
pub fn vtu_string(
    mesh: &VolumeMesh,
    arrays: &[CellArray],
    encoding: VtuEncoding,
) -> Result<String, String> {
    mesh.check(arrays)?;
    let m = &mesh.tets;
    let mut out = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <UnstructuredGrid>\n",
    );
    let _ = writeln!(
        out,
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n      <Points>",
        m.nodes.len(),
        mesh.cell_count()
    );
    let coords: Vec<f64> = m.nodes.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    data_array(&mut out, "Points", 3, Data::F64(&coords), encoding);
    out.push_str("      </Points>\n      <Cells>\n");
    let connectivity: Vec<i64> = m
        .tets
        .iter()
        .flat_map(|t| t.iter().map(|&v| v as i64))
        .chain(
            mesh.triangles
                .iter()
                .flat_map(|t| t.iter().map(|&v| v as i64)),
        )
        .collect();
    let offsets: Vec<i64> = (1..=m.tets.len())
        .map(|i| 4 * i as i64)
        .chain((1..=mesh.triangles.len()).map(|i| 4 * m.tets.len() as i64 + 3 * i as i64))
        .collect();
    let types: Vec<u8> = std::iter::repeat_n(VTK_TETRA, m.tets.len())
        .chain(std::iter::repeat_n(VTK_TRIANGLE, mesh.triangles.len()))
        .collect();
    data_array(
        &mut out,
        "connectivity",
        1,
        Data::I64(&connectivity),
        encoding,
    );
    data_array(&mut out, "offsets", 1, Data::I64(&offsets), encoding);
    data_array(&mut out, "types", 1, Data::U8(&types), encoding);
    out.push_str("      </Cells>\n      <CellData Scalars=\"region\">\n");
    let regions: Vec<i32> = mesh.cell_regions().map(i32::from).collect();
    data_array(&mut out, "region", 1, Data::I32(&regions), encoding);
    for a in arrays {
        data_array(&mut out, &a.name, 1, Data::F64(&a.values), encoding);
    }
    out.push_str("      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    Ok(out)
}

/// Writes `mesh` (tets, then triangles) with its regions and extra cell `arrays` as VTU.
pub fn write_vtu(
    path: &Path,
    mesh: &VolumeMesh,
    arrays: &[CellArray],
    encoding: VtuEncoding,
) -> Result<(), MeshIoError> {
    let text = vtu_string(mesh, arrays, encoding)
        .map_err(|e| MeshIoError::parse(path, "mesh to write", e))?;
    write_bytes(path, text.as_bytes())
}

/// Finds the `DataArray` called `name` among `arrays`.
fn named<'a>(
    path: &Path,
    arrays: &'a [DataArray],
    name: &str,
    section: &str,
) -> Result<&'a DataArray, MeshIoError> {
    arrays
        .iter()
        .find(|a| a.name == name)
        .ok_or_else(|| MeshIoError::parse(path, section, format!("a DataArray named '{name}'")))
}

/// Reads a VTU file of tets and triangles. Regions come from an integer cell array named
/// `region` when present (else every cell is region 1); every other single-component cell
/// array is returned as a `CellArray`, reordered like the cells (tets first).
pub fn read_vtu(path: &Path) -> Result<(VolumeMesh, Vec<CellArray>), MeshIoError> {
    let text = read_text(path)?;
    let root = elements(&text, "VTKFile")
        .next()
        .ok_or_else(|| MeshIoError::parse(path, "document", "a <VTKFile> element"))?;
    if attr(root.tag, "type") != Some("UnstructuredGrid") {
        return Err(MeshIoError::parse(
            path,
            format!("line {} <VTKFile>", line_of(&text, root.start)),
            "type=\"UnstructuredGrid\"",
        ));
    }
    if attr(root.tag, "compressor").is_some_and(|c| !c.is_empty()) {
        return Err(MeshIoError::parse(
            path,
            "<VTKFile> compressor",
            "uncompressed data",
        ));
    }
    let header64 = match attr(root.tag, "header_type").unwrap_or("UInt32") {
        "UInt32" => false,
        "UInt64" => true,
        other => {
            return Err(MeshIoError::parse(
                path,
                "<VTKFile> header_type",
                format!("UInt32 or UInt64, found {other}"),
            ));
        }
    };
    let pieces: Vec<Element> = elements(root.body, "Piece").collect();
    let piece = match pieces.as_slice() {
        [p] => p,
        _ => {
            return Err(MeshIoError::parse(
                path,
                "<UnstructuredGrid>",
                format!("exactly one <Piece>, found {}", pieces.len()),
            ));
        }
    };
    let count = |key: &str| -> Result<usize, MeshIoError> {
        attr(piece.tag, key)
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| {
                MeshIoError::parse(path, format!("<Piece> {key}"), "a non-negative integer")
            })
    };
    let (n_points, n_cells) = (count("NumberOfPoints")?, count("NumberOfCells")?);
    let section = |name: &str| {
        elements(piece.body, name)
            .next()
            .map(|e| DataArray::all(&text, e.body, header64))
    };
    let points = section("Points")
        .ok_or_else(|| MeshIoError::parse(path, "<Piece>", "a <Points> section"))?;
    let points = points.map_err(|(at, what)| MeshIoError::parse(path, at, what))?;
    let cells =
        section("Cells").ok_or_else(|| MeshIoError::parse(path, "<Piece>", "a <Cells> section"))?;
    let cells = cells.map_err(|(at, what)| MeshIoError::parse(path, at, what))?;
    let cell_data = match section("CellData") {
        Some(r) => r.map_err(|(at, what)| MeshIoError::parse(path, at, what))?,
        None => Vec::new(),
    };

    let coords = points
        .first()
        .ok_or_else(|| MeshIoError::parse(path, "<Points>", "one DataArray"))?;
    if coords.values.len() != 3 * n_points {
        return Err(MeshIoError::parse(
            path,
            coords.at(),
            format!(
                "{} coordinates (3 × NumberOfPoints), found {}",
                3 * n_points,
                coords.values.len()
            ),
        ));
    }
    let nodes: Vec<Point3<f64>> = coords
        .values
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let connectivity = named(path, &cells, "connectivity", "<Cells>")?;
    let offsets = named(path, &cells, "offsets", "<Cells>")?;
    let types = named(path, &cells, "types", "<Cells>")?;
    if offsets.values.len() != n_cells || types.values.len() != n_cells {
        return Err(MeshIoError::parse(
            path,
            offsets.at(),
            format!("{n_cells} offsets and types (NumberOfCells)"),
        ));
    }
    let index = |a: &DataArray, i: usize, below: usize| -> Result<usize, MeshIoError> {
        let v = a.values[i];
        if v.fract() == 0.0 && v >= 0.0 && (v as usize) < below {
            Ok(v as usize)
        } else {
            Err(MeshIoError::parse(
                path,
                format!("{} value {i}", a.at()),
                format!("an integer in 0..{below}, found {v}"),
            ))
        }
    };
    let mut mesh = VolumeMesh::default();
    mesh.tets.nodes = nodes;
    // Cell order in the result: tets first, then triangles.
    let (mut tet_cells, mut tri_cells) = (Vec::new(), Vec::new());
    let mut start = 0;
    for c in 0..n_cells {
        let end = index(offsets, c, connectivity.values.len() + 1)?;
        let ty = types.values[c];
        let corners = match ty as i64 {
            t if t == VTK_TETRA as i64 => 4,
            t if t == VTK_TRIANGLE as i64 => 3,
            _ => {
                return Err(MeshIoError::parse(
                    path,
                    format!("cell {c}"),
                    format!("cell type 10 (tetra) or 5 (triangle), found {ty}"),
                ));
            }
        };
        if end < start || end - start != corners {
            return Err(MeshIoError::parse(
                path,
                format!("cell {c} offsets"),
                format!("{corners} nodes for cell type {ty}"),
            ));
        }
        let mut ids = [0u32; 4];
        for (k, slot) in ids.iter_mut().take(corners).enumerate() {
            *slot = index(connectivity, start + k, n_points)? as u32;
        }
        if corners == 4 {
            mesh.tets.tets.push(ids);
            tet_cells.push(c);
        } else {
            mesh.triangles.push([ids[0], ids[1], ids[2]]);
            tri_cells.push(c);
        }
        start = end;
    }
    let order: Vec<usize> = tet_cells.iter().chain(&tri_cells).copied().collect();
    let mut arrays = Vec::new();
    let mut regions: Option<Vec<u16>> = None;
    for a in cell_data.iter().filter(|a| a.components == 1) {
        if a.values.len() != n_cells {
            return Err(MeshIoError::parse(
                path,
                a.at(),
                format!("{n_cells} values (NumberOfCells)"),
            ));
        }
        let values: Vec<f64> = order.iter().map(|&c| a.values[c]).collect();
        if a.name == "region" {
            let r = order
                .iter()
                .map(|&c| index(a, c, u16::MAX as usize + 1).map(|v| v as u16))
                .collect::<Result<Vec<u16>, _>>()?;
            regions = Some(r);
        } else {
            arrays.push(CellArray {
                name: a.name.clone(),
                values,
            });
        }
    }
    let regions = regions.unwrap_or_else(|| vec![1; n_cells]);
    let n_tets = mesh.tets.tets.len();
    mesh.tets.regions = regions[..n_tets].to_vec();
    mesh.triangle_regions = regions[n_tets..].to_vec();
    Ok((mesh, arrays))
}

/// Reads the tets of a VTU file as a `TetMesh` (triangles and extra arrays dropped).
pub fn read_vtu_tets(path: &Path) -> Result<TetMesh, MeshIoError> {
    Ok(read_vtu(path)?.0.tets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::{kuhn_cube, shared_anatomy};
    use crate::mesh::tet::BoundaryOf;
    use crate::mesh::topology::surface_topology;

    /// Kuhn cube with its boundary triangles (region 7) and two material arrays.
    pub(crate) fn sample() -> (VolumeMesh, Vec<CellArray>) {
        let tets = kuhn_cube();
        let b = tets.boundary(BoundaryOf::Whole);
        let triangles: Vec<[u32; 3]> = b
            .surface
            .triangles
            .iter()
            .map(|t| t.map(|v| b.node_of_vertex[v as usize]))
            .collect();
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
        // Independent facts from the data README: 3412 boundary triangles, 18 non-manifold
        // edges, Euler characteristic −3.
        let b = m.boundary(BoundaryOf::Whole);
        assert_eq!(b.surface.triangles.len(), 3412);
        let topo = surface_topology(&b.surface);
        assert_eq!(topo.non_manifold_edges, 18);
        assert_eq!(topo.euler, -3);
    }
}
