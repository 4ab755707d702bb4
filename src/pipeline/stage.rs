//! The stages of `run`, in order. Each writes its artefact under `OUT/stages/`, so a later run
//! with `--from STAGE` reuses what the stages before it wrote: the artefacts' paths, reading
//! one back, running a stage or resuming it, and the wall time of each.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::Error;
use crate::io_util::write_json_file;

/// One stage of the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    Ingest,
    Landmarks,
    Rigid,
    Deform,
    Score,
    Export,
}

impl Stage {
    pub const ALL: [Stage; 6] = [
        Stage::Ingest,
        Stage::Landmarks,
        Stage::Rigid,
        Stage::Deform,
        Stage::Score,
        Stage::Export,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::Ingest => "ingest",
            Stage::Landmarks => "landmarks",
            Stage::Rigid => "rigid",
            Stage::Deform => "deform",
            Stage::Score => "score",
            Stage::Export => "export",
        }
    }

    /// The artefact file of the stage, relative to `OUT/stages/`.
    pub fn artefact(self) -> &'static str {
        match self {
            Stage::Ingest => "ingest.json",
            Stage::Landmarks => "landmarks.json",
            Stage::Rigid => "rigid.json",
            Stage::Deform => "deform.json",
            Stage::Score => "score.json",
            Stage::Export => "export.json",
        }
    }
}

/// Where `stage` keeps its artefact in the run folder `out`.
pub(super) fn artefact_path(out: &Path, stage: Stage) -> PathBuf {
    out.join("stages").join(stage.artefact())
}

/// The artefact an earlier run's `stage` wrote, read back by the type that wrote it.
pub(super) fn read_record<T: DeserializeOwned>(
    out: &Path,
    stage: Stage,
    from: Stage,
) -> Result<T, Error> {
    let path = artefact_path(out, stage);
    let text = crate::io_util::read_text(&path).map_err(|e| {
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

/// The wall time of each step that ran, in order.
#[derive(Default)]
pub(super) struct Clock(pub(super) Vec<(&'static str, f64)>);

impl Clock {
    pub(super) fn record(&mut self, step: &'static str, started: Instant) {
        self.0.push((step, started.elapsed().as_secs_f64()));
    }
}

/// Runs `stage` when the run starts at or before it (its artefact written, its time
/// recorded), or reads the artefact an earlier run wrote.
pub(super) fn run_or_resume<T: Serialize + DeserializeOwned>(
    out: &Path,
    from: Stage,
    stage: Stage,
    clock: &mut Clock,
    run: impl FnOnce() -> Result<T, Error>,
) -> Result<T, Error> {
    if from > stage {
        return read_record(out, stage, from);
    }
    let started = Instant::now();
    let value = run()?;
    write_json_file(&artefact_path(out, stage), &value)?;
    clock.record(stage.name(), started);
    Ok(value)
}
