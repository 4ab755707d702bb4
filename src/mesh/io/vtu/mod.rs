//! VTK XML UnstructuredGrid (`.vtu`, VTK file formats 1.0): write tets (cell type 10) and
//! triangles (type 5) with an Int32 `region` cell array and any Float64 cell arrays, as ASCII or
//! inline base64 binary (UInt64 byte-count header and data encoded as one block, uncompressed);
//! read ASCII or inline base64 files of tets and triangles (any numeric array types). Also the
//! VTK XML PolyData writer (`.vtp`, `polydata`) for surfaces with point data, through the same
//! `DataArray` writer.

mod polydata;
mod read;
mod write;

pub use polydata::{vtp_string, write_vtp};
pub use read::{parse_vtu, read_vtu, read_vtu_tets};
pub use write::{vtu_string, write_vtu};

const VTK_TRIANGLE: u8 = 5;
const VTK_TETRA: u8 = 10;

/// How `DataArray` contents are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VtuEncoding {
    Ascii,
    /// Inline base64 of (UInt64 byte count, little-endian values).
    Base64,
}

#[cfg(test)]
mod tests;
