//! `otoatlas run`: register the atlas onto one case and write the patient model.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use clap::Args;

use super::Report;
use super::out_arg::check_out_dir;
use super::series_arg::SeriesArg;
use crate::Error;
use crate::config::Config;
use crate::ear::Side;
use crate::mechanics::Condition;
use crate::pipeline::{AutoLandmarks, Case, RunOptions, Stage, run_case};
use crate::progress::Reporter;

/// Register the atlas onto a case: ingest, landmarks, rigid, deform, score (with a
/// segmentation), export; then validate the package's mechanics against the atlas
/// ([validate] in the configuration) and write the report and the package.
#[derive(Debug, Args)]
#[command(
    after_help = "Outputs under OUT: package/ (the ready-to-simulate patient package, written
last; its files are described in docs/package-format.md; check it with `otoatlas verify
OUT/package`), package.log.json, report.html, metrics.json, mechanics.json (with [validate]),
timings.json, registered/surfaces/*.ply, registered/volume.vtu,
registered/landmarks.{json,fcsv}, registered/deviation/*.{ply,vtp} (with a segmentation), and
stages/ (one artefact per stage, for --from). No DICOM patient field is written unless
--keep-phi is given.

Examples:
  otoatlas run sample_cases/case-001 --out out/case-001
  otoatlas run scan/ --landmarks picks.fcsv --side left --out out/scan
  otoatlas run sample_cases/case-001 --out out/case-001 --from deform --config tuned.toml"
)]
pub struct RunArgs {
    /// The case folder (dicom/ or image.nii.gz, landmarks, optional segmentation/) or an image.
    pub case: PathBuf,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Landmark file to use instead of the case's (.fcsv, .mrk.json, .json, .csv).
    #[arg(long, value_name = "FILE")]
    pub landmarks: Option<PathBuf>,
    #[command(flatten)]
    pub series: SeriesArg,
    /// Propose the landmarks from the image (`otoatlas landmarks --auto`) instead of reading
    /// them; the case's own landmark file is not read.
    #[arg(long, conflicts_with = "landmarks")]
    pub auto_landmarks: bool,
    /// Atlas folder instead of the embedded default.
    #[arg(long, value_name = "DIR")]
    pub atlas: Option<PathBuf>,
    /// The side of the ear (overrides the landmark file and the DICOM Laterality).
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// Start at this stage, reusing the artefacts of the earlier ones in OUT/stages/.
    #[arg(long, value_enum, default_value = "ingest")]
    pub from: Stage,
    /// The ear's condition the package models: the same registration, the materials of a
    /// pathology (docs/mechanics.md, "Pathologies"), for rehearsing its surgery.
    #[arg(long, value_enum, default_value = "normal")]
    pub condition: Condition,
    /// Copy the DICOM patient fields (name, ID, birth date, institution, accession) into the
    /// package manifest; without it no patient-identifying field is written anywhere.
    #[arg(long)]
    pub keep_phi: bool,
    /// Print machine-readable JSON (the metrics) on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(
    args: &RunArgs,
    config: Option<&Path>,
    progress: &dyn Reporter,
) -> Result<Report, Error> {
    let config = Config::load(config)?;
    let case = Case {
        series: args.series.uid.clone(),
        ..Case::open(&args.case)?
    };
    check_out_dir(&args.out)?;
    let opts = RunOptions {
        out: args.out.clone(),
        from: args.from,
        landmarks: args.landmarks.clone(),
        atlas: args.atlas.clone(),
        side: args.side,
        keep_phi: args.keep_phi,
        auto_landmarks: match args.auto_landmarks {
            true => AutoLandmarks::Always,
            false => AutoLandmarks::Never,
        },
        condition: args.condition,
    };
    let summary = run_case(&case, &opts, &config, progress)?;
    let m = &summary.metrics;
    let mut text = String::new();
    let _ = writeln!(
        text,
        "{}: {} ear, rigid landmark RMS {:.3} mm (scale {:.3}){}, FEM levels {}{}",
        case.id,
        m.side.as_str(),
        m.rigid.rms_mm,
        m.rigid.scale,
        m.deform
            .placed_again
            .last()
            .map(|s| format!(", placed again at scale {s:.3}"))
            .unwrap_or_default(),
        m.deform.status.describe(m.deform.iterations),
        match &m.deform.refinement {
            Some(r) => format!(
                ", surface level {} after {} rounds{}",
                r.stop.name(),
                r.rounds,
                r.mean_offset_last_mm
                    .map(|o| format!(", {o:.3} mm from the bone borders"))
                    .unwrap_or_default()
            ),
            None => String::new(),
        }
    );
    if let Some(scores) = &m.scores {
        let _ = writeln!(
            text,
            "\n{:<10} {:>12} {:>12} {:>10} {:>10}",
            "structure", "MASD rigid", "MASD final", "HD95", "improved"
        );
        for (name, s) in scores {
            let _ = writeln!(
                text,
                "{:<10} {:>9.3} mm {:>9.3} mm {:>7.3} mm {:>9.0} %",
                name,
                s.rigid.as_ref().map_or(f64::NAN, |r| r.masd),
                s.registered.masd,
                s.registered.hd95,
                100.0 * s.masd_improvement.unwrap_or(f64::NAN)
            );
        }
    }
    let _ = writeln!(text);
    for (stage, secs) in &summary.timings {
        let _ = write!(text, "{stage} {secs:.2} s  ");
    }
    let _ = writeln!(text, "\nwrote {}", summary.out.display());
    Ok(Report {
        text,
        json: serde_json::to_value(&summary.metrics).unwrap_or_default(),
    })
}
