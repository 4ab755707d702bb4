//! The PACKAGE argument of `validate` and `simulate`: a run's patient package, checked whole
//! first (as `otoatlas verify` does, which also reads the atlas it contains) so that no
//! command computes on a half-written or altered package, and paired with the atlas it was
//! registered from (identified by the SHA-256 in its manifest).

use std::path::Path;

use crate::Error;
use crate::atlas::{Atlas, load_atlas};
use crate::export::{Manifest, atlas_sha256, verify_package};

/// A verified package: its registered atlas and its manifest.
pub struct Package {
    pub atlas: Atlas,
    pub manifest: Manifest,
}

/// Verifies and reads the package in `dir`.
pub fn open_package(dir: &Path) -> Result<Package, Error> {
    let report = verify_package(dir)?;
    match (report.passed(), report.manifest, report.atlas) {
        (true, Some(manifest), Some(atlas)) => Ok(Package { atlas, manifest }),
        _ => {
            let faults: Vec<String> = report
                .faults
                .iter()
                .map(|f| format!("{} {}: {}", f.check, f.file, f.message))
                .collect();
            Err(Error::Usage(format!(
                "{}: not a whole patient package ({}); `otoatlas verify {}` lists the faults",
                dir.display(),
                faults.join("; "),
                dir.display()
            )))
        }
    }
}

/// The atlas `package` was registered from: the folder `reference_dir`, or the embedded
/// default atlas, on the package's side; its SHA-256 must be the one in the manifest.
pub fn source_atlas(package: &Package, reference_dir: Option<&Path>) -> Result<Atlas, Error> {
    let m = &package.manifest;
    let atlas = load_atlas(reference_dir, Some(m.side))?;
    let digest = atlas_sha256(&atlas)?;
    if digest != m.atlas.sha256 {
        let given = reference_dir.map_or("the embedded default atlas".to_string(), |d| {
            format!("--reference {}", d.display())
        });
        return Err(Error::Usage(format!(
            "the package was registered from atlas '{}' (SHA-256 {}), but {given} is atlas \
             '{}' (SHA-256 {digest}); pass that atlas's folder with --reference",
            m.atlas.name, m.atlas.sha256, atlas.name
        )));
    }
    Ok(atlas)
}
