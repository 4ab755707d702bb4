//! Per-element corotational state of a configuration: element rotations, element elastic
//! forces and the list of inverted tetrahedra / collapsed membrane triangles.
//!
//! Computed in parallel (rayon) over elements, then gathered serially to nodes; the buffers
//! are allocated once per model and reused for every configuration.

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;

use super::bending::{Bending, HingeVectors};
use super::element::CorotElement;
use super::error::{ElementId, FemError};
use super::membrane::{membrane_admissible, membrane_rotation};
use super::model::FemModel;
use super::tet::{tet_admissible, tet_rotation};

/// Elements per rayon task: small enough to balance, large enough to amortise scheduling.
const PAR_CHUNK: usize = 512;

/// Rotations and elastic forces of every element at one configuration.
#[derive(Debug, Clone)]
pub struct CorotationalState {
    pub(crate) tets: ElementStates<4>,
    pub(crate) membranes: ElementStates<3>,
    /// Angle gradient and forces of every bending hinge.
    pub(crate) hinges: HingeStates,
    failed: Vec<ElementId>,
}

#[derive(Debug, Clone)]
pub(crate) struct HingeStates {
    pub gradients: Vec<HingeVectors>,
    deltas: Vec<f64>,
    moments: Vec<f64>,
    forces: Vec<HingeVectors>,
}

impl HingeStates {
    fn new(count: usize) -> Self {
        HingeStates {
            gradients: vec![[Vector3::zeros(); 4]; count],
            deltas: vec![0.0; count],
            moments: vec![0.0; count],
            forces: vec![[Vector3::zeros(); 4]; count],
        }
    }

    /// Angle changes and gradients, then moments m = K θ̃ and forces −m ∇θ; a collapsed
    /// triangle's hinge counts as unbent (the membrane state reports it).
    fn update(&mut self, bending: &Bending, x: &[Point3<f64>]) {
        (&mut self.gradients, &mut self.deltas, &bending.hinges)
            .into_par_iter()
            .with_min_len(PAR_CHUNK)
            .for_each(|(g, d, h)| {
                (*d, *g) = h.angle_change(x).unwrap_or((0.0, [Vector3::zeros(); 4]));
            });
        bending.moments(&self.deltas, &mut self.moments);
        (&mut self.forces, &self.gradients, &self.moments)
            .into_par_iter()
            .with_min_len(PAR_CHUNK)
            .for_each(|(f, g, m)| *f = g.map(|g| g * -m));
    }

    fn gather(&self, bending: &Bending, out: &mut [Vector3<f64>]) {
        gather(bending.hinges.iter().map(|h| &h.nodes), &self.forces, out);
    }
}

/// Adds each cell's nodal forces to `out` at the cell's nodes.
fn gather<'a, const N: usize>(
    cells: impl Iterator<Item = &'a [u32; N]>,
    forces: &[[Vector3<f64>; N]],
    out: &mut [Vector3<f64>],
) {
    for (nodes, f) in cells.zip(forces) {
        for (node, fa) in nodes.iter().zip(f) {
            out[*node as usize] += fa;
        }
    }
}

#[derive(Debug, Clone)]
pub(crate) struct ElementStates<const N: usize> {
    pub rotations: Vec<Matrix3<f64>>,
    forces: Vec<[Vector3<f64>; N]>,
    admissible: Vec<bool>,
}

impl<const N: usize> ElementStates<N> {
    fn new(count: usize) -> Self {
        ElementStates {
            rotations: vec![Matrix3::identity(); count],
            forces: vec![[Vector3::zeros(); N]; count],
            admissible: vec![true; count],
        }
    }

    fn update(
        &mut self,
        elements: &[CorotElement<N>],
        x: &[Point3<f64>],
        rotation: impl Fn(&CorotElement<N>, &Matrix3<f64>) -> (Matrix3<f64>, bool) + Sync,
    ) {
        (
            &mut self.rotations,
            &mut self.forces,
            &mut self.admissible,
            elements,
        )
            .into_par_iter()
            .with_min_len(PAR_CHUNK)
            .for_each(|(r, f, ok, e)| {
                let def = e.deformation(x);
                let (rot, admissible) = rotation(e, &def);
                *r = rot;
                *ok = admissible;
                *f = e.forces(&rot, &def);
            });
    }

    fn gather(&self, elements: &[CorotElement<N>], out: &mut [Vector3<f64>]) {
        gather(elements.iter().map(|e| &e.nodes), &self.forces, out);
    }
}

