//! `run`: one case through every stage — ingest, landmarks, rigid, deform, score, export —
//! each timed, each leaving its artefact under `OUT/stages/` so that `--from STAGE` resumes
//! from what the earlier stages wrote. Outputs (`OUT/registered/`, `metrics.json`,
//! `report.html`, `timings.json`) are written atomically, file by file, only after the stages
//! succeeded; the patient package `OUT/package/` is written last, as a whole
//! (`export::package`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use std::collections::BTreeMap;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

mod landmarks;

use super::case::{Case, ImageDigests};
use super::score::{Reference, StructureScore, score};
use super::stage::{Clock, Stage, artefact_path, read_record, run_or_resume};
use crate::Error;
use crate::atlas::Atlas;
use crate::atlas::export::export_atlas;
use crate::config::Config;
use crate::ear::{LandmarkName, Landmarks, Side};
use crate::export::MechanicsSummary;
use crate::export::package::{PACKAGE_DIR, PackageInput, write_package_logged};
use crate::image::dicom::patient::read_patient_identity;
use crate::image::{self, ImageRecord, LoadedImage, Sampler};
use crate::io_util::{write_atomic, write_json_file};
use crate::mechanics::{Condition, Validation};
use crate::mesh::io::ply::{VertexAttributes, write_ply};
use crate::mesh::io::vtu::{VtuEncoding, read_vtu, write_vtp, write_vtu};
use crate::pipeline::mechanics::validate_registered;
use crate::progress::Reporter;
use crate::register::DeformSettings;
use crate::register::atlas_fit::{DeformRecord, LevelSeconds, fit_landmarks, place};
use crate::register::deform::{DeformStatus, Steps};
use crate::register::landmarks::{LandmarkWarning, check_against_registration, check_edge_support};
use crate::register::placement::deform_placed_again;
use crate::register::rigid::{RigidFit, RigidRecord};
use crate::report::metrics::{
    CaseMetrics, LandmarkMetrics, MechanicsOutcome, Scores, StructureMetrics,
};
use crate::report::{Accuracy, CaseReportInput, Proposed, case_report_html};

/// What `run` is asked to do besides the case and the configuration.
#[derive(Debug, Clone)]
pub struct RunOptions {
    pub out: PathBuf,
    /// The first stage to run; earlier stages are read from `OUT/stages/`.
    pub from: Stage,
    /// A landmark file that replaces the case's.
    pub landmarks: Option<PathBuf>,
    /// An atlas folder instead of the embedded default.
    pub atlas: Option<PathBuf>,
    /// The side of the ear, overriding the landmark file and the DICOM.
    pub side: Option<Side>,
    /// Carry the DICOM patient fields into the package's manifest (never otherwise).
    pub keep_phi: bool,
    /// When the landmarks are proposed from the image instead of read.
    pub auto_landmarks: AutoLandmarks,
    /// The ear's condition the package models (`mechanics::Condition`): the registration
    /// is the same; the package's materials, and the atlas its mechanics are checked
    /// against, are the atlas's under it.
    pub condition: Condition,
}

/// When `run` proposes the landmarks from the image (`pipeline::auto_landmarks`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AutoLandmarks {
    /// Never: a landmark file or the prompt.
    Never,
    /// Always (`run --auto-landmarks`); a case's own landmark file is not read.
    Always,
    /// When the case has no landmark file (`batch`).
    WhenMissing,
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub metrics: CaseMetrics,
    /// Seconds per step: the stages that ran, then "validate" (when on) and "report".
    pub timings: Vec<(&'static str, f64)>,
    pub out: PathBuf,
}

/// The outputs a run writes after its stages (registered/, metrics, report, timings,
/// mechanics, the package and its log), removed as soon as the image is read (and, resumed,
/// found to be the earlier run's): a re-run that fails half-way never leaves an earlier
/// run's package or report beside its own stages, and a resumed run refused for another side
/// or another image leaves them as they were. The stages' artefacts stay (`--from` reads
/// them).
fn remove_previous_outputs(out: &Path) -> Result<(), Error> {
    for (path, metadata) in previous_outputs(out) {
        let removed = match metadata.is_dir() {
            true => std::fs::remove_dir_all(&path),
            false => std::fs::remove_file(&path),
        };
        removed.map_err(crate::io_util::io_err(&path))?;
    }
    Ok(())
}

/// The outputs of an earlier run present in `out` (`remove_previous_outputs`).
fn previous_outputs(out: &Path) -> Vec<(PathBuf, std::fs::Metadata)> {
    [
        PACKAGE_DIR,
        "package.log.json",
        "registered",
        "metrics.json",
        "report.html",
        "timings.json",
        "mechanics.json",
    ]
    .iter()
    .map(|name| out.join(name))
    .filter_map(|path| std::fs::symlink_metadata(&path).ok().map(|m| (path, m)))
    .collect()
}

