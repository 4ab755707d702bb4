//! Writing the patient package: the registered atlas as a simulator loads it, assembled in a
//! temporary sibling folder and renamed into place, so a package is complete or absent (an
//! older package is replaced only once the new one is whole). Same inputs and configuration
//! give the same bytes: nothing depends on the time, the machine or a path. The files it
//! holds and the manifest's fields are described once, in docs/package-format.md.

use std::path::{Path, PathBuf};

use nalgebra::Point3;

use super::ExportError;
use super::digest::file_digests;
use super::manifest::{
    AtlasRef, FORMAT, MANIFEST, Manifest, MechanicsSummary, MeshCounts, Registration, Units,
    VERSION, atlas_sha256,
};
use super::scene::{SCENE, SCENE_MESH, scene_string};
use super::sofa::SOFA_VERSIONS;
use crate::atlas::Atlas;
use crate::atlas::export::export_atlas;
use crate::atlas::format::{MANIFEST as ATLAS_MANIFEST, MESH as ATLAS_MESH, manifest_string};
use crate::config::Config;
use crate::ear::write_mrk_json;
use crate::image::dicom::patient::PatientIdentity;
use crate::io_util::{io_err, write_atomic, write_dir_atomic, write_json_file};
use crate::mechanics::Condition;
use crate::mesh::io::gmsh::write_msh;
use crate::register::atlas_fit::DeformRecord;
use crate::register::rigid::RigidFit;

/// The package folder's name in a run's output folder.
pub const PACKAGE_DIR: &str = "package";

/// Everything a package is made of.
#[derive(Debug, Clone)]
pub struct PackageInput<'a> {
    /// The atlas as the run used it (mirrored to the case's side), at its rest shape, under
    /// `condition`.
    pub atlas: &'a Atlas,
    /// The ear's condition `atlas` was made for (`mechanics::Condition::apply`).
    pub condition: Condition,
    /// The registered node positions (LPS mm).
    pub nodes: &'a [Point3<f64>],
    pub fit: &'a RigidFit,
    /// The deformable stage's record.
    pub deform: &'a DeformRecord,
    pub config: &'a Config,
    pub series_uid_sha256: Option<String>,
    pub inputs_sha256: String,
    /// The mechanical validation against the atlas, when it ran.
    pub mechanics: Option<MechanicsSummary>,
    /// Only with `--keep-phi`.
    pub patient: Option<PatientIdentity>,
}

/// Writes the package `dir` (replacing an older one) and returns its manifest.
pub fn write_package(dir: &Path, input: &PackageInput) -> Result<Manifest, ExportError> {
    write_dir_atomic(dir, |tmp| write_parts(tmp, input))
}

/// Writes `out/package/` and the run-time facts of writing it (seconds, Unix time, file
/// count, whether the patient fields were kept) beside it in `out/package.log.json`.
pub fn write_package_logged(out: &Path, input: &PackageInput) -> Result<Manifest, ExportError> {
    let t = std::time::Instant::now();
    let manifest = write_package(&out.join(PACKAGE_DIR), input)?;
    let written = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let log = serde_json::json!({
        "package": PACKAGE_DIR,
        "files": manifest.files.len() + 1,
        "seconds": t.elapsed().as_secs_f64(),
        "written_unix_s": written,
        "patient_fields_kept": input.patient.is_some(),
    });
    write_json_file(&out.join("package.log.json"), &log)?;
    Ok(manifest)
}

/// The registration summary of the manifest.
fn registration(fit: &RigidFit, deform: &DeformRecord) -> Registration {
    Registration {
        landmark_rms_mm: fit.rms_mm,
        landmark_residuals_mm: fit.residuals_mm.clone(),
        scale: fit.transform.scale,
        deform_status: deform.status.name().to_string(),
        deform_iterations: deform.iterations as u64,
        refine_stop: deform
            .refinement
            .as_ref()
            .map(|r| r.stop.name().to_string()),
        refine_rounds: deform.refinement.as_ref().map(|r| r.rounds as u64),
    }
}

