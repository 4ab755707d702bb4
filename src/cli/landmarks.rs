//! `otoatlas landmarks`: type the three landmarks of a case at a prompt and save them, or have
//! them proposed from the image (`--auto`).

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::json;

use super::Report;
use super::out_arg::check_out_file;
use super::series_arg::SeriesArg;
use crate::Error;
use crate::config::Config;
use crate::ear::{LandmarkName, Side, write_fcsv, write_json};
use crate::image::{self, Sampler};
use crate::io_util::write_atomic;
use crate::pipeline::Case;
use crate::pipeline::auto_landmarks::{proposal_files, proposal_record, propose};
use crate::progress::Reporter;
use crate::register::auto_landmarks::describe_poses_tried;
use crate::register::landmarks::{PromptInput, check_landmarks, prompt_landmarks};

/// Type the umbo, incudomalleolar and incudostapedial joints of a case (LPS mm or voxel
/// indices) and save them as Slicer .fcsv and our .json.
#[derive(Debug, Args)]
#[command(
    after_help = "Answers are 'x y z' in LPS mm or 'v i j k' in voxel indices; each is
echoed with the intensity there, and asked again if it is not understood or outside the image.
On a terminal each question offers the landmark proposed from the image (as --auto finds it):
Enter accepts it. On a pipe, one answer per line; with --suggest an empty line accepts the
proposal.

Without --out they are written into the case folder (CASE/landmarks.fcsv and .json), unless
it has a landmark file already: landmarks are replaced only where --out names them. The files
written beside --out FILE (the other format, the .mrk.json) replace files of those names only
when FILE itself exists: a set written together before.

Examples:
  otoatlas landmarks patient-07
  printf '1 2 3\\nv 10 20 30\\n4 5 6\\n' | otoatlas landmarks scan.nii.gz --out picks.fcsv
  otoatlas landmarks sample_cases/case-001 --auto --out proposed.fcsv

