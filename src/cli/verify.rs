//! `otoatlas verify PACKAGE`: checks a patient package against its manifest and itself.

use std::path::PathBuf;

use clap::Args;

use super::Report;
use crate::Error;
use crate::atlas::read_atlas;
use crate::export::verify_package_against;

/// Check a patient package: every file against the manifest's SHA-256, the manifest's fields,
/// the meshes (counts, no inverted element, mesh.msh = mesh.vtu), each tetrahedron's shape
/// quality and its volume against the atlas it was registered from, atlas.json, and the SOFA
/// scene's components and vectors against the mesh.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  otoatlas verify out/case-001/package
  otoatlas verify out/case-001/package --json
  otoatlas verify out/case-001/package --atlas my-atlas

Exit codes: 0 the package is whole and consistent, 1 a fault (the report names each),
2 no such package folder.")]
pub struct VerifyArgs {
    /// The package folder (OUT/package of a run).
    pub package: PathBuf,
    /// The atlas folder the package was registered from, for the volume of each tetrahedron
    /// against its atlas counterpart (default: the embedded atlas, when the manifest names it).
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &VerifyArgs) -> Result<Report, Error> {
    let atlas = args.atlas.as_deref().map(read_atlas).transpose()?;
    let report = verify_package_against(&args.package, atlas.as_ref())?;
    Ok(Report {
        text: report.text(),
        json: report.to_json(),
    })
}
