//! `run`: one case through every stage — ingest, landmarks, rigid, deform, score, export —
//! each timed, each leaving its artefact under `OUT/stages/` so that `--from STAGE` resumes
//! from what the earlier stages wrote. Outputs (`OUT/registered/`, `metrics.json`,
//! `report.html`, `timings.json`) are written atomically, file by file, only after the stages
//! succeeded; the patient package `OUT/package/` is written last, as a whole
//! (`export::package`).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::Point3;
use serde_json::{Value, json};

use super::Case;
use super::score::{Reference, StructureScore, score};
use super::stage::Stage;
use crate::atlas::Atlas;
use crate::atlas::export::export_atlas;
use crate::config::Config;
use crate::ear::{LandmarkFile, read_landmarks, write_json};
use crate::ear::{Landmarks, Side};
use crate::export::MechanicsSummary;
use crate::export::package::{PACKAGE_DIR, PackageInput, write_package_logged};
use crate::image::dicom::patient::read_patient_identity;
use crate::image::{self, LoadedImage, Sampler};
use crate::io_util::write_atomic;
use crate::mesh::io::ply::{VertexAttributes, write_ply};
use crate::mesh::io::vtu::{VtuEncoding, read_vtu, write_vtu};
use crate::pipeline::mechanics::validate_registered;
use crate::register::atlas_fit::{deform_atlas, fit_landmarks, place};
use crate::register::deform::DeformStatus;
use crate::register::landmarks::{
    ImageCheck, LandmarkError, LandmarkWarning, PromptInput, check_landmarks_on_image,
    prompt_landmarks,
};
use crate::register::rigid::RigidFit;
use crate::report::{Accuracy, CaseReportInput, case_report_html};
use crate::{Error, progress};

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
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub metrics: Value,
    /// Seconds per step: the stages that ran, then "validate" (when on) and "report".
    pub timings: Vec<(&'static str, f64)>,
    pub out: PathBuf,
}

/// The side of the ear, where it came from, and a warning when `--side` overrides a
/// disagreeing source. Without `--side`, a landmark file and a DICOM laterality that disagree
/// are an error naming both (a mirrored atlas on the wrong ear registers badly, silently).
fn side_of(
    opts: &RunOptions,
    file: &LandmarkFile,
    image: &LoadedImage,
) -> Result<(Side, &'static str, Option<LandmarkWarning>), Error> {
    let image_side = image.info.laterality.as_deref().and_then(Side::parse);
    let sources = [
        ("landmark file", file.side),
        ("DICOM laterality", image_side),
    ];
    if let Some(chosen) = opts.side {
        let against: Vec<String> = sources
            .iter()
            .filter_map(|(what, side)| side.filter(|s| *s != chosen).map(|s| (what, s)))
            .map(|(what, s)| format!("the {what} ({})", s.as_str()))
            .collect();
        let warning =
            (!against.is_empty()).then_some(LandmarkWarning::SideOverridden { chosen, against });
        return Ok((chosen, "--side", warning));
    }
    match (file.side, image_side) {
        (Some(f), Some(i)) if f != i => Err(Error::Usage(format!(
            "the landmark file says the {} ear, the image's DICOM laterality the {}: check              that they are of the same ear, and give --side to choose",
            f.as_str(),
            i.as_str()
        ))),
        (Some(f), _) => Ok((f, "landmark file", None)),
        (None, Some(i)) => Ok((i, "DICOM laterality", None)),
        (None, None) => Err(Error::Usage(
            "the side of the ear is unknown: the image has no Laterality (0020,0060) or \
             ImageLaterality (0020,0062) and the landmark file does not say; give --side left or \
             --side right"
                .into(),
        )),
    }
}

fn artefact_path(out: &Path, stage: Stage) -> PathBuf {
    out.join("stages").join(stage.artefact())
}

fn write_json_file(path: &Path, value: &Value) -> Result<(), Error> {
    let text = serde_json::to_string_pretty(value).unwrap_or_default() + "\n";
    Ok(write_atomic(path, text.as_bytes())?)
}

fn read_artefact(out: &Path, stage: Stage, from: Stage) -> Result<Value, Error> {
    let path = artefact_path(out, stage);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Error::Usage(format!(
            "--from {}: cannot read {} from an earlier run ({e}); run from an earlier stage",
            from.name(),
            path.display()
        ))
    })?;
    serde_json::from_str(&text).map_err(|e| {
        Error::Usage(format!(
            "{}: not a {} artefact ({e}); run from an earlier stage",
            path.display(),
            stage.name()
        ))
    })
}

