//! Landmarks proposed from the image, without a manual pick: the chain search places the
//! atlas (`chain_search`), the deformable stage registers it, the atlas is placed again by
//! the similarity of the registered ossicles and registered again (`rescale_passes` times),
//! and the three landmarks are read off the registered atlas at their written definitions
//! (docs/anatomy.md). Each landmark's confidence is how much of the bone surface around it
//! the image confirms.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::DeformSettings;
use super::atlas_fit::{deform_atlas, place};
use super::chain_search::{
    ChainSearch, SCALE_RANGE, SearchConfig, SearchError, SideAtlas, search_chain,
};
use super::deform::{DeformError, probe_surface};
use super::landmarks::LandmarkWarning;
use super::placement::{bone_nodes, placement_from_registration};
use super::probes::probe_triangles;
use crate::atlas::Atlas;
use crate::ear::{LandmarkName, Landmarks, Side};
use crate::image::Sampler;
use crate::progress::Reporter;

/// The least margin by which the other side's chain must fit better for the image's
/// handedness to contradict a stated side (the right side won by 10-24 % on the phantoms,
/// docs/registration.md) \[fraction\].
pub const HANDEDNESS_MARGIN: f64 = 0.05;

/// The surface around a landmark that its confidence is judged on \[mm\].
const SUPPORT_RADIUS_MM: f64 = 2.0;

/// Why no landmarks could be proposed.
#[derive(Debug, thiserror::Error)]
pub enum ProposeError {
    #[error(transparent)]
    Search(#[from] SearchError),
    #[error("registering the atlas found by the chain search failed: {0}")]
    Register(#[from] DeformError),
}

/// Where the proposal's side came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SideSource {
    /// Given by the user (`--side`).
    Given,
    /// The image's DICOM laterality.
    DicomLaterality,
    /// The chain's handedness in the image (the mirrored atlas fits worse).
    Handedness,
}

/// How well the image supports one landmark.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LandmarkSupport {
    /// Share of the registered bone surface within 2 mm of the landmark that finds the image's
    /// bone edge within one voxel \[fraction, area-weighted\].
    pub confidence: f64,
    /// Bone surface within 2 mm \[mm²\].
    pub surface_mm2: f64,
}

/// The proposal: the landmarks, the side, and the method's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Proposal {
    pub landmarks: Landmarks,
    pub side: Side,
    pub side_source: SideSource,
    /// The side stated (`--side` or DICOM laterality) against the chain's handedness, when
    /// the mirrored chain fits the image clearly better than the stated side's.
    pub handedness_disagrees: bool,
    /// The landmarks read off the atlas as the search placed it, before the registration.
    pub searched: Landmarks,
    pub support: [LandmarkSupport; 3],
    pub search: ChainSearch,
    /// The scale of each placement after the first that was kept
    /// (`SearchConfig::rescale_passes`).
    pub rescales: Vec<f64>,
    /// Wall-clock seconds of the registration after the search.
    pub register_seconds: f64,
}

impl SideSource {
    /// Where the side came from, as the report and `metrics.json` say it.
    pub fn describe(self) -> &'static str {
        match self {
            SideSource::Given => "--side",
            SideSource::DicomLaterality => "DICOM laterality",
            SideSource::Handedness => "chain's handedness in the image",
        }
    }
}

impl Proposal {
    /// The warning when the stated side and the chain's handedness disagree.
    pub fn side_warning(&self) -> Option<LandmarkWarning> {
        self.handedness_disagrees
            .then(|| LandmarkWarning::HandednessDisagrees {
                stated: self.side,
                source: self.side_source.describe().to_string(),
                margin: self.search.side_margin,
            })
    }

    /// The support of `name`.
    pub fn support_of(&self, name: LandmarkName) -> LandmarkSupport {
        let k = LandmarkName::ALL
            .iter()
            .position(|n| *n == name)
            .unwrap_or(0);
        self.support[k]
    }
}

/// The image and the registration's settings.
#[derive(Clone, Copy)]
pub struct ProposeInput<'a> {
    pub sampler: &'a Sampler<'a>,
    /// The atlas mirrored to each side.
    pub right: &'a Atlas,
    pub left: &'a Atlas,
    /// The side when it is known (`--side`, else the image's DICOM laterality) and where it
    /// came from; `None`: from the chain's handedness in the image.
    pub known_side: Option<(Side, SideSource)>,
    pub search: &'a SearchConfig,
    pub settings: DeformSettings<'a>,
    /// Probe step \[mm\] (the smallest voxel spacing).
    pub step: f64,
}