/// Refuses an `out` that holds what a run would replace (`previous_outputs`) but is not an
/// earlier run's output folder (it has no `stages/ingest.json`, the first thing a run
/// writes): a report, a `registered/` folder or a package of the user's own, in a folder
/// given as `--out` by mistake, is never removed.
fn check_out_is_a_run(out: &Path) -> Result<(), Error> {
    let found = previous_outputs(out);
    if found.is_empty() || artefact_path(out, Stage::Ingest).is_file() {
        return Ok(());
    }
    let names: Vec<String> = found
        .iter()
        .filter_map(|(path, _)| path.file_name())
        .map(|name| name.to_string_lossy().into_owned())
        .collect();
    Err(Error::Usage(format!(
        "--out {}: holds {} but no stages/ingest.json, so it is not an earlier run's output, and a run would replace them; expected a new or empty folder, or a previous run's",
        out.display(),
        names.join(", ")
    )))
}

/// What every stage of one run reads.
#[derive(Clone, Copy)]
struct Context<'a> {
    case: &'a Case,
    opts: &'a RunOptions,
    config: &'a Config,
    progress: &'a dyn Reporter,
}

/// The image as the later stages use it.
struct Ingested {
    loaded: LoadedImage,
    record: ImageRecord,
    /// Its files' digests (the record's and the package's inputs digest).
    digests: ImageDigests,
    /// The probe step: the smallest voxel spacing [mm].
    step: f64,
}

/// The landmarks stage's outcome: the side, the atlas mirrored to it, the patient's landmarks
/// and what the checks found unusual.
struct Placed {
    side: Side,
    side_source: &'static str,
    atlas: Atlas,
    patient: Landmarks,
    warnings: Vec<LandmarkWarning>,
    /// How the landmarks were proposed from the image, when they were
    /// (`pipeline::auto_landmarks::proposal_record`).
    proposal: Option<serde_json::Value>,
}

/// The deformable stage's outcome.
struct Deformed {
    nodes: Vec<Point3<f64>>,
    record: DeformRecord,
    /// Each level's wall time (only when the stage ran in this run).
    level_seconds: Option<LevelSeconds>,
}

/// The score stage's outcome, when the case has a segmentation.
struct Scored {
    scores: Scores,
    /// Scored in this run: each structure's deviation map and the segmentation read.
    in_memory: Option<(BTreeMap<String, StructureScore>, Reference)>,
}

/// The export stage's record (`OUT/stages/export.json`): the files written under
/// `OUT/registered/`.
#[derive(Debug, Serialize, Deserialize)]
struct ExportRecord {
    files: Vec<String>,
}