With --auto the chain is searched for in the image over every orientation and both sides, the
atlas registered onto it, and the landmarks read off the registered atlas; the files say so,
with a confidence per landmark (the share of the bone surface within 2 mm that the image
confirms) and the search's figures in the .json. A case whose image holds no ossicular chain
fails with exit code 2."
)]
pub struct LandmarksArgs {
    /// The case folder (or a bare image).
    pub case: PathBuf,
    /// Where to write: a .fcsv or .json path. The other format is written beside it (and a
    /// .mrk.json with --auto), replacing a file there only if FILE exists too.
    /// Default: CASE/landmarks.fcsv and CASE/landmarks.json, refused where the case has a
    /// landmark file already.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Propose the landmarks from the image instead of asking for them.
    #[arg(long)]
    pub auto: bool,
    /// Offer the landmarks proposed from the image as each answer's default (Enter accepts);
    /// always on a terminal, with this flag on a pipe too.
    #[arg(long, conflicts_with = "auto")]
    pub suggest: bool,
    /// The atlas to search for and register (default: the embedded atlas); with --auto or
    /// --suggest.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    #[command(flatten)]
    pub series: SeriesArg,
    /// Print machine-readable JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

fn out_paths(args: &LandmarksArgs, case: &Case) -> (PathBuf, PathBuf) {
    match &args.out {
        Some(p) if p.to_string_lossy().to_ascii_lowercase().ends_with(".json") => {
            (p.with_extension("fcsv"), p.clone())
        }
        Some(p) => (p.clone(), p.with_extension("json")),
        // a bare DICOM folder is the case itself: do not write into the series
        None if case.image == case.root => (
            PathBuf::from("landmarks.fcsv"),
            PathBuf::from("landmarks.json"),
        ),
        None => (
            case.root.join("landmarks.fcsv"),
            case.root.join("landmarks.json"),
        ),
    }
}

pub fn run(
    args: &LandmarksArgs,
    config: Option<&Path>,
    progress: &dyn Reporter,
) -> Result<Report, Error> {
    let config = Config::load(config)?;
    let case = Case::open(&args.case)?;
    let (fcsv, json_path) = out_paths(args, &case);
    check_out_file(&fcsv)?;
    check_default_out_is_free(args, &case, [&fcsv, &mrk_path(&fcsv), &json_path])?;
    check_companions_are_replaceable(args, &fcsv, &json_path)?;
    let loaded = image::load_reporting(
        &case.image,
        args.series.uid.as_deref(),
        &config.ingest,
        progress,
    )?;
    let sampler = Sampler::new(&loaded.volume).ok_or_else(|| {
        Error::Usage(format!(
            "{}: the image geometry is degenerate",
            case.image.display()
        ))
    })?;
    if args.auto {
        return propose_and_write(
            args,
            &case,
            &loaded,
            &sampler,
            &config,
            (&fcsv, &json_path),
            progress,
        );
    }
    let terminal = std::io::stdin().is_terminal();
    // the proposal as each answer's default; a case where none is found is still asked for
    let proposal = match args.suggest || terminal {
        true => {
            progress.log(&format!(
                "{}: proposing the landmarks from the image",
                case.id
            ));
            match propose(
                &loaded,
                &sampler,
                args.atlas.as_deref(),
                None,
                &config,
                progress,
            ) {
                Ok(p) => Some(p),
                Err(e) => {
                    progress.log(&format!("no proposal to offer: {e}"));
                    None
                }
            }
        }
        false => None,
    };
    let defaults = proposal.as_ref().map(|p| &p.landmarks);
    let input = if terminal {
        prompt_landmarks(PromptInput::Terminal, &sampler, defaults)?
    } else {
        let stdin = std::io::stdin();
        let mut lock = stdin.lock();
        let mut stderr = std::io::stderr();
        prompt_landmarks(
            PromptInput::Lines {
                input: &mut lock,
                echo: &mut stderr,
            },
            &sampler,
            defaults,
        )?
    };
    // the image's laterality, else the chain's handedness when a proposal was made
    let side = loaded
        .info
        .laterality
        .as_deref()
        .and_then(Side::parse)
        .or(proposal.as_ref().map(|p| p.side));
    // the distances against the embedded atlas's (a mirror does not change them); a suspected
    // swap is only warned about here: `run` asks the image
    let atlas = crate::atlas::load_atlas(None, side)?;
    let atlas_landmarks = atlas.landmark_positions(atlas.nodes());
    let warnings = check_landmarks(
        &input,
        Some(&sampler),
        Some(&atlas_landmarks),
        &config.landmarks,
    )?;
    for warning in &warnings {
        progress.log(&format!("landmark warning: {warning}"));
    }
    write_atomic(&fcsv, write_fcsv(&input).as_bytes())?;
    write_atomic(&json_path, write_json(&input, side).as_bytes())?;
    progress.log(&format!(
        "wrote {} and {}",
        fcsv.display(),
        json_path.display()
    ));
    let json = json!({
        "fcsv": fcsv,
        "json": json_path,
        "side": side.map(Side::as_str),
        "landmarks": {
            "umbo": input.umbo.coords.as_slice(),
            "incudomalleolar": input.incudomalleolar.coords.as_slice(),
            "incudostapedial": input.incudostapedial.coords.as_slice(),
        },
        "warnings": warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
    });
    let text = format!("wrote {} and {}\n", fcsv.display(), json_path.display());
    Ok(Report { text, json })
}

/// `--auto`: the proposal written as `.fcsv`, `.mrk.json` and `.json`.
fn propose_and_write(
    args: &LandmarksArgs,
    case: &Case,
    loaded: &image::LoadedImage,
    sampler: &Sampler,
    config: &Config,
    (fcsv, json_path): (&Path, &Path),
    progress: &dyn Reporter,
) -> Result<Report, Error> {
    progress.log(&format!(
        "{}: proposing the landmarks from the image",
        case.id
    ));
    let proposal = propose(
        loaded,
        sampler,
        args.atlas.as_deref(),
        None,
        config,
        progress,
    )?;
    let warning = proposal.side_warning();
    if let Some(w) = &warning {
        progress.log(&format!("landmark warning: {w}"));
    }
    let (fcsv_text, mrk_text, json_text) = proposal_files(&proposal);
    let mrk = mrk_path(fcsv);
    write_atomic(fcsv, fcsv_text.as_bytes())?;
    write_atomic(&mrk, mrk_text.as_bytes())?;
    write_atomic(json_path, json_text.as_bytes())?;
    let mut text = String::new();
    for name in LandmarkName::ALL {
        let p = proposal.landmarks.get(name);
        text.push_str(&format!(
            "{:<16} ({:8.3}, {:8.3}, {:8.3}) mm LPS, confidence {:.2}\n",
            name.key(),
            p.x,
            p.y,
            p.z,
            proposal.support_of(name).confidence
        ));
    }
    text.push_str(&format!(
        "{} ear (from the {}; the mirrored chain fits {:.0} % worse), found in {:.2} s, registered in {:.2} s{}\n{}wrote {}, {} and {}\n",
        proposal.side.as_str(),
        proposal.side_source.describe(),
        100.0 * proposal.search.side_margin,
        proposal.search.seconds,
        proposal.register_seconds,
        placed_again(&proposal.rescales),
        describe_poses_tried(&proposal.poses_tried)
            .map(|line| format!("{line}\n"))
            .unwrap_or_default(),
        fcsv.display(),
        mrk.display(),
        json_path.display()
    ));
    let json = json!({
        "fcsv": fcsv,
        "mrk_json": mrk,
        "json": json_path,
        "side": proposal.side.as_str(),
        "landmarks": {
            "umbo": proposal.landmarks.umbo.coords.as_slice(),
            "incudomalleolar": proposal.landmarks.incudomalleolar.coords.as_slice(),
            "incudostapedial": proposal.landmarks.incudostapedial.coords.as_slice(),
        },
        "proposal": proposal_record(&proposal),
        "warnings": warning.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
    });
    Ok(Report { text, json })
}

/// Refuses, before the image is read, to write where landmarks already are when no `--out`
/// names the place: a case's picks (placed by hand, perhaps over many minutes) are replaced
/// only on request.
fn check_default_out_is_free(
    args: &LandmarksArgs,
    case: &Case,
    written: [&Path; 3],
) -> Result<(), Error> {
    if args.out.is_some() {
        return Ok(());
    }
    let existing = case.landmarks.clone().or_else(|| {
        written
            .into_iter()
            .find(|p| p.exists())
            .map(Path::to_path_buf)
    });
    match existing {
        None => Ok(()),
        Some(file) => Err(Error::Usage(format!(
            "{} holds landmarks already, which are replaced only on request: give --out {} to replace them, or --out FILE to write elsewhere",
            file.display(),
            written[0].display()
        ))),
    }
}

/// Refuses, before the image is read, to replace a file that `--out` does not name but that is
/// written beside it (the other format; the `.mrk.json` with `--auto`), unless the named file
/// is there too: then they are a set written together (or the named one edited since), and
/// the request to replace it covers them. A lone `picks.json` of another origin is kept.
fn check_companions_are_replaceable(
    args: &LandmarksArgs,
    fcsv: &Path,
    json_path: &Path,
) -> Result<(), Error> {
    let Some(named) = &args.out else {
        return Ok(());
    };
    if named.exists() {
        return Ok(());
    }
    let mrk = mrk_path(fcsv);
    let companions = [fcsv, json_path]
        .into_iter()
        .filter(|p| *p != named.as_path())
        .chain(args.auto.then_some(mrk.as_path()));
    for companion in companions {
        if companion.exists() {
            return Err(Error::Usage(format!(
                "--out {} would also write {}, which exists without {} beside it and is replaced only on request: remove it, or give --out FILE with another name",
                named.display(),
                companion.display(),
                named.display(),
            )));
        }
    }
    Ok(())
}

/// The `.mrk.json` beside a `.fcsv`.
fn mrk_path(fcsv: &Path) -> PathBuf {
    let stem = fcsv
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    fcsv.with_file_name(format!("{stem}.mrk.json"))
}

/// ` (placed again at scale 1.010, 1.026)`, or nothing when the atlas was not placed again.
fn placed_again(scales: &[f64]) -> String {
    if scales.is_empty() {
        return String::new();
    }
    let list: Vec<String> = scales.iter().map(|s| format!("{s:.3}")).collect();
    format!(" (placed again at scale {})", list.join(", "))
}
