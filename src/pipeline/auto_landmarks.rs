//! Landmarks proposed from a case's image (`landmarks --auto`, `run --auto-landmarks`): the
//! atlas on each side, the proposal (`register::auto_landmarks`), and its landmark files, which
//! say how each landmark was found and how sure the image is of it.

use std::path::Path;

use serde_json::{Value, json};

use crate::config::Config;
use crate::ear::write_mrk_json_described;
use crate::ear::{LandmarkName, Side, write_fcsv_described, write_json_with};
use crate::image::{LoadedImage, Sampler};
use crate::pipeline::Error;
use crate::progress::Reporter;
use crate::register::DeformSettings;
use crate::register::auto_landmarks::{Proposal, ProposeInput, SideSource, propose_landmarks};
use crate::register::deform::Steps;

/// Proposes the landmarks of `image` with the atlas at `atlas_dir` (the embedded one when
/// `None`), as `config` registers; `side` (`--side`) overrides the image's DICOM laterality,
/// and without either the chain's handedness decides.
pub fn propose(
    image: &LoadedImage,
    sampler: &Sampler,
    atlas_dir: Option<&Path>,
    side: Option<Side>,
    config: &Config,
    progress: &dyn Reporter,
) -> Result<Proposal, Error> {
    // read once; the other ear is its mirror image, as `load_atlas` makes it
    let right = crate::atlas::load_atlas(atlas_dir, Some(Side::Right))?;
    let left = right.mirrored();
    let step = image.volume.smallest_spacing();
    let input = ProposeInput {
        sampler,
        right: &right,
        left: &left,
        known_side: match side {
            Some(side) => Some((side, SideSource::Given)),
            None => image
                .info
                .laterality
                .as_deref()
                .and_then(Side::parse)
                .map(|side| (side, SideSource::DicomLaterality)),
        },
        search: &config.auto_landmarks,
        settings: DeformSettings {
            articulate: &config.articulate,
            deform: &config.deform,
            refine: &config.refine,
            steps: Steps::Newton,
        },
        step,
    };
    Ok(propose_landmarks(input, progress)?)
}

/// Each landmark's description in the Slicer files: how it was found and its confidence.
fn descriptions(p: &Proposal) -> [String; 3] {
    LandmarkName::ALL.map(|name| {
        format!(
            "proposed by otoatlas from the image; confidence {:.2}",
            p.support_of(name).confidence
        )
    })
}

/// The method's figures, as `landmarks.json`'s `proposal` and `metrics.json` carry them.
pub fn proposal_record(p: &Proposal) -> Value {
    let support: serde_json::Map<String, Value> = LandmarkName::ALL
        .iter()
        .map(|&name| {
            let s = p.support_of(name);
            (
                name.key().to_string(),
                json!({"confidence": s.confidence, "surface_mm2": s.surface_mm2}),
            )
        })
        .collect();
    json!({
        "method": "chain search over all orientations and both sides, then the registration; \
                   the landmarks are the registered atlas's",
        "side_source": p.side_source,
        "side_margin": p.search.side_margin,
        "search": p.search,
        "support": support,
        "searched": {
            "umbo": p.searched.umbo.coords.as_slice(),
            "incudomalleolar": p.searched.incudomalleolar.coords.as_slice(),
            "incudostapedial": p.searched.incudostapedial.coords.as_slice(),
        },
        "rescales": p.rescales,
        "poses_tried": p.poses_tried,
        "register_seconds": p.register_seconds,
    })
}

/// The proposal's `.fcsv`, `.mrk.json` and `.json` texts.
pub fn proposal_files(p: &Proposal) -> (String, String, String) {
    let desc = descriptions(p);
    let mut extra = serde_json::Map::new();
    extra.insert("proposal".into(), proposal_record(p));
    (
        write_fcsv_described(&p.landmarks, &desc),
        write_mrk_json_described(&p.landmarks, &desc),
        write_json_with(&p.landmarks, Some(p.side), extra),
    )
}
