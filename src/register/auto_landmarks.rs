//! Landmarks proposed from the image, without a manual pick: the chain search places the
//! atlas (`chain_search`), the deformable stage registers it (and, when that leaves the
//! stapes poorly supported by the image, registers the search's next poses too and keeps the
//! best supported: a search's best pose can be the chain turned about a joint, which no
//! registration undoes), the atlas is placed again by
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
use super::support::{
    STAPES_SUPPORT_WARNING, mean_share, registered_support, stapes_share, weak_stapes,
};
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
    /// The search's poses registered, the first the search's best: more when the first
    /// registration's stapes was poorly supported by the image (`support::weak_stapes`).
    pub poses_tried: Vec<PoseTried>,
    /// Wall-clock seconds of the registration after the search.
    pub register_seconds: f64,
}

/// One pose of the chain search registered, and how well the image supports the result.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseTried {
    /// The pose's score in the search \[fraction of a perfect edge\].
    pub search_score: f64,
    /// The pose's scale \[atlas\].
    pub scale: f64,
    /// The registered stapes's share of surface on a bone edge (`support`).
    pub stapes_support: f64,
    /// The registered ossicles' mean share: what the poses are judged by.
    pub mean_support: f64,
    /// The registration the proposal went on from.
    pub kept: bool,
}

/// How much more of the registered ossicles' surface (mean share) an alternative pose must
/// put on bone edges to replace the search's best.
const SUPPORT_MARGIN: f64 = 0.02;

/// A sentence on the search's poses registered, when more than its best was.
pub fn describe_poses_tried(tried: &[PoseTried]) -> Option<String> {
    let first = tried.first().filter(|_| tried.len() >= 2)?;
    let verdict = match tried.iter().position(|t| t.kept) {
        Some(k) if k > 0 => format!(
            "pose {} (score {:.3}) kept: {:.2} of the stapes, {:.2} of the ossicles",
            k + 1,
            tried[k].search_score,
            tried[k].stapes_support,
            tried[k].mean_support
        ),
        _ => "none put more of the ossicles on an edge, so the best pose stands".to_string(),
    };
    let others = match tried.len() - 1 {
        1 => "the search's next pose was registered".to_string(),
        n => format!("the search's next {n} poses were registered"),
    };
    Some(format!(
        "the search's best pose (score {:.3}) left {:.2} of the stapes's surface on a bone edge \
         ({:.2} of the ossicles'); {others}, {verdict}",
        first.search_score, first.stapes_support, first.mean_support
    ))
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
    let supports = |nodes: &[Point3<f64>]| {
        registered_support(atlas, nodes, input.sampler, input.step, input.settings)
    };
    let first = supports(&nodes);
    let mut poses_tried = vec![PoseTried {
        search_score: chosen.score,
        scale: chosen.atlas_to_image.scale,
        stapes_support: stapes_share(&first),
        mean_support: mean_share(&first),
        kept: false,
    }];
    let mut best = 0;
    if weak_stapes(&first).is_some() {
        progress.log(&format!(
            "the registered stapes has {:.2} of its surface on a bone edge (under {STAPES_SUPPORT_WARNING}): \
             registering from the search's next poses",
            stapes_share(&first)
        ));
        let alternatives = search.alternatives.iter().filter(|a| a.side == chosen.side);
        for alternative in alternatives {
            // an alternative that fails to register is one fewer candidate, not an error
            let Ok(again) = register(&place(atlas, &alternative.atlas_to_image)) else {
                continue;
            };
            let support = supports(&again);
            poses_tried.push(PoseTried {
                search_score: alternative.score,
                scale: alternative.atlas_to_image.scale,
                stapes_support: stapes_share(&support),
                mean_support: mean_share(&support),
                kept: false,
            });
            let last = poses_tried.len() - 1;
            if poses_tried[last].mean_support >= poses_tried[best].mean_support + SUPPORT_MARGIN {
                best = last;
                nodes = again;
            }
        }
        progress.log(&format!(
            "kept pose {} of {} (mean edge support {:.2})",
            best + 1,
            poses_tried.len(),
            poses_tried[best].mean_support
        ));
    }
    poses_tried[best].kept = true;
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
        poses_tried,
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
