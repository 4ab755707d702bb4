//! Meshes: triangle surfaces, tetrahedral volumes, the labelled-domain interface the mesher
//! consumes, and mesh file formats.

pub mod domain;
pub mod isosurface;
pub mod shapes;
pub mod surface;

pub use domain::LabelledDomain;
pub use surface::TriMesh;
