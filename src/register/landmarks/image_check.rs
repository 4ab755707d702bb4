//! Does the image confirm a label swap the distances suggest? The atlas is placed by each
//! labelling (the landmark fit of the rigid stage) and every ossicle triangle on its outer
//! boundary is probed along its normal for a bone edge, as the deformable stage does on its
//! first iteration. The labelling that lays the atlas onto the chain finds a border from more
//! triangles, and nearer: a swapped pair turns the chain by tens of degrees about the third
//! landmark, so most of its surface then lies in air or in the wrong bone.

use serde::{Deserialize, Serialize};

use crate::atlas::Atlas;
use crate::ear::Landmarks;
use crate::image::Sampler;
use crate::register::atlas_fit::{fit_landmarks, place};
use crate::register::deform::{ProbeConfig, probe_surface};
use crate::register::probes::probe_triangles;

/// The image and what places and probes the atlas in it.
#[derive(Debug, Clone, Copy)]
pub struct ImageCheck<'a> {
    /// The atlas, already on the patient's side.
    pub atlas: &'a Atlas,
    pub sampler: &'a Sampler<'a>,
    /// Probe step \[mm\] (the smallest voxel spacing, as in the deformable stage).
    pub step_mm: f64,
    /// The bone-edge probe (`[deform]` in pipeline.toml).
    pub probe: &'a ProbeConfig,
    /// Fit the scale with the landmarks (`[rigid] with_scale`).
    pub with_scale: bool,
}

/// How well the atlas placed by one labelling lies on the image's bone borders.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BorderFit {
    /// Ossicle surface triangles probed.
    pub triangles: usize,
    /// Fraction of them that found a bone edge within the search range \[fraction\].
    pub found_fraction: f64,
    /// Mean |offset| from a triangle to the edge it found \[mm\].
    pub mean_abs_offset_mm: f64,
}

/// The two labellings side by side.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SwapEvidence {
    pub given: BorderFit,
    pub swapped: BorderFit,
    /// The swapped labelling fits clearly better: its found fraction is higher by at least the
    /// configured gain and its mean |offset| is not larger.
    pub confirms_swap: bool,
}

impl ImageCheck<'_> {
    /// The border fit of the atlas placed by `landmarks`; `None` when the fit is degenerate
    /// or no triangle could be probed (the atlas placed outside the image).
    pub fn border_fit(&self, landmarks: &Landmarks) -> Option<BorderFit> {
        let fit = fit_landmarks(self.atlas, landmarks, self.with_scale)?;
        let nodes = place(self.atlas, &fit.transform);
        let triangles = probe_triangles(self.atlas);
        let probed = probe_surface(&triangles, &nodes, self.sampler, self.step_mm, self.probe);
        let found: Vec<f64> = probed
            .iter()
            .flatten()
            .map(|p| p.border.offset_mm.abs())
            .collect();
        if triangles.is_empty() {
            return None;
        }
        Some(BorderFit {
            triangles: triangles.len(),
            found_fraction: found.len() as f64 / triangles.len() as f64,
            mean_abs_offset_mm: if found.is_empty() {
                f64::NAN
            } else {
                found.iter().sum::<f64>() / found.len() as f64
            },
        })
    }
}

impl SwapEvidence {
    /// The given and the swapped labelling's fits side by side; the swap is confirmed when the
    /// swapped fit finds borders from at least `min_gain` more of the triangles, no farther.
    pub fn of(given: BorderFit, swapped: BorderFit, min_gain: f64) -> SwapEvidence {
        let offset_not_worse = swapped.mean_abs_offset_mm <= given.mean_abs_offset_mm
            || (given.mean_abs_offset_mm.is_nan() && swapped.found_fraction > 0.0);
        SwapEvidence {
            given,
            swapped,
            confirms_swap: swapped.found_fraction - given.found_fraction >= min_gain
                && offset_not_worse,
        }
    }
}
