//! VTU reader: ASCII or inline base64 `DataArray`s of tets and triangles.

use std::path::Path;

use nalgebra::Point3;

use super::{VTK_TETRA, VTK_TRIANGLE};
use crate::mesh::TetMesh;
use crate::mesh::io::xml::{DataArray, Element, attr, elements, line_of};
use crate::mesh::io::{CellArray, MeshIoError, VolumeMesh, read_text};

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
    parse_vtu(&read_text(path)?, path)
}

/// Parses a VTU document already in memory; `path` names it in errors.
pub fn parse_vtu(text: &str, path: &Path) -> Result<(VolumeMesh, Vec<CellArray>), MeshIoError> {
    let root = elements(text, "VTKFile")
        .next()
        .ok_or_else(|| MeshIoError::parse(path, "document", "a <VTKFile> element"))?;
    if attr(root.tag, "type") != Some("UnstructuredGrid") {
        return Err(MeshIoError::parse(
            path,
            format!("line {} <VTKFile>", line_of(text, root.start)),
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
            .map(|e| DataArray::all(text, e.body, header64))
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
    if Some(coords.values.len()) != n_points.checked_mul(3) {
        return Err(MeshIoError::parse(
            path,
            coords.at(),
            format!(
                "{} coordinates (3 × NumberOfPoints), found {}",
                n_points.saturating_mul(3),
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
