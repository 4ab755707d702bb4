//! Matrix-free product with the linearised implicit step matrix
//! A = diag(d ⊗ I₃) + Σ c n nᵀ (directional dashpots) + s·(K'(x) + K_σ⁺(x)), fixed DOFs
//! projected out (row and column zero, diagonal 1): the same matrix `SparsePattern::assemble`
//! + `add_dashpots` + `add_membrane_stress_stiffness` build, applied element by element without assembling it.
//!
//! Why: a time step needs the current matrix only inside a few conjugate-gradient products,
//! and scattering ~150,000 entries every step cost more than those products (the factor that
//! preconditions them is refreshed rarely and is the only consumer of the assembled matrix).
//! Per element, with the perturbation gradient δF = Σ_b p_b g_bᵀ, the warped stiffness
//! R K Rᵀ gives (K'p)_a = w R σ(Rᵀ δF) g_a (σ(H) = λ tr(ε) P + 2μ ε, ε = P sym(H) P, the
//! element's linear stress) and the tensile stress stiffness w·g_aᵀσ⁺g_b·I₃ gives
//! (K_σ p)_a = w δF σ⁺ g_a, with σ⁺ computed once per configuration (`update`).

use nalgebra::{Matrix3, Point3, Vector3};

use super::dashpot::{Dashpot, check_dashpots};
use super::element::CorotElement;
use super::error::FemError;
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::state::{CorotationalState, ElementStates, check_positions};

/// The membranes' tensile stress (times their measure) at one configuration, ready to apply
/// the step matrix at it.
#[derive(Debug, Clone)]
pub struct StepOperator {
    tension: Vec<Matrix3<f64>>,
    /// The vector with its fixed DOFs zeroed (scratch of `apply`).
    free: Vec<f64>,
    /// Each hinge's angle change along the vector, and its moment (scratch of `apply`).
    hinge_rates: Vec<f64>,
    hinge_moments: Vec<f64>,
}

/// Adds `product(k, p restricted to the nodes of cell k)` of every cell to `y` at the
/// cell's nodes (`p` and `y` flat, three DOFs per node).
fn add_element_products<'e, const N: usize>(
    cells: impl Iterator<Item = &'e [u32; N]>,
    p: &[f64],
    y: &mut [f64],
    mut product: impl FnMut(usize, &[Vector3<f64>; N]) -> [Vector3<f64>; N],
) {
    for (k, nodes) in cells.enumerate() {
        let local = nodes.map(|v| {
            let i = 3 * v as usize;
            Vector3::new(p[i], p[i + 1], p[i + 2])
        });
        let out = product(k, &local);
        for (v, f) in nodes.iter().zip(&out) {
            let i = 3 * *v as usize;
            y[i] += f.x;
            y[i + 1] += f.y;
            y[i + 2] += f.z;
        }
    }
}

/// Adds `scale`·(K' p) of every element of one kind to `y` (free DOFs of `p` only).
fn add_warped<const N: usize>(
    elements: &[CorotElement<N>],
    states: &ElementStates<N>,
    scale: f64,
    p: &[f64],
    y: &mut [f64],
) {
    add_element_products(elements.iter().map(|e| &e.nodes), p, y, |k, local| {
        elements[k].warped_product(&states.rotations[k], local, scale)
    });
}

impl StepOperator {
    /// An operator for `model`, with no membrane tension until `update`.
    pub fn new(model: &FemModel) -> Self {
        StepOperator {
            tension: vec![Matrix3::zeros(); model.membranes.len()],
            free: vec![0.0; model.dof_count()],
            hinge_rates: vec![0.0; model.bending.hinges.len()],
            hinge_moments: vec![0.0; model.bending.hinges.len()],
        }
    }

