//! The finite-element model of one mesh: rest positions, corotated tetrahedra and membrane
//! triangles with their materials, and the lumped nodal masses.
//!
//! Inputs are plain slices so the model depends on no other otoatlas module. Lumped mass
//! (SOFA DiagonalMass with vertexMass; docs/fem.md): m_v = Σ_tets ρV/4 + Σ_tris ρhA/3,
//! in g.

use nalgebra::Point3;

use super::bending::{Bending, bending};
use super::element::CorotElement;
use super::error::FemError;
use super::material::{MembraneMaterial, TetMaterial};
use super::membrane::{MembraneElement, rest_membrane};
use super::rigid::RigidBodies;
use super::tet::{TetElement, rest_tet};

/// One family of elements: node indices per cell, a material index per cell, the materials.
#[derive(Debug, Clone, Copy)]
pub struct Elements<'a, const N: usize, M> {
    /// Node indices of each cell (into the rest positions).
    pub cells: &'a [[u32; N]],
    /// Index into `materials` for each cell.
    pub material_index: &'a [u32],
    /// The materials, validated when the model is built.
    pub materials: &'a [M],
}

impl<const N: usize, M> Elements<'_, N, M> {
    /// No elements of this family.
    pub const fn none() -> Self {
        Elements {
            cells: &[],
            material_index: &[],
            materials: &[],
        }
    }
}

/// Tetrahedra (4 nodes) with solid materials.
pub type TetElements<'a> = Elements<'a, 4, TetMaterial>;
/// Membrane triangles (3 nodes) with membrane materials.
pub type MembraneElements<'a> = Elements<'a, 3, MembraneMaterial>;

/// A corotational linear FEM model (mm, g, s; forces in µN, moduli in Pa).
#[derive(Debug, Clone)]
pub struct FemModel {
    rest: Vec<Point3<f64>>,
    pub(crate) tets: Vec<TetElement>,
    pub(crate) membranes: Vec<MembraneElement>,
    pub(crate) bending: Bending,
    masses: Vec<f64>,
}

fn build<const N: usize, M>(
    kind: &'static str,
    rest: &[Point3<f64>],
    set: &Elements<'_, N, M>,
    validate: impl Fn(&M, usize) -> Result<(), FemError>,
    make: impl Fn(usize, [u32; N], &M) -> Result<CorotElement<N>, FemError>,
) -> Result<Vec<CorotElement<N>>, FemError> {
    if set.material_index.len() != set.cells.len() {
        return Err(FemError::LengthMismatch {
            what: kind,
            expected: set.cells.len(),
            found: set.material_index.len(),
        });
    }
    for (i, m) in set.materials.iter().enumerate() {
        validate(m, i)?;
    }
    let mut out = Vec::with_capacity(set.cells.len());
    for (e, (cell, &mi)) in set.cells.iter().zip(set.material_index).enumerate() {
        for (a, &node) in cell.iter().enumerate() {
            if node as usize >= rest.len() {
                return Err(FemError::NodeOutOfRange {
                    kind,
                    element: e,
                    node,
                    n_nodes: rest.len(),
                });
            }
            if cell[..a].contains(&node) {
                return Err(FemError::RepeatedNode {
                    kind,
                    element: e,
                    node,
                });
            }
        }
        let mat = set
            .materials
            .get(mi as usize)
            .ok_or(FemError::MaterialOutOfRange {
                kind,
                element: e,
                index: mi,
                n_materials: set.materials.len(),
            })?;
        out.push(make(e, *cell, mat)?);
    }
    Ok(out)
}