impl CorotationalState {
    /// Buffers for `model`, initialised to the rest state.
    pub fn new(model: &FemModel) -> Self {
        CorotationalState {
            tets: ElementStates::new(model.tets.len()),
            membranes: ElementStates::new(model.membranes.len()),
            hinges: HingeStates::new(model.bending.hinges.len()),
            failed: Vec::new(),
        }
    }

    /// Computes rotations and element forces at positions `x` (mm), one per node.
    pub fn update(&mut self, model: &FemModel, x: &[Point3<f64>]) -> Result<(), FemError> {
        self.check_model(model)?;
        check_positions(model, x)?;
        self.tets.update(&model.tets, x, |_, f| tet_rotation(f));
        self.membranes
            .update(&model.membranes, x, |e, f| membrane_rotation(e, x, f));
        self.hinges.update(&model.bending, x);
        self.failed.clear();
        let tets = self.tets.admissible.iter().enumerate();
        self.failed
            .extend(tets.filter(|(_, ok)| !**ok).map(|(i, _)| ElementId::Tet(i)));
        let tris = self.membranes.admissible.iter().enumerate();
        self.failed.extend(
            tris.filter(|(_, ok)| !**ok)
                .map(|(i, _)| ElementId::Membrane(i)),
        );
        Ok(())
    }

    /// Inverted tetrahedra (det F ≤ 0) and collapsed membrane triangles at the last update.
    pub fn failed_elements(&self) -> &[ElementId] {
        &self.failed
    }

    /// Adds the elastic nodal forces (µN) of the last update to `out` (one per node).
    pub fn add_elastic_forces(
        &self,
        model: &FemModel,
        out: &mut [Vector3<f64>],
    ) -> Result<(), FemError> {
        self.check_model(model)?;
        if out.len() != model.node_count() {
            return Err(FemError::LengthMismatch {
                what: "force buffer",
                expected: model.node_count(),
                found: out.len(),
            });
        }
        self.tets.gather(&model.tets, out);
        self.membranes.gather(&model.membranes, out);
        self.hinges.gather(&model.bending, out);
        Ok(())
    }

    /// Checks that this state was made for `model` (same element counts).
    pub(crate) fn check_model(&self, model: &FemModel) -> Result<(), FemError> {
        for (what, expected, found) in [
            (
                "state tetrahedra",
                model.tets.len(),
                self.tets.rotations.len(),
            ),
            (
                "state membrane triangles",
                model.membranes.len(),
                self.membranes.rotations.len(),
            ),
            (
                "state bending hinges",
                model.bending.hinges.len(),
                self.hinges.gradients.len(),
            ),
        ] {
            if expected != found {
                return Err(FemError::LengthMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        Ok(())
    }
}

/// Checks one finite position per node.
/// The first element that an update at `x` would list as failed (tetrahedra first, as
/// [`CorotationalState::failed_elements`] lists them), without computing any rotation or
/// force: the cheap test of a trial step. `x` must be finite ([`check_positions`]).
pub(crate) fn first_failure(model: &FemModel, x: &[Point3<f64>]) -> Option<ElementId> {
    let tet = model
        .tets
        .par_iter()
        .with_min_len(PAR_CHUNK)
        .position_first(|e| !tet_admissible(&e.deformation(x)));
    if let Some(i) = tet {
        return Some(ElementId::Tet(i));
    }
    model
        .membranes
        .par_iter()
        .with_min_len(PAR_CHUNK)
        .position_first(|e| !membrane_admissible(e, x))
        .map(ElementId::Membrane)
}

pub(crate) fn check_positions(model: &FemModel, x: &[Point3<f64>]) -> Result<(), FemError> {
    if x.len() != model.node_count() {
        return Err(FemError::LengthMismatch {
            what: "positions",
            expected: model.node_count(),
            found: x.len(),
        });
    }
    match x
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        Some(i) => Err(FemError::NonFinite {
            what: "position of node",
            index: i,
        }),
        None => Ok(()),
    }
}

impl FemModel {
    /// Corotational elastic forces f = −R K (Rᵀx − X) at positions `x` (mm) into `f` (µN, one
    /// per node, overwritten). `state` is updated to `x`; its `failed_elements()` lists the
    /// inverted or collapsed elements (forces are still defined for them, via the det fix).
    pub fn elastic_forces(
        &self,
        x: &[Point3<f64>],
        state: &mut CorotationalState,
        f: &mut [Vector3<f64>],
    ) -> Result<(), FemError> {
        state.update(self, x)?;
        f.fill(Vector3::zeros());
        state.add_elastic_forces(self, f)
    }
}