/// Finds the chain, registers the atlas and reads the landmarks off it.
pub fn propose_landmarks(
    input: ProposeInput,
    progress: &dyn Reporter,
) -> Result<Proposal, ProposeError> {
    let sides = [
        SideAtlas {
            side: Side::Right,
            atlas: input.right,
        },
        SideAtlas {
            side: Side::Left,
            atlas: input.left,
        },
    ];
    let search = search_chain(input.sampler.volume(), &sides, input.search, progress)?;
    let handedness_disagrees = input.known_side.is_some_and(|(side, _)| {
        side != search.best.side && search.side_margin >= HANDEDNESS_MARGIN
    });
    let (chosen, side_source) = match input.known_side {
        Some((side, source)) if side != search.best.side => (search.other, source),
        Some((_, source)) => (search.best, source),
        None => (search.best, SideSource::Handedness),
    };
    let atlas = match chosen.side {
        Side::Right => input.right,
        Side::Left => input.left,
    };
    progress.log(&format!(
        "chain search: {} ear (score {:.2}, the {} ear's {:.2}), {:.2} s",
        search.best.side.as_str(),
        search.best.score,
        search.other.side.as_str(),
        search.other.score,
        search.seconds
    ));
    let register = |placed: &[Point3<f64>]| {
        deform_atlas(
            atlas,
            placed,
            placed,
            input.sampler,
            input.step,
            input.settings,
            progress,
        )
        .map(|registered| registered.deform.positions)
    };
    let placed = place(atlas, &chosen.atlas_to_image);
    let clock = std::time::Instant::now();
    let mut nodes = register(&placed)?;
    let mut rescales = Vec::with_capacity(input.search.rescale_passes);
    let bones = bone_nodes(atlas);
    for _ in 0..input.search.rescale_passes {
        // a placement outside the sizes people's ossicles have ends the passes
        let Some(placement) = placement_from_registration(atlas, &bones, &nodes, SCALE_RANGE)
        else {
            break;
        };
        progress.log(&format!(
            "atlas placed again at scale {:.3} (the registered ossicles' similarity); registering again",
            placement.scale
        ));
        // a pass refines a registration that succeeded: when it fails, that one stands
        match register(&place(atlas, &placement)) {
            Ok(again) => {
                nodes = again;
                rescales.push(placement.scale);
            }
            Err(e) => {
                progress.log(&format!(
                    "registering the atlas placed again failed ({e}); the registration before it is kept"
                ));
                break;
            }
        }
    }
    let landmarks = atlas.landmark_positions(&nodes);
    let support = support(atlas, &nodes, &landmarks, &input);
    Ok(Proposal {
        landmarks,
        side: chosen.side,
        side_source,
        handedness_disagrees,
        searched: atlas.landmark_positions(&placed),
        support,
        search,
        rescales,
        register_seconds: clock.elapsed().as_secs_f64(),
    })
}

/// Each landmark's support on the registered atlas.
fn support(
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    landmarks: &Landmarks,
    input: &ProposeInput,
) -> [LandmarkSupport; 3] {
    let triangles = probe_triangles(atlas);
    let probe = &input.settings.deform.probe;
    let probed = probe_surface(&triangles, nodes, input.sampler, input.step, probe);
    let tolerance = input.step.max(0.1);
    LandmarkName::ALL.map(|name| {
        let at = landmarks.get(name);
        let (mut near, mut held) = (0.0, 0.0);
        for (t, p) in triangles.iter().zip(&probed) {
            let [a, b, c] = t.nodes.map(|k| nodes[k as usize]);
            let centre = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            if (centre - at).norm() > SUPPORT_RADIUS_MM {
                continue;
            }
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            near += area;
            if p.is_some_and(|p| p.border.offset_mm.abs() <= tolerance) {
                held += area;
            }
        }
        LandmarkSupport {
            confidence: if near > 0.0 { held / near } else { 0.0 },
            surface_mm2: near,
        }
    })
}
