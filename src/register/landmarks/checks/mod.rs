//! Checks on the three landmarks before anything runs. Refused: a landmark outside the image,
//! three nearly collinear landmarks, an overall size off the atlas's by more than the scale
//! range, a distance outside what any middle ear has (its *possible* band), and a label swap
//! that both the distances and the image confirm. Warned about, with the figures: a distance
//! outside its *typical* band, a flat triangle, and a swap the distances suggest but the image
//! does not confirm (or that no image could check).
//!
//! The bands are anatomical (docs/anatomy.md, "Landmark distance bands"), in mm, independent of
//! the atlas: people's chains differ from the atlas's by far more than any one scale explains
//! (five real chains have umbo-ISJ 2.4-2.9 mm where the atlas had 3.69 mm before its ISJ
//! was put at the joint; it now has 2.77 mm).
//!
//! Exchanging two labels keeps their own distance and exchanges the two distances to the third
//! landmark. The distances suggest a swap when the given labelling has a distance outside its
//! typical band and the exchanged labelling has all three inside theirs. Where the two
//! exchanged distances have overlapping typical bands (umbo-IMJ and IMJ-ISJ, that is umbo and
//! ISJ exchanged) the distances can hardly tell; the image decides.

use serde::{Deserialize, Serialize};

use super::image_check::{ImageCheck, SwapEvidence};
use super::{LandmarkError, LandmarkName, Landmarks};
use crate::image::Sampler;
use crate::register::support::{EdgeSupport, STAPES_SUPPORT_WARNING, weak_stapes};

mod warning;

pub use warning::LandmarkWarning;
use warning::{border_text, triple};

/// Tolerances and anatomical bands of the landmark checks (`[landmarks]` in pipeline.toml,
/// which holds the defaults). The bands, how each was built and their sources are in
/// docs/anatomy.md, "Landmark distance bands":
///
/// *Typical* (outside it, a warning): what real chains and SOFA's chain span, and the atlas's
/// triangle scaled by 0.9-1.1 (ossicle dimensions vary by about ±10 % at ±2 SD), each end
/// widened by 0.3 mm (a landmark is picked to about one 0.3 mm voxel).
///
/// *Possible* (outside it, refused): bounds set by ossicle dimensions where one bone spans the
/// distance (the malleus for umbo-IMJ, the incus for IMJ-ISJ); umbo-ISJ spans two bones and
/// depends on how the chain is articulated, so its possible band is the typical band widened
/// by 0.6 mm each way, and up to 5.0 mm so that an ISJ picked at the stapes neck is a warning,
/// not a refusal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckConfig {
    /// Smallest height of the landmark triangle \[mm\]; below it the rigid fit is undetermined.
    pub min_triangle_height_mm: f64,
    /// Below this smallest height \[mm\] the triangle is flat for a middle ear: the rigid fit's
    /// rotation about its longest side is known only to about pick error / height (a warning).
    pub typical_min_height_mm: f64,
    /// Allowed patient/atlas ratio of the landmark triangle's perimeter [unitless, min and
    /// max] (the perimeter does not change when labels are exchanged).
    pub scale_ratio_range: [f64; 2],
    /// umbo-IMJ distance usual in real ears [mm, min and max]; outside it, a warning.
    pub umbo_imj_typical_mm: [f64; 2],
    /// umbo-IMJ distance any middle ear can have [mm, min and max]; outside it, refused.
    pub umbo_imj_possible_mm: [f64; 2],
    /// umbo-ISJ distance usual in real ears [mm, min and max].
    pub umbo_isj_typical_mm: [f64; 2],
    /// umbo-ISJ distance any middle ear can have [mm, min and max].
    pub umbo_isj_possible_mm: [f64; 2],
    /// IMJ-ISJ distance usual in real ears [mm, min and max].
    pub imj_isj_typical_mm: [f64; 2],
    /// IMJ-ISJ distance any middle ear can have [mm, min and max].
    pub imj_isj_possible_mm: [f64; 2],
    /// The image confirms a swap when the atlas placed by the exchanged labels finds a bone
    /// border from at least this larger a fraction of its surface triangles, at a mean offset
    /// no larger [fraction of the probed triangles].
    pub swap_border_gain: f64,
}

