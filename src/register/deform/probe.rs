//! Looking for the boundary along a surface normal, as the source study does (its eq. 1-2):
//! samples X(j) = B ± j·step·n inside and outside the surface, and the ratio of successive
//! intensities R(j) = I(X(j)) / I(X(j-1)) on intensities shifted to be positive. A bone
//! boundary is where R leaves [1 - t, 1 + t] in the direction of leaving bone: falling when
//! walking outwards, rising when walking inwards. The edge is then placed between samples at
//! the point where the profile crosses half-way between its local bone and background levels
//! (exact for a symmetric blur, up to the interpolation between voxels), and kept only if its
//! bone side is bone-like. A membrane (the eardrum) is a thin sheet, not an edge: there the probe looks for
//! a ridge of intensity instead.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::image::Sampler;

/// Probe settings (part of `[deform]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeConfig {
    /// How far to look on each side of the surface \[mm\].
    pub search_range_mm: f64,
    /// Positive shift added to HU before taking ratios, so air stays well above zero \[HU\].
    pub intensity_shift_hu: f64,
    /// Ratio threshold t: a boundary is where I(j)/I(j-1) leaves [1 - t, 1 + t] \[fraction\].
    pub ratio_threshold: f64,
    /// The bone side of an edge must reach at least this \[HU\].
    pub bone_min_hu: f64,
    /// A membrane ridge must rise this much above the lower of its two sides \[HU\].
    pub sheet_contrast_hu: f64,
}

/// What is being looked for along a normal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProbeKind {
    /// The outer boundary of bone (ossicles).
    Bone,
    /// A thin soft-tissue sheet in air (the eardrum).
    Sheet,
}

/// A boundary found: its position and its signed offset along the normal (mm, + outwards).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Border {
    pub point: Point3<f64>,
    pub offset_mm: f64,
}

/// Intensities along the normal at offsets s_j = j·step, j = -J..=J (index j + J).
struct Profile {
    values: Vec<f64>,
    half: usize,
    step: f64,
}

impl Profile {
    fn sample(
        sampler: &Sampler,
        b: &Point3<f64>,
        n: &Vector3<f64>,
        step: f64,
        half: usize,
        shift: f64,
    ) -> Option<Profile> {
        let mut values = Vec::with_capacity(2 * half + 1);
        for j in -(half as isize)..=(half as isize) {
            let p = b + n * (j as f64 * step);
            values.push(sampler.sample(&p)? as f64 + shift);
        }
        Some(Profile { values, half, step })
    }

    fn at(&self, j: isize) -> f64 {
        self.values[(j + self.half as isize) as usize]
    }

    /// Where the profile crosses half-way between its high and low levels around the falling
    /// step from j-1 to j (offset in steps, linear interpolation between samples). For an edge
    /// blurred by a symmetric point-spread function the half level sits exactly on the edge.
    fn half_level_crossing(&self, j: isize) -> f64 {
        let h = self.half as isize;
        let clamp = |m: isize| m.clamp(-h, h);
        let high = (clamp(j - 3)..=clamp(j - 1))
            .map(|m| self.at(m))
            .fold(f64::MIN, f64::max);
        let low = (clamp(j)..=clamp(j + 2))
            .map(|m| self.at(m))
            .fold(f64::MAX, f64::min);
        let mid = 0.5 * (high + low);
        for m in clamp(j - 2)..clamp(j + 2) {
            let (a, b) = (self.at(m), self.at(m + 1));
            if a >= mid && b < mid {
                return m as f64 + (a - mid) / (a - b);
            }
        }
        j as f64 - 0.5
    }
}

/// Looks for the boundary along `normal` (unit, outward) from `b`.
pub fn probe(
    sampler: &Sampler,
    b: &Point3<f64>,
    normal: &Vector3<f64>,
    kind: ProbeKind,
    step: f64,
    cfg: &ProbeConfig,
) -> Option<Border> {
    let half = ((cfg.search_range_mm / step).ceil() as usize).max(1);
    let profile = Profile::sample(sampler, b, normal, step, half, cfg.intensity_shift_hu)?;
    let offset_steps = match kind {
        ProbeKind::Bone => bone_edge(&profile, cfg)?,
        ProbeKind::Sheet => sheet_ridge(&profile, cfg)?,
    };
    let offset_mm = offset_steps * profile.step;
    Some(Border {
        point: b + normal * offset_mm,
        offset_mm,
    })
}

/// The nearest edge leaving bone: falling outwards (j > 0) or rising inwards (j < 0).
fn bone_edge(p: &Profile, cfg: &ProbeConfig) -> Option<f64> {
    let t = cfg.ratio_threshold;
    let bone_min = cfg.bone_min_hu + cfg.intensity_shift_hu;
    let h = p.half as isize;
    for j in 1..=h {
        // outwards: from X(j-1) to X(j)
        let r = p.at(j) / p.at(j - 1);
        if r < 1.0 - t && p.at(j - 1) >= bone_min {
            return Some(p.half_level_crossing(j));
        }
        // inwards: from X(-(j-1)) to X(-j), entering bone from outside
        let r = p.at(-j) / p.at(-(j - 1));
        if r > 1.0 + t && p.at(-j) >= bone_min {
            // in increasing offsets this is the falling step from -j to -(j-1)
            return Some(p.half_level_crossing(-(j - 1)));
        }
    }
    None
}

/// The nearest local maximum standing out of its surroundings by the sheet contrast.
fn sheet_ridge(p: &Profile, cfg: &ProbeConfig) -> Option<f64> {
    let h = p.half as isize;
    let mut order: Vec<isize> = (-(h - 1)..=(h - 1)).collect();
    order.sort_by_key(|j| j.abs());
    for j in order {
        let (l, c, r) = (p.at(j - 1), p.at(j), p.at(j + 1));
        if c >= l && c >= r {
            let low = (-h..=h).map(|m| p.at(m)).fold(f64::MAX, f64::min);
            if c - low >= cfg.sheet_contrast_hu {
                let denom = l - 2.0 * c + r;
                let delta = if denom.abs() > 1e-12 {
                    (0.5 * (l - r) / denom).clamp(-0.5, 0.5)
                } else {
                    0.0
                };
                return Some(j as f64 + delta);
            }
        }
    }
    None
}