/// The patient's landmarks: `--landmarks`, the case's file, or the prompt on a terminal.
fn landmark_input(
    case: &Case,
    opts: &RunOptions,
    sampler: &Sampler,
) -> Result<LandmarkFile, Error> {
    if let Some(path) = opts.landmarks.as_ref().or(case.landmarks.as_ref()) {
        return Ok(read_landmarks(path)?);
    }
    if std::io::stdin().is_terminal() {
        progress::log("no landmark file: type the three landmarks");
        let landmarks = prompt_landmarks(PromptInput::Terminal, sampler)?;
        return Ok(LandmarkFile {
            landmarks,
            side: None,
            notes: vec!["typed at the prompt".into()],
        });
    }
    Err(Error::Usage(format!(
        "{}: no landmarks (landmarks.fcsv, .mrk.json, .json or .csv); give --landmarks FILE, \
         pick them with `otoatlas landmarks {}`, or run on a terminal to be prompted",
        case.root.display(),
        case.root.display()
    )))
}

/// The outputs a run writes after its stages (registered/, metrics, report, timings,
/// mechanics, the package and its log), removed before anything else: a re-run that fails
/// half-way never leaves an earlier run's package or report beside its own stages. The
/// stages' artefacts stay (`--from` reads them).
fn remove_previous_outputs(out: &Path) -> Result<(), Error> {
    for name in [
        PACKAGE_DIR,
        "package.log.json",
        "registered",
        "metrics.json",
        "report.html",
        "timings.json",
        "mechanics.json",
    ] {
        let path = out.join(name);
        let removed = match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(&path),
            Ok(_) => std::fs::remove_file(&path),
            Err(_) => continue,
        };
        removed.map_err(crate::io_util::io_err(&path))?;
    }
    Ok(())
}

fn geometry_json(loaded: &LoadedImage, source: &Path) -> Value {
    let v = &loaded.volume;
    json!({
        // a path that is not UTF-8 is written lossily (serialising it would fail)
        "image": source.display().to_string(),
        "format": loaded.info.format,
        "dims": v.dims,
        "spacing": v.spacing,
        "origin": [v.origin.x, v.origin.y, v.origin.z],
        "direction": v.direction_row_major(),
        "laterality": loaded.info.laterality,
        "series_uid_sha256": loaded.info.series_uid_sha256,
    })
}

fn points_json(l: &Landmarks) -> Value {
    json!({
        "umbo": [l.umbo.x, l.umbo.y, l.umbo.z],
        "incudomalleolar": [l.incudomalleolar.x, l.incudomalleolar.y, l.incudomalleolar.z],
        "incudostapedial": [l.incudostapedial.x, l.incudostapedial.y, l.incudostapedial.z],
    })
}

