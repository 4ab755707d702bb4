//! The landmarks stage of `run`: the patient's landmarks (proposed from the image, a file, or
//! the prompt), the ear's side and where it came from, their checks against the image, and
//! the atlas mirrored to that side.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use super::{AutoLandmarks, Context, Ingested, Placed, RunOptions};
use crate::Error;
use crate::atlas::Atlas;
use crate::ear::{LandmarkFile, Side, read_landmarks, write_json_with};
use crate::image::{LoadedImage, Sampler};
use crate::io_util::write_atomic;
use crate::pipeline::auto_landmarks::{proposal_record, propose};
use crate::pipeline::stage::{Clock, Stage, artefact_path};
use crate::register::auto_landmarks::{Proposal, SideSource};
use crate::register::landmarks::{
    ImageCheck, LandmarkError, LandmarkWarning, PromptInput, check_landmarks_on_image,
    prompt_landmarks,
};

/// Landmarks and side: read (or prompted), checked against the image, the atlas mirrored to
/// the side.
pub(super) fn landmarks(
    cx: Context,
    ingested: &Ingested,
    sampler: &Sampler,
    clock: &mut Clock,
) -> Result<Placed, Error> {
    let Context {
        case,
        opts,
        config,
        progress,
    } = cx;
    progress.case_stage(&case.id, Stage::Landmarks.name());
    let out = &opts.out;
    let t = Instant::now();
    let (file, proposal) = if opts.from <= Stage::Landmarks {
        landmark_input(cx, ingested, sampler)?
    } else {
        (read_landmarks(&artefact_path(out, Stage::Landmarks))?, None)
    };
    let recorded = match opts.from <= Stage::Landmarks {
        true => Recorded::default(),
        false => read_recorded(&artefact_path(out, Stage::Landmarks)),
    };
    let proposal_record = match &proposal {
        Some(p) => Some(proposal_record(p)),
        // resumed: the record the landmarks stage kept, if they were proposed
        None => recorded.proposal,
    };
    let (side, mut side_source, side_warning) = side_of(opts, &file, &ingested.loaded)?;
    if opts.side.is_none()
        && let Some(recorded) = recorded.side_source
    {
        // resumed: the stage's file carries the side it settled on, wherever that came from
        side_source = recorded;
    }
    if let Some(p) = &proposal {
        side_source = p.side_source.describe();
    } else if let Some(source) = proposal_record
        .as_ref()
        .and_then(|r| serde_json::from_value::<SideSource>(r["side_source"].clone()).ok())
    {
        side_source = source.describe();
    }
    let atlas: Atlas = crate::atlas::load_atlas(opts.atlas.as_deref(), Some(side))?;
    let patient = file.landmarks;
    let image_check = ImageCheck {
        atlas: &atlas,
        sampler,
        step_mm: ingested.step,
        probe: &config.deform.probe,
        with_scale: config.rigid.with_scale,
    };
    let mut warnings = check_landmarks_on_image(&patient, &image_check, &config.landmarks)
        .map_err(|e| {
            // name the file to correct (none for landmarks typed at the prompt); proposed
            // landmarks come from no file, whatever the case folder holds
            if proposal.is_some() {
                return LandmarkError::Proposed(Box::new(e));
            }
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
    warnings.extend(side_warning);
    warnings.extend(proposal.as_ref().and_then(Proposal::side_warning));
    for warning in &warnings {
        progress.log(&format!("{}: landmark warning: {warning}", case.id));
    }
    if opts.from <= Stage::Landmarks {
        let mut extra = serde_json::Map::new();
        extra.insert("side_source".into(), side_source.into());
        if let Some(record) = &proposal_record {
            extra.insert("proposal".into(), record.clone());
        }
        write_atomic(
            &artefact_path(out, Stage::Landmarks),
            write_json_with(&patient, Some(side), extra).as_bytes(),
        )?;
        clock.record(Stage::Landmarks.name(), t);
    }
    progress.log(&format!(
        "{}: {} ear (from the {side_source}), atlas '{}'",
        case.id,
        side.as_str(),
        atlas.name
    ));
    Ok(Placed {
        side,
        side_source,
        atlas,
        patient,
        warnings,
        proposal: proposal_record,
    })
}

/// Refuses a `--side` that differs from the side a resumed run's landmarks stage recorded
/// (the later stages' artefacts were made with the atlas mirrored to that side), before the
/// run removes or writes anything.
pub(super) fn check_resumed_side(opts: &RunOptions) -> Result<(), Error> {
    let Some(given) = opts.side.filter(|_| opts.from > Stage::Landmarks) else {
        return Ok(());
    };
    let path = artefact_path(&opts.out, Stage::Landmarks);
    match read_landmarks(&path)?.side {
        Some(recorded) if recorded != given => Err(Error::Usage(format!(
            "--side {} disagrees with the {} ear the earlier run in {} settled on, which its \
             later stages were computed for; give --from landmarks (or ingest) to change the side",
            given.as_str(),
            recorded.as_str(),
            opts.out.display()
        ))),
        _ => Ok(()),
    }
}

/// What a landmarks artefact keeps beside the landmarks.
#[derive(Default)]
struct Recorded {
    /// Where its side came from (one of `side_of`'s sources).
    side_source: Option<&'static str>,
    /// The proposal record, if its landmarks were proposed.
    proposal: Option<serde_json::Value>,
}

fn read_recorded(path: &Path) -> Recorded {
    let doc = crate::io_util::read_text(path)
        .ok()
        .and_then(|text| serde_json::from_str::<serde_json::Value>(&text).ok());
    let Some(mut doc) = doc else {
        return Recorded::default();
    };
    Recorded {
        side_source: doc
            .get("side_source")
            .and_then(serde_json::Value::as_str)
            .and_then(|recorded| SIDE_SOURCES.into_iter().find(|s| *s == recorded)),
        proposal: doc.get_mut("proposal").map(serde_json::Value::take),
    }
}

/// The patient's landmarks: proposed from the image (see [`AutoLandmarks`]), `--landmarks`,
/// the case's file, or the prompt on a terminal; with the proposal when there is one.
fn landmark_input(
    cx: Context,
    ingested: &Ingested,
    sampler: &Sampler,
) -> Result<(LandmarkFile, Option<Proposal>), Error> {
    let (case, opts, progress) = (cx.case, cx.opts, cx.progress);
    let given = opts.landmarks.as_ref().or(case.landmarks.as_ref());
    let auto = match opts.auto_landmarks {
        AutoLandmarks::Always => true,
        AutoLandmarks::WhenMissing => given.is_none(),
        AutoLandmarks::Never => false,
    };
    let propose_here = || {
        propose(
            &ingested.loaded,
            sampler,
            opts.atlas.as_deref(),
            opts.side,
            cx.config,
            progress,
        )
    };
    if auto {
        if let Some(path) = given {
            progress.log(&format!(
                "{}: landmarks proposed from the image; {} is not read",
                case.id,
                path.display()
            ));
        }
        progress.log(&format!(
            "{}: proposing the landmarks from the image",
            case.id
        ));
        let proposal = propose_here()?;
        let file = LandmarkFile {
            landmarks: proposal.landmarks,
            side: Some(proposal.side),
            notes: vec!["proposed from the image".into()],
        };
        return Ok((file, Some(proposal)));
    }
    if let Some(path) = given {
        return Ok((read_landmarks(path)?, None));
    }
    if std::io::stdin().is_terminal() {
        progress.log("no landmark file: type the three landmarks (Enter accepts a proposal)");
        let proposal = propose_here();
        if let Err(e) = &proposal {
            progress.log(&format!("no proposal to offer: {e}"));
        }
        let defaults = proposal.as_ref().ok().map(|p| &p.landmarks);
        let landmarks = prompt_landmarks(PromptInput::Terminal, sampler, defaults)?;
        let file = LandmarkFile {
            landmarks,
            side: None,
            notes: vec!["typed at the prompt".into()],
        };
        return Ok((file, None));
    }
    Err(Error::Usage(format!(
        "{}: no landmarks (landmarks.fcsv, .mrk.json, .json or .csv); give --landmarks FILE, \
         pick them with `otoatlas landmarks {}`, give --auto-landmarks to have them proposed \
         from the image, or run on a terminal to be prompted",
        case.root.display(),
        case.root.display()
    )))
}

/// Where the side can come from: `--side`, the landmark file, the DICOM laterality.
const SIDE_SOURCES: [&str; 3] = ["--side", "landmark file", "DICOM laterality"];

/// The side of the ear, where it came from, and a warning when `--side` overrides a
/// disagreeing source. Without `--side`, a landmark file and a DICOM laterality that disagree
/// are an error naming both (a mirrored atlas on the wrong ear registers badly, silently).
fn side_of(
    opts: &RunOptions,
    file: &LandmarkFile,
    image: &LoadedImage,
) -> Result<(Side, &'static str, Option<LandmarkWarning>), Error> {
    let image_side = image.info.laterality.as_deref().and_then(Side::parse);
    let [given, from_file, from_image] = SIDE_SOURCES;
    let sources = [(from_file, file.side), (from_image, image_side)];
    if let Some(chosen) = opts.side {
        let against: Vec<String> = sources
            .iter()
            .filter_map(|(what, side)| side.filter(|s| *s != chosen).map(|s| (what, s)))
            .map(|(what, s)| format!("the {what} ({})", s.as_str()))
            .collect();
        let warning =
            (!against.is_empty()).then_some(LandmarkWarning::SideOverridden { chosen, against });
        return Ok((chosen, given, warning));
    }
    match (file.side, image_side) {
        (Some(f), Some(i)) if f != i => Err(Error::Usage(format!(
            "the landmark file says the {} ear, the image's DICOM laterality the {}: check              that they are of the same ear, and give --side to choose",
            f.as_str(),
            i.as_str()
        ))),
        (Some(f), _) => Ok((f, from_file, None)),
        (None, Some(i)) => Ok((i, from_image, None)),
        (None, None) => Err(Error::Usage(
            "the side of the ear is unknown: the image has no Laterality (0020,0060) or \
             ImageLaterality (0020,0062) and the landmark file does not say; give --side left or \
             --side right"
                .into(),
        )),
    }
}
