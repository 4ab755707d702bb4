//! Finite-element core: corotational linear tetrahedra (Müller & Gross 2004, SOFA
//! TetrahedronFEMForceField method="polar") and corotational CST membrane triangles, the
//! membrane's discrete-shell bending hinges, lumped masses, sparse assembly with a pattern
//! built once per mesh, a sparse Cholesky whose symbolic analysis is reused, a quasi-static
//! spring-equilibrium solver, point dashpots along one direction, and a linearised implicit Euler step (with a conjugate-gradient
//! solver preconditioned by an earlier factor), a follower pressure load and a complex
//! harmonic (frequency-domain) solver. Formulas: docs/fem.md.
//!
//! Units (mm-g-s): positions in mm, forces in µN, stiffness in µN/mm, Young's modulus and
//! stress in Pa (= µN/mm²), density in g/mm³, mass in g, time in s. Degrees of freedom are
//! ordered x, y, z per node. Sign convention: K = −∂f/∂x (positive semi-definite).
//! This module depends on no other otoatlas module.

mod anderson;
mod assembly;
pub(crate) mod bending;
mod cholesky;
mod complex_ldlt;
mod complex_symmetric;
mod dashpot;
mod dynamics;
mod element;
mod error;
mod fixed;
mod harmonic;
mod harmonic_sweep;
mod material;
mod membrane;
mod model;
mod operator;
mod pcg;
mod pressure;
mod reduced_pattern;
mod rigid;
mod rigid_statics;
mod rotation;
mod state;
mod static_problem;
mod static_unknowns;
mod statics;
mod tet;
mod variant;
pub(crate) mod vector_state;

pub use assembly::SparsePattern;
pub use cholesky::{FactorPrecision, SparseCholesky};
pub use dashpot::Dashpot;
pub use dynamics::{ImplicitEuler, Rayleigh, StepReport};
pub use error::{ElementId, FemError};
pub use fixed::FixedDofs;
pub use harmonic::{ComplexDisplacement, HarmonicSolver};
pub use harmonic_sweep::{Sweep, SweepOptions, SweepReport};
pub use material::{MembraneMaterial, TetMaterial};
pub use model::{Elements, FemModel, MembraneElements, TetElements};
pub use operator::StepOperator;
pub use pcg::Pcg;
pub use pressure::PressureLoad;
pub use rigid::RigidBodies;
pub use state::CorotationalState;
pub use static_problem::{Spring, StaticLoads, StaticOptions, StaticReport};
pub use statics::StaticSolver;