fn write_parts(dir: &Path, input: &PackageInput) -> Result<Manifest, ExportError> {
    let atlas = input.atlas;
    let mut registered = atlas.clone();
    registered.mesh.tets.nodes = input.nodes.to_vec();
    // the package's atlas must read back: positive volumes, landmarks on the mesh
    crate::atlas::format::validate(&registered, &dir.join(ATLAS_MANIFEST))?;

    // surfaces, the VTU with material arrays, landmarks.{json,fcsv}
    export_atlas(atlas, input.nodes, dir)?;
    let vtu: PathBuf = dir.join(ATLAS_MESH);
    std::fs::rename(dir.join("volume.vtu"), &vtu).map_err(io_err(&vtu))?;
    let landmarks = atlas.landmark_positions(input.nodes);
    write_atomic(
        &dir.join("landmarks.mrk.json"),
        write_mrk_json(&landmarks).as_bytes(),
    )?;
    let names = registered
        .regions
        .iter()
        .map(|r| (r.label, r.name.clone()))
        .collect();
    write_msh(&dir.join(SCENE_MESH), &registered.mesh, &names)?;
    write_atomic(
        &dir.join(ATLAS_MANIFEST),
        manifest_string(&registered)?.as_bytes(),
    )?;
    write_atomic(
        &dir.join(SCENE),
        scene_string(atlas, input.nodes)?.as_bytes(),
    )?;

    let transform = input.fit.transform;
    let manifest = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        otoatlas_version: env!("CARGO_PKG_VERSION").into(),
        units: Units::ours(),
        sofa_versions: SOFA_VERSIONS.into(),
        side: atlas.side,
        atlas: AtlasRef {
            name: atlas.name.clone(),
            sha256: atlas_sha256(atlas)?,
        },
        condition: input.condition,
        series_uid_sha256: input.series_uid_sha256.clone(),
        inputs_sha256: input.inputs_sha256.clone(),
        config_sha256: input.config.sha256(),
        config: input.config.clone(),
        atlas_to_patient: transform,
        atlas_to_patient_matrix4: transform.matrix4().transpose().as_slice().to_vec(),
        registration: registration(input.fit, input.deform),
        mesh: MeshCounts {
            nodes: input.nodes.len(),
            tetrahedra: atlas.mesh.tets.tets.len(),
            triangles: atlas.mesh.triangles.len(),
        },
        mechanics: input.mechanics.clone(),
        patient: input.patient.clone(),
        files: file_digests(dir)?,
    };
    write_atomic(&dir.join(MANIFEST), manifest.to_json()?.as_bytes())?;
    Ok(manifest)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::default_atlas;
    use crate::export::verify_package;
    use crate::register::rigid::SimilarityTransform;

    #[test]
    fn a_refused_package_leaves_the_previous_one_whole_and_no_temporary() {
        let atlas = default_atlas().unwrap();
        let config = Config::default_config().unwrap();
        let fit = RigidFit {
            transform: SimilarityTransform::identity(),
            residuals_mm: vec![0.0; 3],
            rms_mm: 0.0,
        };
        let deform: DeformRecord = serde_json::from_value(serde_json::json!({
            "articulation": null,
            "status": { "status": "max_iterations" },
            "iterations": 0,
            "history": [],
            "eardrum": { "free_nodes": 0, "found_last_round": 0, "mean_offset_mm": 0.0 },
            "probe_step_mm": 0.2,
        }))
        .unwrap();
        let input = PackageInput {
            condition: Condition::Normal,
            atlas: &atlas,
            nodes: atlas.nodes(),
            fit: &fit,
            deform: &deform,
            config: &config,
            series_uid_sha256: None,
            inputs_sha256: "0".repeat(64),
            mechanics: None,
            patient: None,
        };
        let dir = tempfile::tempdir().unwrap();
        let package = dir.path().join(PACKAGE_DIR);
        let manifest = write_package(&package, &input).unwrap();
        assert_eq!(manifest.mesh.tetrahedra, atlas.mesh.tets.tets.len());
        let report = verify_package(&package).unwrap();
        assert!(report.passed(), "{}", report.text());
        let before = file_digests(&package).unwrap();
        // the nodes mirrored without re-orienting the elements: every tetrahedron inverted
        let inverted: Vec<Point3<f64>> = atlas
            .nodes()
            .iter()
            .map(|p| Point3::new(-p.x, p.y, p.z))
            .collect();
        let bad = PackageInput {
            nodes: &inverted,
            ..input.clone()
        };
        let err = write_package(&package, &bad).unwrap_err().to_string();
        assert!(err.contains("positive volume"), "{err}");
        assert_eq!(file_digests(&package).unwrap(), before);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, [PACKAGE_DIR]);
    }
}