impl FemModel {
    /// Builds the model; checks finite positions, node and material indices, materials, and
    /// non-degenerate rest elements (either orientation of a tetrahedron is accepted).
    pub fn new(
        rest: &[Point3<f64>],
        tets: TetElements<'_>,
        membranes: MembraneElements<'_>,
    ) -> Result<Self, FemError> {
        if let Some(i) = rest
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(FemError::NonFinite {
                what: "rest position",
                index: i,
            });
        }
        let tet_elems = build(
            "tetrahedron",
            rest,
            &tets,
            TetMaterial::validate,
            |e, c, m| rest_tet(e, c, rest, m),
        )?;
        let tri_elems = build(
            "membrane triangle",
            rest,
            &membranes,
            MembraneMaterial::validate,
            |e, c, m| rest_membrane(e, c, rest, m),
        )?;
        let mut masses = vec![0.0; rest.len()];
        for (t, &mi) in tet_elems.iter().zip(tets.material_index) {
            let m = tets.materials[mi as usize].density * t.measure / 4.0;
            t.nodes.iter().for_each(|&n| masses[n as usize] += m);
        }
        for (t, &mi) in tri_elems.iter().zip(membranes.material_index) {
            // measure = h·A, so ρ·measure/3 = ρhA/3.
            let m = membranes.materials[mi as usize].density * t.measure / 3.0;
            t.nodes.iter().for_each(|&n| masses[n as usize] += m);
        }
        let plate = |t: usize| {
            let m = &membranes.materials[membranes.material_index[t] as usize];
            (m.flexural_rigidity(), m.poisson_ratio)
        };
        let bending = bending(&tri_elems, plate, rest);
        Ok(FemModel {
            rest: rest.to_vec(),
            tets: tet_elems,
            membranes: tri_elems,
            bending,
            masses,
        })
    }

    /// The same model with every membrane bending at one flexural thickness (`bending`
    /// module), each triangle with the flexural rigidity D = E h_b³/(12(1 − ν²)) of its
    /// material at `bending_thickness_mm` (mm). It replaces the bending the materials' own
    /// `bending_thickness` gave (a what-if; see `MembraneMaterial`).
    pub fn with_membrane_bending(mut self, bending_thickness_mm: f64) -> Result<Self, FemError> {
        if !(bending_thickness_mm.is_finite() && bending_thickness_mm > 0.0) {
            return Err(FemError::InvalidParameter {
                what: "membrane bending thickness (mm)",
                value: bending_thickness_mm,
                expected: "finite and > 0",
            });
        }
        let membranes = &self.membranes;
        self.bending = bending(
            membranes,
            |t| {
                let lame = &membranes[t].lame;
                (
                    lame.flexural_rigidity(bending_thickness_mm),
                    lame.plane_stress_poisson_ratio(),
                )
            },
            &self.rest,
        );
        Ok(self)
    }

    /// The same model without the tetrahedra whose four nodes lie on one of `bodies` (they
    /// carry no strain when the body moves rigidly; `fem::rigid`), with the same lumped masses.
    pub fn without_rigid_tets(&self, bodies: &RigidBodies) -> Result<Self, FemError> {
        if bodies.node_count() != self.node_count() {
            return Err(FemError::LengthMismatch {
                what: "rigid body of each node",
                expected: self.node_count(),
                found: bodies.node_count(),
            });
        }
        let mut out = self.clone();
        out.tets.retain(|t| !bodies.holds(&t.nodes));
        Ok(out)
    }

    /// Number of bending hinges (interior membrane edges between bending triangles).
    pub fn hinge_count(&self) -> usize {
        self.bending.hinges.len()
    }

    /// Number of couplings between bending hinges (pairs of hinges of one triangle whose
    /// patch gives them a joint stiffness; `bending` module).
    pub fn hinge_coupling_count(&self) -> usize {
        self.bending.couplings.len()
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.rest.len()
    }

    /// Number of degrees of freedom (3 per node, ordered x, y, z per node).
    pub fn dof_count(&self) -> usize {
        3 * self.rest.len()
    }

    /// Number of tetrahedra.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// Number of membrane triangles.
    pub fn membrane_count(&self) -> usize {
        self.membranes.len()
    }

    /// Rest positions (mm).
    pub fn rest_positions(&self) -> &[Point3<f64>] {
        &self.rest
    }

    /// Lumped nodal masses (g): ρV/4 per tetrahedron node plus ρhA/3 per triangle node.
    pub fn lumped_masses(&self) -> &[f64] {
        &self.masses
    }
}
