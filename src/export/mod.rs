//! The patient package: the registered atlas as a simulator loads it (SOFA scene, Gmsh and
//! VTU meshes with region and material per element, the atlas's boundary conditions, surfaces,
//! landmarks) with a manifest that hashes every file, written atomically and
//! deterministically; and `verify`, which checks a package against its manifest and itself.
//! Layout and manifest fields: docs/package-format.md.

pub mod digest;
mod error;
pub mod manifest;
pub mod package;
pub mod scene;
mod scene_bending;
pub mod sofa;
pub mod verify;

pub use error::ExportError;
pub use manifest::{Manifest, MechanicsSummary, atlas_sha256};
pub use package::{PackageInput, write_package};
pub use verify::{Fault, VerifyReport, verify_package, verify_package_against};