/// One distance's bands \[mm\].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Band {
    pub typical_mm: [f64; 2],
    pub possible_mm: [f64; 2],
}

impl CheckConfig {
    /// The bands of umbo-IMJ, umbo-ISJ, IMJ-ISJ, in that order.
    pub fn bands(&self) -> [Band; 3] {
        [
            (self.umbo_imj_typical_mm, self.umbo_imj_possible_mm),
            (self.umbo_isj_typical_mm, self.umbo_isj_possible_mm),
            (self.imj_isj_typical_mm, self.imj_isj_possible_mm),
        ]
        .map(|(typical_mm, possible_mm)| Band {
            typical_mm,
            possible_mm,
        })
    }

    /// Checks every knob: the key (under `landmarks.`), its value and what was expected.
    pub fn validate(&self) -> Result<(), (&'static str, String, &'static str)> {
        let positive = |key: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((key, v.to_string(), "a finite number > 0"))
            }
        };
        let range = |key: &'static str, [lo, hi]: [f64; 2]| {
            if lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi {
                Ok(())
            } else {
                Err((
                    key,
                    format!("[{lo}, {hi}]"),
                    "[min, max] of finite numbers with 0 < min <= max",
                ))
            }
        };
        positive(
            "landmarks.min_triangle_height_mm",
            self.min_triangle_height_mm,
        )?;
        positive(
            "landmarks.typical_min_height_mm",
            self.typical_min_height_mm,
        )?;
        positive("landmarks.swap_border_gain", self.swap_border_gain)?;
        range("landmarks.scale_ratio_range", self.scale_ratio_range)?;
        for (typical_key, possible_key, t, p) in [
            (
                "landmarks.umbo_imj_typical_mm",
                "landmarks.umbo_imj_possible_mm",
                self.umbo_imj_typical_mm,
                self.umbo_imj_possible_mm,
            ),
            (
                "landmarks.umbo_isj_typical_mm",
                "landmarks.umbo_isj_possible_mm",
                self.umbo_isj_typical_mm,
                self.umbo_isj_possible_mm,
            ),
            (
                "landmarks.imj_isj_typical_mm",
                "landmarks.imj_isj_possible_mm",
                self.imj_isj_typical_mm,
                self.imj_isj_possible_mm,
            ),
        ] {
            range(typical_key, t)?;
            range(possible_key, p)?;
            if p[0] > t[0] || p[1] < t[1] {
                return Err((
                    possible_key,
                    format!("[{}, {}]", p[0], p[1]),
                    "a band containing the typical one",
                ));
            }
        }
        Ok(())
    }
}

/// How far the registered atlas may put a landmark from its pick before `run` warns \[mm\]:
/// above the picks' noise (0.15 mm in the phantoms) and where the atlas's landmark
/// definitions and a chain's picks differ (up to 0.45 mm on the real chains, README).
pub const REGISTRATION_AGREEMENT_MM: f64 = 1.0;

/// The picks that the registered atlas's landmarks (`registered`) end far from.
pub fn check_against_registration(
    picks: &Landmarks,
    registered: &Landmarks,
) -> Vec<LandmarkWarning> {
    LandmarkName::ALL
        .iter()
        .filter_map(|&name| {
            let distance_mm = (picks.get(name) - registered.get(name)).norm();
            (distance_mm > REGISTRATION_AGREEMENT_MM).then(|| {
                LandmarkWarning::FarFromRegistration {
                    landmark: name.key().to_string(),
                    distance_mm,
                    limit_mm: REGISTRATION_AGREEMENT_MM,
                }
            })
        })
        .collect()
}

/// The warning for a stapes whose support (in `supports`) is below
/// [`STAPES_SUPPORT_WARNING`], if it is.
pub fn check_edge_support(supports: &[EdgeSupport]) -> Option<LandmarkWarning> {
    weak_stapes(supports).map(|s| LandmarkWarning::WeakEdgeSupport {
        ossicle: s.part.name().to_string(),
        share: s.share,
        limit: STAPES_SUPPORT_WARNING,
    })
}

