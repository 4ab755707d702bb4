//! The stages of `run`, in order. Each writes its artefact under `OUT/stages/`, so a later run
//! with `--from STAGE` reuses what the stages before it wrote.

use serde::Serialize;

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
