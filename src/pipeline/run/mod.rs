//! `run`: one case through every stage — ingest, landmarks, rigid, deform, score, export —
//! each timed, each leaving its artefact under `OUT/stages/` so that `--from STAGE` resumes
//! from what the earlier stages wrote. Outputs (`OUT/registered/`, `metrics.json`,
//! `report.html`, `timings.json`) are written atomically, file by file, only after the stages
//! succeeded; the patient package `OUT/package/` is written last, as a whole
//! (`export::package`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Point3;

mod landmarks;
mod outputs;
mod stages;

use super::case::{Case, ImageDigests};
use super::score::{Reference, StructureScore};
use super::stage::{Clock, Stage};
use crate::Error;
use crate::atlas::Atlas;
use crate::config::Config;
use crate::ear::{LandmarkName, Landmarks, Side};
use crate::export::MechanicsSummary;
use crate::export::package::{PackageInput, write_package_logged};
use crate::image::dicom::patient::read_patient_identity;
use crate::image::{ImageRecord, LoadedImage, Sampler};
use crate::io_util::{write_atomic, write_json_file};
use crate::mechanics::Condition;
use crate::progress::Reporter;
use crate::register::atlas_fit::{DeformRecord, LevelSeconds, place};
use crate::register::landmarks::{LandmarkWarning, check_against_registration, check_edge_support};
use crate::report::metrics::{CaseMetrics, LandmarkMetrics, MechanicsOutcome, Scores};
use crate::report::{Accuracy, CaseReportInput, Proposed, case_report_html};
use outputs::{check_out_is_a_run, remove_previous_outputs};
use stages::{deform, export, ingest, rigid, score_case, validate};

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
