//! Follower pressure on a triangulated surface (SOFA SurfacePressureForceField,
//! docs/fem.md): per triangle (a, b, c) each node receives (p/6)·(b − a)×(c − a),
//! i.e. p·A/3 along the current winding normal, evaluated at the current positions, so the
//! load turns with the surface. Units: p in Pa (= µN/mm²), forces in µN.

use nalgebra::{Point3, Vector3};

use super::error::FemError;

/// A uniform pressure acting along the winding normal of `triangles`.
#[derive(Debug, Clone, Copy)]
pub struct PressureLoad<'a> {
    /// Loaded triangles over the model's nodes; the force points along (b − a)×(c − a).
    pub triangles: &'a [[u32; 3]],
    /// Pressure in Pa; negative pulls against the winding normal.
    pub pressure: f64,
}

impl PressureLoad<'_> {
    /// Checks node indices and a finite pressure.
    pub fn check(&self, node_count: usize) -> Result<(), FemError> {
        if !self.pressure.is_finite() {
            return Err(FemError::InvalidParameter {
                what: "pressure (Pa)",
                value: self.pressure,
                expected: "finite",
            });
        }
        match self
            .triangles
            .iter()
            .flatten()
            .find(|&&v| v as usize >= node_count)
        {
            Some(&node) => Err(FemError::BadNodeReference {
                what: "pressure triangle",
                node,
                n_nodes: node_count,
            }),
            None => Ok(()),
        }
    }

    /// Adds the nodal forces (µN) at positions `x` to `out` (one per node); indices must have
    /// been checked with [`PressureLoad::check`].
    pub fn add_forces(&self, x: &[Point3<f64>], out: &mut [Vector3<f64>]) {
        let scale = self.pressure / 6.0;
        for t in self.triangles {
            let [a, b, c] = t.map(|v| x[v as usize]);
            let f = (b - a).cross(&(c - a)) * scale;
            for &v in t {
                out[v as usize] += f;
            }
        }
    }
}
