//! `otoatlas verify PACKAGE`: checks a patient package against its manifest and itself.

use std::path::PathBuf;

use clap::Args;

use super::Report;
use crate::Error;
use crate::export::verify_package;

/// Check a patient package: every file against the manifest's SHA-256, the manifest's fields,
/// the meshes (counts, no inverted element, mesh.msh = mesh.vtu), atlas.json, and the SOFA
/// scene's components and vectors against the mesh.
#[derive(Debug, Args)]
#[command(after_help = "Examples:
  otoatlas verify out/case-001/package
  otoatlas verify out/case-001/package --json

Exit codes: 0 the package is whole and consistent, 1 a fault (the report names each),
2 no such package folder.")]
pub struct VerifyArgs {
    /// The package folder (OUT/package of a run).
    pub package: PathBuf,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &VerifyArgs) -> Result<Report, Error> {
    let report = verify_package(&args.package)?;
    Ok(Report {
        text: report.text(),
        json: report.to_json(),
    })
}
