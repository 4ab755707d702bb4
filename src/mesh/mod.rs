//! Meshes: triangle surfaces, tetrahedral volumes, the labelled-domain interface the mesher
//! consumes, and mesh file formats.

pub mod domain;
pub mod io;
pub mod isosurface;
pub mod mesher;
pub mod quality;
pub mod shapes;
pub mod spatial;
pub mod surface;
pub mod surface_repair;
pub mod tet;
pub mod topology;
pub mod union;

pub use domain::LabelledDomain;
pub use surface::TriMesh;
pub use tet::TetMesh;