    /// Computes the membranes' tensile stress at positions `x` (`state` updated to `x`).
    pub fn update(
        &mut self,
        model: &FemModel,
        x: &[Point3<f64>],
        state: &CorotationalState,
    ) -> Result<(), FemError> {
        state.check_model(model)?;
        check_positions(model, x)?;
        if self.tension.len() != model.membranes.len() {
            return Err(FemError::LengthMismatch {
                what: "operator membranes",
                expected: model.membranes.len(),
                found: self.tension.len(),
            });
        }
        for ((t, e), r) in self
            .tension
            .iter_mut()
            .zip(&model.membranes)
            .zip(&state.membranes.rotations)
        {
            *t = e.tension(r, &e.deformation(x)) * e.measure;
        }
        Ok(())
    }

    /// y = A p with A = diag(`node_diagonal` ⊗ I₃) + Σ c n nᵀ (`dashpots`, as given) +
    /// `scale`·(K'(state) + K_σ⁺), fixed DOFs projected out; `state` and the last `update` must be of the same configuration.
    #[allow(clippy::too_many_arguments)]
    pub fn apply(
        &mut self,
        model: &FemModel,
        state: &CorotationalState,
        scale: f64,
        node_diagonal: &[f64],
        dashpots: &[Dashpot],
        fixed: &FixedDofs,
        p: &[f64],
        y: &mut [f64],
    ) -> Result<(), FemError> {
        state.check_model(model)?;
        check_dashpots(dashpots, model.node_count())?;
        for (what, expected, found) in [
            ("node diagonal", model.node_count(), node_diagonal.len()),
            ("fixed DOF mask", model.dof_count(), fixed.len()),
            ("vector", model.dof_count(), p.len()),
            ("product", model.dof_count(), y.len()),
            (
                "operator membranes",
                model.membranes.len(),
                self.tension.len(),
            ),
            ("operator DOFs", model.dof_count(), self.free.len()),
            (
                "operator hinges",
                model.bending.hinges.len(),
                self.hinge_rates.len(),
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
        // the fixed DOFs of p are excluded from the products (their columns are zero)
        let free = &mut self.free;
        free.copy_from_slice(p);
        fixed.zero_fixed(free);
        for ((y, p), d) in y
            .chunks_exact_mut(3)
            .zip(free.chunks_exact(3))
            .zip(node_diagonal)
        {
            for i in 0..3 {
                y[i] = d * p[i];
            }
        }
        for d in dashpots {
            let v = 3 * d.node as usize;
            let local = d.block() * Vector3::new(free[v], free[v + 1], free[v + 2]);
            y[v..v + 3]
                .iter_mut()
                .zip(local.iter())
                .for_each(|(y, b)| *y += b);
        }
        add_warped(&model.tets, &state.tets, scale, free, y);
        add_warped(&model.membranes, &state.membranes, scale, free, y);
        let tension = &self.tension;
        let membranes = &model.membranes;
        add_element_products(membranes.iter().map(|e| &e.nodes), free, y, |k, local| {
            let e = &membranes[k];
            let kt = e.gradient(local) * tension[k] * scale;
            e.grads.map(|g| kt * g)
        });
        // bending: the angles' rates ∇θ·p, their moments K (∇θ·p), back through ∇θ
        let (hinges, gradients) = (&model.bending.hinges, &state.hinges.gradients);
        for ((rate, h), grads) in self.hinge_rates.iter_mut().zip(hinges).zip(gradients) {
            *rate = h
                .nodes
                .iter()
                .zip(grads)
                .map(|(v, g)| {
                    let i = 3 * *v as usize;
                    g.dot(&Vector3::new(free[i], free[i + 1], free[i + 2]))
                })
                .sum();
        }
        model
            .bending
            .moments(&self.hinge_rates, &mut self.hinge_moments);
        let moments = &self.hinge_moments;
        add_element_products(hinges.iter().map(|h| &h.nodes), free, y, |k, _| {
            gradients[k].map(|g| g * (moments[k] * scale))
        });
        for (dof, (y, p)) in y.iter_mut().zip(p).enumerate() {
            if fixed.is_fixed(dof) {
                *y = *p;
            }
        }
        Ok(())
    }
}
