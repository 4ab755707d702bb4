//! The stages of `run` other than the landmarks (`landmarks.rs`): ingest, rigid, deform,
//! score, export and the package check, each timed on the run's clock, each resumable from
//! the artefact it leaves under `OUT/stages/` (`pipeline::stage`).

use std::collections::BTreeMap;
use std::time::Instant;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::{Context, Deformed, Ingested, Placed, Scored};
use crate::Error;
use crate::atlas::Atlas;
use crate::atlas::export::export_atlas;
use crate::image::{self, ImageRecord, Sampler};
use crate::io_util::write_json_file;
use crate::mechanics::Validation;
use crate::mesh::io::ply::{VertexAttributes, write_ply};
use crate::mesh::io::vtu::{VtuEncoding, read_vtu, write_vtp, write_vtu};
use crate::pipeline::mechanics::validate_registered;
use crate::pipeline::score::{Reference, StructureScore, score};
use crate::pipeline::stage::{Clock, Stage, artefact_path, read_record, run_or_resume};
use crate::register::DeformSettings;
use crate::register::atlas_fit::{DeformRecord, fit_landmarks};
use crate::register::deform::{DeformStatus, Steps};
use crate::register::placement::deform_placed_again;
use crate::register::rigid::{RigidFit, RigidRecord};
use crate::report::metrics::{Scores, StructureMetrics};

/// The export stage's record (`OUT/stages/export.json`): the files written under
/// `OUT/registered/`.
#[derive(Debug, Serialize, Deserialize)]
struct ExportRecord {
    files: Vec<String>,
}

/// Ingest: always read (the later stages need the voxels); on resume, the image must be the
/// one the earlier run saw.
pub(super) fn ingest(cx: Context, clock: &mut Clock) -> Result<Ingested, Error> {
    let Context {
        case,
        opts,
        config,
        progress,
    } = cx;
    progress.case_stage(&case.id, Stage::Ingest.name());
    let t = Instant::now();
    progress.log(&format!("{}: ingest {}", case.id, case.image.display()));
    let loaded = image::load_reporting(
        &case.image,
        case.series.as_deref(),
        &config.ingest,
        progress,
    )?;
    let digests = case.image_digests()?;
    let record = ImageRecord::of(&loaded, &case.image, digests.sha256());
    if opts.from <= Stage::Ingest {
        write_json_file(&artefact_path(&opts.out, Stage::Ingest), &record)?;
    } else {
        let before: ImageRecord = read_record(&opts.out, Stage::Ingest, opts.from)?;
        let differences = before.differences(&record);
        if !differences.is_empty() {
            return Err(Error::Usage(format!(
                "--from {}: {} is not the image the earlier run read from {} (they differ in {}); run from ingest",
                opts.from.name(),
                case.image.display(),
                before.image,
                differences.join(", ")
            )));
        }
    }
    let step = loaded.volume.smallest_spacing();
    clock.record(Stage::Ingest.name(), t);
    Ok(Ingested {
        loaded,
        record,
        digests,
        step,
    })
}

/// The rigid (or similarity) fit of the atlas landmarks onto the patient's.
pub(super) fn rigid(cx: Context, placed: &Placed, clock: &mut Clock) -> Result<RigidFit, Error> {
    let Context {
        case,
        opts,
        config,
        progress,
    } = cx;
    progress.case_stage(&case.id, Stage::Rigid.name());
    let with_scale = config.rigid.with_scale;
    let record: RigidRecord = run_or_resume(&opts.out, opts.from, Stage::Rigid, clock, || {
        let fit = fit_landmarks(&placed.atlas, &placed.patient, with_scale).ok_or_else(|| {
            Error::Usage("the landmarks are degenerate: no rigid fit exists".into())
        })?;
        Ok(RigidRecord::of(&fit, with_scale))
    })?;
    let fit = record.fit();
    progress.log(&format!(
        "{}: rigid fit, scale {:.3}, landmark RMS {:.3} mm",
        case.id, fit.transform.scale, fit.rms_mm
    ));
    Ok(fit)
}

/// The deformable stage (per-ossicle poses, FEM levels, surface level, eardrum); on resume,
/// its record and `stages/deform.vtu`.
pub(super) fn deform(
    cx: Context,
    atlas: &Atlas,
    rigid_nodes: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    clock: &mut Clock,
) -> Result<Deformed, Error> {
    let Context {
        case,
        opts,
        config,
        progress,
    } = cx;
    progress.case_stage(&case.id, Stage::Deform.name());
    let deform_vtu = opts.out.join("stages").join("deform.vtu");
    let mut resumed = true;
    let mut level_seconds = None;
    let mut nodes = Vec::new();
    let record: DeformRecord = run_or_resume(&opts.out, opts.from, Stage::Deform, clock, || {
        resumed = false;
        let settings = DeformSettings {
            articulate: &config.articulate,
            deform: &config.deform,
            refine: &config.refine,
            steps: Steps::Newton,
        };
        let registered =
            deform_placed_again(atlas, rigid_nodes, sampler, step, settings, progress)?;
        if let DeformStatus::InversionGuard { message } = &registered.deform.status {
            progress.log(&format!(
                "{}: deformable stage stopped at its last valid state: {message}",
                case.id
            ));
        }
        level_seconds = Some(registered.seconds);
        let mut mesh = atlas.mesh.clone();
        mesh.tets.nodes = registered.deform.positions.clone();
        write_vtu(&deform_vtu, &mesh, &[], VtuEncoding::Base64)?;
        nodes = registered.deform.positions.clone();
        Ok(registered.record(step))
    })?;
    if resumed {
        let (mesh, _) = read_vtu(&deform_vtu)?;
        if mesh.tets.nodes.len() != atlas.nodes().len() {
            return Err(Error::Usage(format!(
                "{}: {} nodes, the atlas has {}; run from deform",
                deform_vtu.display(),
                mesh.tets.nodes.len(),
                atlas.nodes().len()
            )));
        }
        nodes = mesh.tets.nodes;
    }
    Ok(Deformed {
        nodes,
        record,
        level_seconds,
    })
}