const PAIRS: [(LandmarkName, LandmarkName, &str); 3] = [
    (
        LandmarkName::Umbo,
        LandmarkName::Incudomalleolar,
        "umbo-IMJ",
    ),
    (
        LandmarkName::Umbo,
        LandmarkName::Incudostapedial,
        "umbo-ISJ",
    ),
    (
        LandmarkName::Incudomalleolar,
        LandmarkName::Incudostapedial,
        "IMJ-ISJ",
    ),
];

const SWAPS: [(LandmarkName, LandmarkName); 3] = [
    (LandmarkName::Umbo, LandmarkName::Incudomalleolar),
    (LandmarkName::Umbo, LandmarkName::Incudostapedial),
    (LandmarkName::Incudomalleolar, LandmarkName::Incudostapedial),
];

fn distances(l: &Landmarks) -> [f64; 3] {
    PAIRS.map(|(a, b, _)| (l.get(a) - l.get(b)).norm())
}

/// The triangle's smallest height [mm]: twice its area over its longest side.
fn smallest_height(l: &Landmarks) -> f64 {
    let [a, b, c] = l.points();
    let longest = distances(l).into_iter().fold(f64::MIN_POSITIVE, f64::max);
    (b - a).cross(&(c - a)).norm() / longest
}

fn within(d: f64, [lo, hi]: [f64; 2]) -> bool {
    (lo..=hi).contains(&d)
}

fn swapped(l: &Landmarks, (x, y): (LandmarkName, LandmarkName)) -> Landmarks {
    let mut pts = l.points();
    pts.swap(x as usize, y as usize);
    Landmarks::from_points(pts)
}

/// Runs every check its inputs allow: the image checks with a sampler, the distance checks
/// with the atlas's landmarks. A swap the distances suggest is only warned about here: no
/// image can confirm it (see [`check_landmarks_on_image`]). Returns the warnings.
pub fn check_landmarks(
    landmarks: &Landmarks,
    image: Option<&Sampler>,
    atlas: Option<&Landmarks>,
    cfg: &CheckConfig,
) -> Result<Vec<LandmarkWarning>, LandmarkError> {
    check(landmarks, image, atlas, None, cfg)
}

/// Every check, with the image asked about any swap the distances suggest: the atlas placed by
/// the given and by the exchanged labels, probed for bone borders. A swap both confirm is
/// refused; one only the distances suggest is a warning.
pub fn check_landmarks_on_image(
    landmarks: &Landmarks,
    image: &ImageCheck,
    cfg: &CheckConfig,
) -> Result<Vec<LandmarkWarning>, LandmarkError> {
    let atlas = image.atlas.landmark_positions(image.atlas.nodes());
    check(
        landmarks,
        Some(image.sampler),
        Some(&atlas),
        Some(image),
        cfg,
    )
}

