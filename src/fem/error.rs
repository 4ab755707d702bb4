//! Errors of the finite-element core: each names the element, node, material or degree of
//! freedom at fault and what was expected, so a caller can fix its input or its loads.

/// A finite-element model could not be built, assembled, factorised or solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FemError {
    #[error("{kind} material {index}: {field} = {value} is invalid (expected {expected})")]
    InvalidMaterial {
        kind: &'static str,
        index: usize,
        field: &'static str,
        value: f64,
        expected: &'static str,
    },
    #[error("{what}: length {found}, expected {expected}")]
    LengthMismatch {
        what: &'static str,
        expected: usize,
        found: usize,
    },
    #[error("{what} {index} is not finite")]
    NonFinite { what: &'static str, index: usize },
    #[error("{kind} {element}: node {node} out of range (the model has {n_nodes} nodes)")]
    NodeOutOfRange {
        kind: &'static str,
        element: usize,
        node: u32,
        n_nodes: usize,
    },
    #[error("{kind} {element}: node {node} appears twice")]
    RepeatedNode {
        kind: &'static str,
        element: usize,
        node: u32,
    },
    #[error("{kind} {element}: material index {index} out of range ({n_materials} materials)")]
    MaterialOutOfRange {
        kind: &'static str,
        element: usize,
        index: u32,
        n_materials: usize,
    },
    #[error("{kind} {element}: degenerate at rest ({measure_name} = {measure:e})")]
    DegenerateElement {
        kind: &'static str,
        element: usize,
        measure_name: &'static str,
        measure: f64,
    },
    #[error("{count} element(s) inverted or collapsed in the given state, first: {first}")]
    InvertedState { count: usize, first: ElementId },
    #[error(
        "the tangent matrix is not positive definite at pivot {pivot}: the system is under-constrained \
         (fix nodes or add springs so that no rigid motion is free) or the material is unstable"
    )]
    NotPositiveDefinite { pivot: usize },
    #[error("sparse factorisation failed: {message}")]
    Factorisation { message: String },
    #[error(
        "no admissible step after {halvings} halvings at iteration {iteration}: every trial state \
         inverts an element ({element} among others)"
    )]
    StepRejected {
        iteration: usize,
        halvings: usize,
        /// An element that the smallest trial step inverted.
        element: ElementId,
    },
    #[error(
        "not converged after {iterations} iterations: max nodal update {max_update:e} mm \
         (tolerance {tolerance:e} mm), out-of-balance force {relative_residual:e} of the load \
         (tolerance {residual_tolerance:e}; inf: not judged) (the positions hold the last \
         admissible iterate)"
    )]
    NotConverged {
        iterations: usize,
        max_update: f64,
        tolerance: f64,
        /// |out-of-balance force| / |load| at the last iterate whose update was small enough
        /// (inf if none was).
        relative_residual: f64,
        residual_tolerance: f64,
    },
    #[error(
        "preconditioned conjugate gradients: relative residual {residual:e} > tolerance \
         {tolerance:e} after {iterations} iterations"
    )]
    IterativeNotConverged {
        iterations: usize,
        residual: f64,
        tolerance: f64,
    },
    #[error("{what} refers to node {node}, out of range (the model has {n_nodes} nodes)")]
    BadNodeReference {
        what: &'static str,
        node: u32,
        n_nodes: usize,
    },
    #[error("{what} = {value} is invalid (expected {expected})")]
    InvalidParameter {
        what: &'static str,
        value: f64,
        expected: &'static str,
    },
}

/// Which element: the index within the tetrahedra or within the membrane triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElementId {
    Tet(usize),
    Membrane(usize),
}

impl std::fmt::Display for ElementId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ElementId::Tet(i) => write!(f, "tetrahedron {i}"),
            ElementId::Membrane(i) => write!(f, "membrane triangle {i}"),
        }
    }
}