/// Scores the rigid and the registered atlas against the case's segmentation, when it has one.
pub(super) fn score_case(
    cx: Context,
    atlas: &Atlas,
    rigid_nodes: &[Point3<f64>],
    nodes: &[Point3<f64>],
    step: f64,
    clock: &mut Clock,
) -> Result<Option<Scored>, Error> {
    let Context {
        case,
        opts,
        config,
        progress,
    } = cx;
    progress.case_stage(&case.id, Stage::Score.name());
    let Some(segmentation) = &case.segmentation else {
        return Ok(None);
    };
    let mut in_memory = None;
    let scores: Scores = run_or_resume(&opts.out, opts.from, Stage::Score, clock, || {
        let reference = Reference::load(segmentation, &config.ingest)?;
        let [rigid, registered] = score(atlas, [rigid_nodes, nodes], &reference, step)?;
        let scores = scores_of(&rigid, &registered);
        in_memory = Some((registered, reference));
        Ok(scores)
    })?;
    Ok(Some(Scored { scores, in_memory }))
}

/// Per structure: the rigid-only and the registered surface distances, and the MASD
/// improvement of the deformable stage.
fn scores_of(
    rigid: &BTreeMap<String, StructureScore>,
    registered: &BTreeMap<String, StructureScore>,
) -> Scores {
    registered
        .iter()
        .map(|(name, r)| {
            let before = rigid.get(name).map(|s| s.distances);
            let improvement = before.as_ref().map(|b| 1.0 - r.distances.masd / b.masd);
            let metrics = StructureMetrics {
                registered: r.distances,
                rigid: before,
                masd_improvement: improvement,
                by_region: r.by_region.clone(),
                far_mm: Some(r.far_mm()),
            };
            (name.clone(), metrics)
        })
        .collect()
}

/// The registered atlas's surfaces, volume and landmarks, and each scored structure's
/// deviation map (PLY and VTP), under `OUT/registered/`.
pub(super) fn export(
    cx: Context,
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    scored: &Option<Scored>,
    clock: &mut Clock,
) -> Result<(), Error> {
    let (case, out, progress) = (cx.case, &cx.opts.out, cx.progress);
    progress.case_stage(&case.id, Stage::Export.name());
    let t = Instant::now();
    let registered_dir = out.join("registered");
    let mut files = export_atlas(atlas, nodes, &registered_dir)?.files;
    if let Some(Scored {
        in_memory: Some((per_structure, _)),
        ..
    }) = scored
    {
        for (name, s) in per_structure {
            let path = registered_dir.join("deviation").join(format!("{name}.ply"));
            let attrs = VertexAttributes {
                quality: Some(s.deviation.clone()),
                colors: Some(s.colours.clone()),
            };
            write_ply(&path, &s.surface, &attrs)?;
            // the same map for VTK and ParaView, whose PLY reader drops `quality`
            let vtp = path.with_extension("vtp");
            write_vtp(
                &vtp,
                &s.surface,
                &[("deviation_mm", s.deviation.as_slice())],
            )?;
            files.push(path);
            files.push(vtp);
        }
    }
    let record = ExportRecord {
        files: files.iter().map(|f| f.display().to_string()).collect(),
    };
    write_json_file(&artefact_path(out, Stage::Export), &record)?;
    clock.record(Stage::Export.name(), t);
    Ok(())
}

/// The registered package's mechanics against the atlas (`mechanics.json`), when
/// `[validate]` is on.
pub(super) fn validate(
    cx: Context,
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    clock: &mut Clock,
) -> Result<Option<Validation>, Error> {
    let (case, out, config, progress) = (cx.case, &cx.opts.out, cx.config, cx.progress);
    if !config.validate.enabled {
        // an earlier run's verdict was removed with its other outputs at the start
        return Ok(None);
    }
    progress.case_stage(&case.id, "validate");
    let t = Instant::now();
    let mut v = validate_registered(atlas, nodes, &config.validate, progress)?;
    // `atlas` is already the atlas under the run's condition; the record says which
    v.condition = cx.opts.condition;
    write_json_file(&out.join("mechanics.json"), &v)?;
    progress.log(&format!(
        "{}: mechanics against the atlas: {} ({} of {} gates failed)",
        case.id,
        if v.verdict.passed { "pass" } else { "FAIL" },
        v.verdict.failures().count(),
        v.verdict.gates.len()
    ));
    if let Some(why) = &v.mechanics.udsp.failure {
        progress.log(&format!(
            "{}: static pressure stopped short: {why}",
            case.id
        ));
    }
    clock.record("validate", t);
    Ok(Some(v))
}
