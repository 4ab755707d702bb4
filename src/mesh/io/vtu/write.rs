//! VTU writer: one inline `DataArray` per field, ASCII or base64.

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;

use super::{VTK_TETRA, VTK_TRIANGLE, VtuEncoding};
use crate::mesh::io::{CellArray, MeshIoError, VolumeMesh, write_bytes};

pub(super) enum Data<'a> {
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

pub(super) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The `connectivity` and `offsets` arrays of a VTK XML cell block (VTU `Cells`, VTP `Polys`).
pub(super) fn cell_arrays(
    out: &mut String,
    connectivity: &[i64],
    offsets: &[i64],
    encoding: VtuEncoding,
) {
    data_array(out, "connectivity", 1, Data::I64(connectivity), encoding);
    data_array(out, "offsets", 1, Data::I64(offsets), encoding);
}

pub(super) fn data_array(
    out: &mut String,
    name: &str,
    components: usize,
    data: Data,
    encoding: VtuEncoding,
) {
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
    cell_arrays(&mut out, &connectivity, &offsets, encoding);
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