fn check(
    landmarks: &Landmarks,
    sampler: Option<&Sampler>,
    atlas: Option<&Landmarks>,
    image: Option<&ImageCheck>,
    cfg: &CheckConfig,
) -> Result<Vec<LandmarkWarning>, LandmarkError> {
    if let Some(sampler) = sampler {
        for name in LandmarkName::ALL {
            let p = landmarks.get(name);
            if !sampler.contains(&p) {
                let ijk = sampler.index_of(&p);
                return Err(LandmarkError::OutsideImage {
                    name: name.key(),
                    x: p.x,
                    y: p.y,
                    z: p.z,
                    i: ijk.x,
                    j: ijk.y,
                    k: ijk.z,
                    dims: sampler.volume().dims,
                });
            }
        }
    }
    let height = smallest_height(landmarks);
    if height < cfg.min_triangle_height_mm {
        return Err(LandmarkError::Collinear {
            height_mm: height,
            min_mm: cfg.min_triangle_height_mm,
        });
    }
    let d = distances(landmarks);
    let da = atlas.map(distances);
    if let Some(da) = da {
        let perimeter = d.iter().sum::<f64>();
        let atlas_perimeter = da.iter().sum::<f64>();
        let scale = perimeter / atlas_perimeter;
        let [lo, hi] = cfg.scale_ratio_range;
        if !(lo..=hi).contains(&scale) {
            return Err(LandmarkError::Scale {
                scale,
                perimeter_mm: perimeter,
                atlas_perimeter_mm: atlas_perimeter,
                min: lo,
                max: hi,
            });
        }
    }
    let bands = cfg.bands();
    let all_typical = |d: &[f64; 3]| (0..3).all(|k| within(d[k], bands[k].typical_mm));
    let mut warnings = Vec::new();

    // exchanged labels: the distances suggest it when the given labelling is not typical and
    // the exchanged one is; the image, when the atlas placed by the exchanged labels lies
    // clearly better on the bone borders (asked for every exchange: where two exchanged
    // distances have overlapping typical bands, the distances cannot tell)
    let given_fit = image.and_then(|img| img.border_fit(landmarks));
    for (x, y) in SWAPS {
        let exchanged = swapped(landmarks, (x, y));
        let ds = distances(&exchanged);
        let by_distances = !all_typical(&d) && all_typical(&ds);
        let evidence = match (image, given_fit) {
            (Some(img), Some(given)) => img
                .border_fit(&exchanged)
                .map(|s| SwapEvidence::of(given, s, cfg.swap_border_gain)),
            _ => None,
        };
        let by_image = evidence.is_some_and(|e| e.confirms_swap);
        if let (true, Some(e)) = (by_distances, evidence.filter(|e| e.confirms_swap)) {
            return Err(LandmarkError::Swapped {
                a: x.key(),
                b: y.key(),
                given_mm: d,
                swapped_mm: ds,
                swapped_found: 100.0 * e.swapped.found_fraction,
                swapped_offset_mm: e.swapped.mean_abs_offset_mm,
                given_found: 100.0 * e.given.found_fraction,
                given_offset_mm: e.given.mean_abs_offset_mm,
            });
        }
        if by_distances || by_image {
            warnings.push(LandmarkWarning::SuspectedSwap {
                a: x.key().into(),
                b: y.key().into(),
                by_distances,
                given_mm: d,
                swapped_mm: ds,
                atlas_mm: da,
                image: evidence,
            });
        }
    }

    for (k, band) in bands.iter().enumerate() {
        if !within(d[k], band.possible_mm) {
            let hint = warnings
                .iter()
                .find_map(|w| match w {
                    LandmarkWarning::SuspectedSwap {
                        a,
                        b,
                        by_distances: true,
                        swapped_mm,
                        image,
                        ..
                    } => Some(format!(
                        "; with {a} and {b} exchanged every distance would be typical \
                         (umbo-IMJ / umbo-ISJ / IMJ-ISJ {}){}",
                        triple(swapped_mm),
                        match image {
                            Some(e) =>
                                format!(", but the image does not confirm it ({})", border_text(e)),
                            None => String::new(),
                        }
                    )),
                    _ => None,
                })
                .unwrap_or_default();
            return Err(LandmarkError::OutsideBand {
                pair: PAIRS[k].2,
                patient_mm: d[k],
                min_mm: band.possible_mm[0],
                max_mm: band.possible_mm[1],
                atlas: da
                    .map(|da| format!("; the atlas has {:.2} mm", da[k]))
                    .unwrap_or_default(),
                hint,
            });
        }
        if !within(d[k], band.typical_mm) {
            warnings.push(LandmarkWarning::UnusualDistance {
                pair: PAIRS[k].2.into(),
                patient_mm: d[k],
                typical_mm: band.typical_mm,
                possible_mm: band.possible_mm,
                atlas_mm: da.map(|da| da[k]),
            });
        }
    }
    if height < cfg.typical_min_height_mm {
        warnings.push(LandmarkWarning::FlatTriangle {
            height_mm: height,
            typical_min_mm: cfg.typical_min_height_mm,
            atlas_height_mm: atlas.map(smallest_height),
        });
    }
    Ok(warnings)
}

#[cfg(test)]
mod tests;