/// Runs `case` through the pipeline.
pub fn run_case(case: &Case, opts: &RunOptions, config: &Config) -> Result<RunSummary, Error> {
    let out = &opts.out;
    let mut timings: Vec<(Stage, f64)> = Vec::new();
    let started = Instant::now();
    remove_previous_outputs(out)?;

    progress::case_stage(&case.id, Stage::Ingest.name());
    // ingest: always read (the later stages need the voxels); on resume, the image must be
    // the one the earlier run saw
    let t = Instant::now();
    progress::log(format!("{}: ingest {}", case.id, case.image.display()));
    let loaded = image::load(&case.image, None, &config.ingest)?;
    let geometry = geometry_json(&loaded, &case.image);
    if opts.from <= Stage::Ingest {
        write_json_file(&artefact_path(out, Stage::Ingest), &geometry)?;
    } else {
        let before = read_artefact(out, Stage::Ingest, opts.from)?;
        if before != geometry {
            return Err(Error::Usage(format!(
                "--from {}: the image differs from the one in {}; run from ingest",
                opts.from.name(),
                artefact_path(out, Stage::Ingest).display()
            )));
        }
    }
    let sampler = Sampler::new(&loaded.volume).ok_or_else(|| {
        Error::Usage(format!(
            "{}: the image geometry is degenerate",
            case.image.display()
        ))
    })?;
    let step = loaded
        .volume
        .spacing
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    timings.push((Stage::Ingest, t.elapsed().as_secs_f64()));

    progress::case_stage(&case.id, Stage::Landmarks.name());
    // landmarks and side
    let t = Instant::now();
    let file = if opts.from <= Stage::Landmarks {
        landmark_input(case, opts, &sampler)?
    } else {
        read_landmarks(&artefact_path(out, Stage::Landmarks))?
    };
    let (side, side_source, side_warning) = side_of(opts, &file, &loaded)?;
    let atlas: Atlas = crate::atlas::load_atlas(opts.atlas.as_deref(), Some(side))?;
    let patient = file.landmarks;
    let image_check = ImageCheck {
        atlas: &atlas,
        sampler: &sampler,
        step_mm: step,
        probe: &config.deform.probe,
        with_scale: config.rigid.with_scale,
    };
    let mut landmark_warnings = check_landmarks_on_image(&patient, &image_check, &config.landmarks)
        .map_err(|e| {
            // name the file to correct (none for landmarks typed at the prompt)
            let path = match opts.from <= Stage::Landmarks {
                true => opts.landmarks.as_ref().or(case.landmarks.as_ref()).cloned(),
                false => Some(artefact_path(out, Stage::Landmarks)),
            };
            match path {
                Some(path) => LandmarkError::InFile {
                    path,
                    source: Box::new(e),
                },
                None => e,
            }
        })?;
    landmark_warnings.extend(side_warning);
    for warning in &landmark_warnings {
        progress::log(format!("{}: landmark warning: {warning}", case.id));
    }
    if opts.from <= Stage::Landmarks {
        write_atomic(
            &artefact_path(out, Stage::Landmarks),
            write_json(&patient, Some(side)).as_bytes(),
        )?;
        timings.push((Stage::Landmarks, t.elapsed().as_secs_f64()));
    }
    progress::log(format!(
        "{}: {} ear (from the {side_source}), atlas '{}'",
        case.id,
        side.as_str(),
        atlas.name
    ));

    progress::case_stage(&case.id, Stage::Rigid.name());
    // rigid
    let t = Instant::now();
    let fit: RigidFit = if opts.from <= Stage::Rigid {
        let fit = fit_landmarks(&atlas, &patient, config.rigid.with_scale).ok_or_else(|| {
            Error::Usage("the landmarks are degenerate: no rigid fit exists".into())
        })?;
        let value = json!({
            "atlas_to_patient": fit.transform,
            "matrix4": fit.transform.matrix4().transpose().as_slice(),
            "residuals_mm": fit.residuals_mm,
            "rms_mm": fit.rms_mm,
            "with_scale": config.rigid.with_scale,
        });
        write_json_file(&artefact_path(out, Stage::Rigid), &value)?;
        timings.push((Stage::Rigid, t.elapsed().as_secs_f64()));
        fit
    } else {
        let v = read_artefact(out, Stage::Rigid, opts.from)?;
        RigidFit {
            transform: serde_json::from_value(v["atlas_to_patient"].clone())
                .map_err(|e| Error::Usage(format!("stages/rigid.json: atlas_to_patient: {e}")))?,
            residuals_mm: serde_json::from_value(v["residuals_mm"].clone()).unwrap_or_default(),
            rms_mm: v["rms_mm"].as_f64().unwrap_or(f64::NAN),
        }
    };
    progress::log(format!(
        "{}: rigid fit, scale {:.3}, landmark RMS {:.3} mm",
        case.id, fit.transform.scale, fit.rms_mm
    ));
    let placed = place(&atlas, &fit);

    progress::case_stage(&case.id, Stage::Deform.name());
    // deform
    let t = Instant::now();
    let deform_vtu = out.join("stages").join("deform.vtu");
    // each level's wall time, for timings.json (the stage's record stays deterministic)
    let mut level_seconds = None;
    let (nodes, deform_json): (Vec<Point3<f64>>, Value) = if opts.from <= Stage::Deform {
        let registered = deform_atlas(
            &atlas,
            &placed,
            &sampler,
            step,
            &config.articulate,
            &config.deform,
            &config.refine,
        )?;
        let (result, eardrum) = (registered.deform, registered.eardrum);
        if let DeformStatus::InversionGuard { message } = &result.status {
            progress::log(format!(
                "{}: deformable stage stopped at its last valid state: {message}",
                case.id
            ));
        }
        let value = json!({
            "articulation": registered.articulation,
            "status": result.status,
            "iterations": result.history.len(),
            "history": result.history,
            "refinement": registered.refinement,
            "eardrum": eardrum,
            "probe_step_mm": step,
        });
        level_seconds = Some(registered.seconds);
        let mut mesh = atlas.mesh.clone();
        mesh.tets.nodes = result.positions.clone();
        write_vtu(&deform_vtu, &mesh, &[], VtuEncoding::Base64)?;
        write_json_file(&artefact_path(out, Stage::Deform), &value)?;
        timings.push((Stage::Deform, t.elapsed().as_secs_f64()));
        (result.positions, value)
    } else {
        let value = read_artefact(out, Stage::Deform, opts.from)?;
        let (mesh, _) = read_vtu(&deform_vtu)?;
        if mesh.tets.nodes.len() != atlas.nodes().len() {
            return Err(Error::Usage(format!(
                "{}: {} nodes, the atlas has {}; run from deform",
                deform_vtu.display(),
                mesh.tets.nodes.len(),
                atlas.nodes().len()
            )));
        }
        (mesh.tets.nodes, value)
    };

    progress::case_stage(&case.id, Stage::Score.name());
    // score (with a segmentation)
    let t = Instant::now();
    let mut reference = None;
    let scores = match &case.segmentation {
        Some(seg) if opts.from <= Stage::Score => {
            let reference = reference.insert(Reference::load(seg, &config.ingest)?);
            let rigid = score(&atlas, &placed, reference, step)?;
            let registered = score(&atlas, &nodes, reference, step)?;
            let value = scores_json(&rigid, &registered);
            write_json_file(&artefact_path(out, Stage::Score), &value)?;
            timings.push((Stage::Score, t.elapsed().as_secs_f64()));
            Some((value, registered))
        }
        Some(_) => Some((
            read_artefact(out, Stage::Score, opts.from)?,
            Default::default(),
        )),
        None => None,
    };

    progress::case_stage(&case.id, Stage::Export.name());
    // export
    let t = Instant::now();
    let registered_dir = out.join("registered");
    let mut files = export_atlas(&atlas, &nodes, &registered_dir)?.files;
    if let Some((_, per_structure)) = &scores {
        for (name, s) in per_structure {
            let path = registered_dir.join("deviation").join(format!("{name}.ply"));
            let attrs = VertexAttributes {
                quality: Some(s.deviation.clone()),
                colors: Some(s.colours.clone()),
            };
            write_ply(&path, &s.surface, &attrs)?;
            files.push(path);
        }
    }
    write_json_file(
        &artefact_path(out, Stage::Export),
        &json!({ "files": files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>() }),
    )?;
    timings.push((Stage::Export, t.elapsed().as_secs_f64()));

    let mut stage_times: Vec<(&'static str, f64)> =
        timings.iter().map(|(s, t)| (s.name(), *t)).collect();
    let mechanics_path = out.join("mechanics.json");
    let validation = if config.validate.enabled {
        progress::case_stage(&case.id, "validate");
        let t = Instant::now();
        let v = validate_registered(&atlas, &nodes, &config.validate)?;
        write_json_file(
            &mechanics_path,
            &serde_json::to_value(&v).unwrap_or_default(),
        )?;
        progress::log(format!(
            "{}: mechanics against the atlas: {} ({} of {} gates failed)",
            case.id,
            if v.verdict.passed { "pass" } else { "FAIL" },
            v.verdict.failures().count(),
            v.verdict.gates.len()
        ));
        if let Some(why) = &v.mechanics.udsp.failure {
            progress::log(format!("{}: static pressure stopped short: {why}", case.id));
        }
        stage_times.push(("validate", t.elapsed().as_secs_f64()));
        Some(v)
    } else {
        // an earlier run's verdict was removed with its other outputs at the start
        None
    };
    let report = CaseReportInput {
        case_id: &case.id,
        image: &loaded,
        sampler: &sampler,
        side,
        side_source,
        atlas: &atlas,
        fit: &fit,
        landmark_warnings: &landmark_warnings,
        rigid_nodes: &placed,
        registered_nodes: &nodes,
        deform: &deform_json,
        accuracy: match (&scores, &reference) {
            (None, _) => Accuracy::NoSegmentation,
            (Some((value, _)), None) => Accuracy::Resumed { scores: value },
            (Some((value, per_structure)), Some(reference)) => Accuracy::Scored {
                scores: value,
                deviation: per_structure
                    .iter()
                    .map(|(name, s)| (name.as_str(), (&s.surface, s.deviation.as_slice())))
                    .collect(),
                reference: &reference.surfaces,
            },
        },
        mechanics: validation.as_ref(),
        timings: &stage_times,
        total_seconds: started.elapsed().as_secs_f64(),
    };
    let metrics = json!({
        "case": case.id,
        "side": side.as_str(),
        "side_source": side_source,
        "atlas": atlas.name,
        "image": geometry,
        "landmarks": {
            "patient": points_json(&patient),
            "registered": points_json(&atlas.landmark_positions(&nodes)),
        },
        "landmark_warnings": warnings_json(&landmark_warnings),
        "rigid": {
            "atlas_to_patient": fit.transform,
            "scale": fit.transform.scale,
            "residuals_mm": fit.residuals_mm,
            "rms_mm": fit.rms_mm,
        },
        "deform": deform_json,
        "scores": scores.as_ref().map(|(v, _)| v.clone()),
        "mechanics": validation.as_ref().map(|v| json!({
            "passed": v.verdict.passed,
            "gates": v.verdict.gates.len(),
            "failed": v.verdict.failures().map(|g| g.name.clone()).collect::<Vec<_>>(),
        })),
    });
    write_json_file(&out.join("metrics.json"), &metrics)?;
    let t = Instant::now();
    let report_path = out.join("report.html");
    let html = case_report_html(&report).map_err(|source| Error::Report {
        path: report_path.clone(),
        source,
    })?;
    write_atomic(&report_path, html.as_bytes())?;
    let mut timing_map = serde_json::Map::new();
    for (name, secs) in &stage_times {
        timing_map.insert((*name).into(), json!(secs));
    }
    // the package's own time is in package.log.json, written with it
    stage_times.push(("report", t.elapsed().as_secs_f64()));
    timing_map.insert("report".into(), json!(t.elapsed().as_secs_f64()));
    timing_map.insert("total".into(), json!(started.elapsed().as_secs_f64()));
    if let Some(levels) = level_seconds {
        timing_map.insert("deform_levels".into(), json!(levels));
    }
    write_json_file(&out.join("timings.json"), &Value::Object(timing_map))?;
    // keep last: a package is present only for a case that finished
    let patient = match opts.keep_phi {
        true => read_patient_identity(&case.image)?,
        false => None,
    };
    let package = PackageInput {
        atlas: &atlas,
        nodes: &nodes,
        fit: &fit,
        deform: &deform_json,
        config,
        series_uid_sha256: loaded.info.series_uid_sha256.clone(),
        inputs_sha256: case.inputs_sha256(opts.landmarks.as_deref())?,
        mechanics: validation.as_ref().map(MechanicsSummary::of),
        patient,
    };
    write_package_logged(out, &package)?;
    Ok(RunSummary {
        metrics,
        timings: stage_times,
        out: out.clone(),
    })
}

/// The landmark checks' warnings: each typed (`kind` and its figures) with its message.
fn warnings_json(warnings: &[LandmarkWarning]) -> Value {
    warnings
        .iter()
        .map(|w| {
            let mut value = serde_json::to_value(w).unwrap_or_default();
            if let Value::Object(map) = &mut value {
                map.insert("message".into(), json!(w.to_string()));
            }
            value
        })
        .collect()
}

/// Per structure: the rigid-only and the registered surface distances, and the MASD
/// improvement of the deformable stage.
fn scores_json(
    rigid: &std::collections::BTreeMap<String, StructureScore>,
    registered: &std::collections::BTreeMap<String, StructureScore>,
) -> Value {
    let mut map = serde_json::Map::new();
    for (name, r) in registered {
        let before = rigid.get(name).map(|s| &s.distances);
        let improvement = before.map(|b| 1.0 - r.distances.masd / b.masd);
        map.insert(
            name.clone(),
            json!({
                "registered": r.distances,
                "rigid": before,
                "masd_improvement": improvement,
            }),
        );
    }
    Value::Object(map)
}
