//! `VolumeMesh`: what the volume formats (VTU, Gmsh) carry: a region-labelled tet mesh plus
//! optional region-labelled boundary triangles on the same nodes, and per-cell data arrays
//! (tets first, then triangles, the order cells are written).

use crate::mesh::TetMesh;

/// A named per-cell array, one value per cell (tets, then triangles).
#[derive(Debug, Clone, PartialEq)]
pub struct CellArray {
    pub name: String,
    pub values: Vec<f64>,
}

/// Tets and triangles over one node set.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VolumeMesh {
    /// Nodes, tets and their regions.
    pub tets: TetMesh,
    /// Triangles over `tets.nodes`.
    pub triangles: Vec<[u32; 3]>,
    pub triangle_regions: Vec<u16>,
}

impl VolumeMesh {
    /// A volume mesh of tets only.
    pub fn from_tets(tets: TetMesh) -> Self {
        Self {
            tets,
            ..Self::default()
        }
    }

    /// Number of cells (tets + triangles).
    pub fn cell_count(&self) -> usize {
        self.tets.tets.len() + self.triangles.len()
    }

    /// Region of every cell, tets first.
    pub fn cell_regions(&self) -> impl Iterator<Item = u16> + '_ {
        self.tets
            .regions
            .iter()
            .chain(&self.triangle_regions)
            .copied()
    }

    /// Checks indices and array lengths; the message names the first problem.
    pub fn check(&self, arrays: &[CellArray]) -> Result<(), String> {
        self.tets.validate().map_err(|e| e.to_string())?;
        if self.triangle_regions.len() != self.triangles.len() {
            return Err(format!(
                "one region per triangle ({} triangles, {} regions)",
                self.triangles.len(),
                self.triangle_regions.len()
            ));
        }
        let n = self.tets.nodes.len();
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= n))
        {
            return Err(format!("triangle {t} with node indices below {n}"));
        }
        if let Some(a) = arrays.iter().find(|a| a.values.len() != self.cell_count()) {
            return Err(format!(
                "cell array '{}' with one value per cell ({}), found {}",
                a.name,
                self.cell_count(),
                a.values.len()
            ));
        }
        Ok(())
    }
}
