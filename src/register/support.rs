//! How well each registered ossicle is supported by its image: the share of its outer surface
//! that lies on a bone edge.
//!
//! Why: a registration always ends somewhere, and its own record (offsets, stop reasons) is
//! of the surfaces it moved, not of whether the pose they started from was right. A bone whose
//! surface mostly finds no edge within reach, or finds one far off, lies in air or in other
//! bone: on randomly varied real-chain phantoms whose stapes was registered turned the wrong
//! way about its head, 0.19-0.24 of the stapes's surface was on an edge after the articulation,
//! against 0.33-0.41 where it was right (docs/registration.md, "Chains varied at random").
//!
//! Measure: every outer triangle of the ossicle probes along its normal (the surface level's
//! probe and range); a triangle whose probe finds an edge counts with its area weighted by
//! 1 / (1 + (offset / 0.3 mm)²), one that finds none counts 0; the sum over the ossicle's
//! area.

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::DeformSettings;
use super::deform::{ProbeConfig, probe_surface};
use super::probes::probe_triangles_by_part;
use crate::atlas::{Atlas, Part};
use crate::image::Sampler;

/// The offset at which a found edge counts half \[mm\].
const HALF_WEIGHT_OFFSET_MM: f64 = 0.3;

/// Below this share of its surface on an edge the registered stapes's pose is suspect and
/// `run` warns. Chosen on the 64 randomly varied real-chain phantoms and the 16 development
/// cases (docs/registration.md, "Edge support"): the two stapes registered 0.4-0.8 mm off the
/// truth had 0.34 and 0.36, every other case 0.43 or more (atlas-shape sample cases 0.52-0.85).
/// Fitted to those cases, so a warning, not a verdict; a stapes 0.2-0.5 mm off can stay above it.
/// `landmarks --auto` registers the chain search's next poses when its first registration is
/// under it (`auto_landmarks`).
pub const STAPES_SUPPORT_WARNING: f64 = 0.4;

/// One ossicle's edge support.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EdgeSupport {
    pub part: Part,
    /// The share of the ossicle's outer surface on a bone edge (module doc), 0 to 1.
    pub share: f64,
}

/// The edge support of each ossicle of `atlas` with its nodes at `x`.
pub fn edge_support(
    atlas: &Atlas,
    x: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    probe: &ProbeConfig,
) -> Vec<EdgeSupport> {
    let by_part = probe_triangles_by_part(atlas);
    let triangles: Vec<_> = by_part.iter().map(|(_, t)| *t).collect();
    let found = probe_surface(&triangles, x, sampler, step, probe);
    Part::BONES
        .iter()
        .map(|&part| {
            let (mut on_edge, mut area) = (0.0, 0.0);
            for (t, f) in by_part.iter().zip(&found).filter(|((p, _), _)| *p == part) {
                let [a, b, c] = t.1.nodes.map(|k| x[k as usize]);
                area += 0.5 * (b - a).cross(&(c - a)).norm();
                if let Some(f) = f {
                    on_edge +=
                        f.area / (1.0 + (f.border.offset_mm / HALF_WEIGHT_OFFSET_MM).powi(2));
                }
            }
            EdgeSupport {
                part,
                share: if area > 0.0 { on_edge / area } else { 0.0 },
            }
        })
        .collect()
}

/// The edge support of a registration made with `settings`, probed with the surface level's
/// probe and range (what `run` records and warns on).
pub fn registered_support(
    atlas: &Atlas,
    x: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    settings: DeformSettings,
) -> Vec<EdgeSupport> {
    let probe = ProbeConfig {
        search_range_mm: settings.refine.search_range_mm,
        ..settings.deform.probe.clone()
    };
    edge_support(atlas, x, sampler, step, &probe)
}

/// The stapes's support, if `supports` has one.
fn stapes(supports: &[EdgeSupport]) -> Option<EdgeSupport> {
    supports.iter().find(|s| s.part == Part::Stapes).copied()
}

/// The stapes's share of its surface on a bone edge (1 when it has none to judge) \[0 to 1\].
pub fn stapes_share(supports: &[EdgeSupport]) -> f64 {
    stapes(supports).map_or(1.0, |s| s.share)
}

/// The stapes's support when it is below [`STAPES_SUPPORT_WARNING`].
pub fn weak_stapes(supports: &[EdgeSupport]) -> Option<EdgeSupport> {
    stapes(supports).filter(|s| s.share < STAPES_SUPPORT_WARNING)
}

/// The mean of the ossicles' shares, each ossicle counting alike (the stapes, a tenth of the
/// chain's surface, as much as the malleus) \[0 to 1\].
pub fn mean_share(supports: &[EdgeSupport]) -> f64 {
    supports.iter().map(|s| s.share).sum::<f64>() / supports.len().max(1) as f64
}