/// Runs `case` through the pipeline, reporting to `progress`.
pub fn run_case(
    case: &Case,
    opts: &RunOptions,
    config: &Config,
    progress: &dyn Reporter,
) -> Result<RunSummary, Error> {
    let cx = Context {
        case,
        opts,
        config,
        progress,
    };
    let out = &opts.out;
    let started = Instant::now();
    let mut clock = Clock::default();
    landmarks::check_resumed_side(opts)?;
    check_out_is_a_run(out)?;
    let ingested = ingest(cx, &mut clock)?;
    remove_previous_outputs(out)?;
    let sampler = Sampler::new(&ingested.loaded.volume).ok_or_else(|| {
        Error::Usage(format!(
            "{}: the image geometry is degenerate",
            case.image.display()
        ))
    })?;
    let mut placed = landmarks::landmarks(cx, &ingested, &sampler, &mut clock)?;
    let fit = rigid(cx, &placed, &mut clock)?;
    let rigid_nodes = place(&placed.atlas, &fit.transform);
    let deformed = deform(
        cx,
        &placed.atlas,
        &rigid_nodes,
        &sampler,
        ingested.step,
        &mut clock,
    )?;
    let registered_landmarks = placed.atlas.landmark_positions(&deformed.nodes);
    if placed.proposal.is_none() {
        // the image's word on the picks: where the registered atlas put each landmark
        let far = check_against_registration(&placed.patient, &registered_landmarks);
        for warning in &far {
            progress.log(&format!("{}: landmark warning: {warning}", case.id));
        }
        placed.warnings.extend(far);
    }
    // the image's word on the registered stapes's pose
    if let Some(weak) = check_edge_support(&deformed.record.edge_support) {
        progress.log(&format!("{}: registration warning: {weak}", case.id));
        placed.warnings.push(weak);
    }
    let scored = score_case(
        cx,
        &placed.atlas,
        &rigid_nodes,
        &deformed.nodes,
        ingested.step,
        &mut clock,
    )?;
    export(cx, &placed.atlas, &deformed.nodes, &scored, &mut clock)?;
    // the condition changes materials only: registration and scoring used the atlas as it is
    let ear = cx.opts.condition.apply(&placed.atlas)?;
    let validation = validate(cx, &ear, &deformed.nodes, &mut clock)?;
    let metrics = CaseMetrics {
        case: case.id.clone(),
        side: placed.side,
        side_source: placed.side_source.to_string(),
        atlas: placed.atlas.name.clone(),
        condition: cx.opts.condition,
        image: ingested.record.clone(),
        landmarks: LandmarkMetrics {
            patient: (&placed.patient).into(),
            registered: (&registered_landmarks).into(),
            proposal: placed.proposal.clone(),
        },
        landmark_warnings: placed.warnings.iter().map(Into::into).collect(),
        rigid: (&fit).into(),
        deform: deformed.record.clone(),
        scores: scored.as_ref().map(|s| s.scores.clone()),
        mechanics: validation.as_ref().map(|v| MechanicsOutcome {
            passed: v.verdict.passed,
            gates: v.verdict.gates.len(),
            failed: v.verdict.failures().map(|g| g.name.clone()).collect(),
        }),
    };
    write_json_file(&out.join("metrics.json"), &metrics)?;
    let report = CaseReportInput {
        case_id: &case.id,
        image: &ingested.loaded,
        sampler: &sampler,
        side: placed.side,
        side_source: placed.side_source,
        atlas: &placed.atlas,
        condition: cx.opts.condition,
        fit: &fit,
        landmark_warnings: &placed.warnings,
        landmarks: &placed.patient,
        proposed: placed.proposal.as_ref().map(|record| Proposed {
            confidence: LandmarkName::ALL.map(|name| {
                record["support"][name.key()]["confidence"]
                    .as_f64()
                    .unwrap_or(f64::NAN)
            }),
            // a proposal recorded before poses were judged has none to show
            poses_tried: serde_json::from_value(record["poses_tried"].clone()).unwrap_or_default(),
        }),
        rigid_nodes: &rigid_nodes,
        registered_nodes: &deformed.nodes,
        deform: &deformed.record,
        accuracy: match &scored {
            None => Accuracy::NoSegmentation,
            Some(Scored {
                scores,
                in_memory: None,
            }) => Accuracy::Resumed { scores },
            Some(Scored {
                scores,
                in_memory: Some((per_structure, reference)),
            }) => Accuracy::Scored {
                scores,
                deviation: per_structure
                    .iter()
                    .map(|(name, s)| (name.as_str(), (&s.surface, s.deviation.as_slice())))
                    .collect(),
                reference: &reference.surfaces,
            },
        },
        mechanics: validation.as_ref(),
        timings: &clock.0,
        total_seconds: started.elapsed().as_secs_f64(),
    };
    let t = Instant::now();
    report_case(out, &report)?;
    // the package's own time is in package.log.json, written with it
    clock.record("report", t);
    write_timings(out, &clock, started, deformed.level_seconds)?;
    // keep last: a package is present only for a case that finished
    let patient = match opts.keep_phi {
        true => read_patient_identity(
            &case.image,
            ingested.loaded.info.series_uid_sha256.as_deref(),
        )?,
        false => None,
    };
    let package = PackageInput {
        atlas: &ear,
        condition: cx.opts.condition,
        nodes: &deformed.nodes,
        fit: &fit,
        deform: &deformed.record,
        config,
        series_uid_sha256: ingested.loaded.info.series_uid_sha256.clone(),
        inputs_sha256: case.inputs_sha256(&ingested.digests, opts.landmarks.as_deref())?,
        mechanics: validation.as_ref().map(MechanicsSummary::of),
        patient,
    };
    write_package_logged(out, &package)?;
    Ok(RunSummary {
        metrics,
        timings: clock.0,
        out: out.clone(),
    })
}

/// Ingest: always read (the later stages need the voxels); on resume, the image must be the
/// one the earlier run saw.
fn ingest(cx: Context, clock: &mut Clock) -> Result<Ingested, Error> {
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
fn rigid(cx: Context, placed: &Placed, clock: &mut Clock) -> Result<RigidFit, Error> {
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
fn deform(
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
fn score_case(
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
            };
            (name.clone(), metrics)
        })
        .collect()
}

/// The registered atlas's surfaces, volume and landmarks, and each scored structure's
/// deviation map (PLY and VTP), under `OUT/registered/`.
fn export(
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
fn validate(
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

/// `report.html`.
fn report_case(out: &Path, input: &CaseReportInput) -> Result<(), Error> {
    let path = out.join("report.html");
    let html = case_report_html(input).map_err(|source| Error::Report {
        path: path.clone(),
        source,
    })?;
    write_atomic(&path, html.as_bytes())?;
    Ok(())
}

/// `timings.json`: seconds per step, the whole run, and each level of the deformable stage.
fn write_timings(
    out: &Path,
    clock: &Clock,
    started: Instant,
    levels: Option<LevelSeconds>,
) -> Result<(), Error> {
    let mut timings = serde_json::Map::new();
    for (name, secs) in &clock.0 {
        timings.insert((*name).into(), (*secs).into());
    }
    timings.insert("total".into(), started.elapsed().as_secs_f64().into());
    if let Some(levels) = levels {
        timings.insert(
            "deform_levels".into(),
            serde_json::to_value(levels).unwrap_or_default(),
        );
    }
    Ok(write_json_file(&out.join("timings.json"), &timings)?)
}
