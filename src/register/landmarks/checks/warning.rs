//! What the landmark checks warn about (`LandmarkWarning`): an unusual but possible triangle,
//! a suspected label swap, a side chosen against the data, a pick far from the registration,
//! a stapes with little edge support; each with its figures, and each said in one sentence
//! that tells the user what to check.

use serde::{Deserialize, Serialize};

use crate::register::landmarks::image_check::SwapEvidence;

/// Something unusual but possible about the landmarks: the case runs, the user is told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LandmarkWarning {
    /// A distance outside its typical band (inside its possible band).
    UnusualDistance {
        /// "umbo-IMJ", "umbo-ISJ" or "IMJ-ISJ".
        pair: String,
        patient_mm: f64,
        typical_mm: [f64; 2],
        possible_mm: [f64; 2],
        atlas_mm: Option<f64>,
    },
    /// The triangle's smallest height is below the typical one.
    FlatTriangle {
        height_mm: f64,
        typical_min_mm: f64,
        atlas_height_mm: Option<f64>,
    },
    /// Two labels may be exchanged, but only one of the distances and the image says so (or
    /// there was no image to ask).
    SuspectedSwap {
        a: String,
        b: String,
        /// The distances suggest it: exchanged, every distance is in its typical band, as
        /// given not.
        by_distances: bool,
        /// umbo-IMJ, umbo-ISJ, IMJ-ISJ as given and with `a` and `b` exchanged \[mm\].
        given_mm: [f64; 3],
        swapped_mm: [f64; 3],
        atlas_mm: Option<[f64; 3]>,
        /// The image's verdict, when there was an image.
        image: Option<SwapEvidence>,
    },
    /// `--side` chose the ear against what the landmark file or the image says.
    SideOverridden {
        chosen: crate::ear::Side,
        /// Each disagreeing source and its side, e.g. "DICOM laterality: right".
        against: Vec<String>,
    },
    /// The side stated (`--side` or the DICOM laterality) is not the side whose chain fits
    /// the image: the mirrored chain fits clearly better.
    HandednessDisagrees {
        stated: crate::ear::Side,
        /// "--side" or "DICOM laterality".
        source: String,
        /// How much worse the stated side's chain fits \[fraction\].
        margin: f64,
    },
    /// The registered atlas puts a landmark far from its pick: the image does not agree with
    /// the pick (or with its label).
    FarFromRegistration {
        /// "umbo", "incudomalleolar" or "incudostapedial".
        landmark: String,
        distance_mm: f64,
        limit_mm: f64,
    },
    /// Little of a registered ossicle's surface lies on a bone edge (`register::support`):
    /// its pose, which the landmarks start (the stapes's about the ISJ pick), may be wrong.
    WeakEdgeSupport {
        ossicle: String,
        /// The share of its surface on an edge, and the share below which this is said.
        share: f64,
        limit: f64,
    },
}

impl LandmarkWarning {
    /// What the warning is about, for its prefix in logs and reports: "registration" for the
    /// registered pose's own (`WeakEdgeSupport`), "landmark" for the others.
    pub fn subject(&self) -> &'static str {
        match self {
            LandmarkWarning::WeakEdgeSupport { .. } => "registration",
            _ => "landmark",
        }
    }
}

fn band_text([lo, hi]: [f64; 2]) -> String {
    format!("{lo:.2}-{hi:.2} mm")
}

pub(super) fn triple(d: &[f64; 3]) -> String {
    format!("{:.2} / {:.2} / {:.2} mm", d[0], d[1], d[2])
}

pub(super) fn border_text(e: &SwapEvidence) -> String {
    format!(
        "a bone border found from {:.0} % of the atlas's surface triangles at a mean |offset| of \
         {:.2} mm with the labels exchanged, {:.0} % and {:.2} mm as given",
        100.0 * e.swapped.found_fraction,
        e.swapped.mean_abs_offset_mm,
        100.0 * e.given.found_fraction,
        e.given.mean_abs_offset_mm
    )
}

impl std::fmt::Display for LandmarkWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LandmarkWarning::UnusualDistance {
                pair,
                patient_mm,
                typical_mm,
                possible_mm,
                atlas_mm,
            } => {
                write!(
                    f,
                    "{pair} is {patient_mm:.2} mm, outside its typical band {} (possible {})",
                    band_text(*typical_mm),
                    band_text(*possible_mm)
                )?;
                if let Some(a) = atlas_mm {
                    write!(f, "; the atlas has {a:.2} mm")?;
                }
                write!(f, ": unusual but possible, check the picks on the overlays")
            }
            LandmarkWarning::FlatTriangle {
                height_mm,
                typical_min_mm,
                atlas_height_mm,
            } => {
                write!(
                    f,
                    "the landmark triangle is flat: its smallest height is {height_mm:.2} mm \
                     (typically at least {typical_min_mm:.2} mm"
                )?;
                if let Some(a) = atlas_height_mm {
                    write!(f, "; the atlas's is {a:.2} mm")?;
                }
                write!(
                    f,
                    "); the rigid fit's rotation about the longest side depends strongly on the picks"
                )
            }
            LandmarkWarning::SuspectedSwap {
                a,
                b,
                by_distances,
                given_mm,
                swapped_mm,
                atlas_mm,
                image,
            } => {
                let atlas = match atlas_mm {
                    Some(d) => format!("; the atlas has {}", triple(d)),
                    None => String::new(),
                };
                match (by_distances, image) {
                    (true, None) => write!(
                        f,
                        "landmarks {a} and {b} may be swapped: exchanged, every distance is in \
                         its typical band (umbo-IMJ / umbo-ISJ / IMJ-ISJ {} instead of {}{atlas}); \
                         no image was checked, kept as given",
                        triple(swapped_mm),
                        triple(given_mm),
                    ),
                    (true, Some(e)) => write!(
                        f,
                        "landmarks {a} and {b} may be swapped: exchanged, every distance is in \
                         its typical band (umbo-IMJ / umbo-ISJ / IMJ-ISJ {} instead of {}{atlas}), \
                         but the image does not confirm it ({}); kept as given",
                        triple(swapped_mm),
                        triple(given_mm),
                        border_text(e)
                    ),
                    (false, image) => write!(
                        f,
                        "landmarks {a} and {b} may be swapped: the atlas placed by the exchanged \
                         labels fits the image's bone borders clearly better ({}), but the \
                         distances cannot tell (umbo-IMJ / umbo-ISJ / IMJ-ISJ {} as given, {} \
                         exchanged{atlas}); kept as given: check the labels on the overlays",
                        image.as_ref().map(border_text).unwrap_or_default(),
                        triple(given_mm),
                        triple(swapped_mm),
                    ),
                }
            }
            LandmarkWarning::SideOverridden { chosen, against } => write!(
                f,
                "--side {} overrides {}: check that the image and the landmarks are of this ear",
                chosen.as_str(),
                against.join(" and ")
            ),
            LandmarkWarning::HandednessDisagrees {
                stated,
                source,
                margin,
            } => write!(
                f,
                "the {source} says the {} ear, but the chain in the image is the other ear's: \
                 the {} ear's chain fits it {:.0} % worse than its mirror image; kept as \
                 stated: check that the image and the side are of this ear",
                stated.as_str(),
                stated.as_str(),
                100.0 * margin
            ),
            LandmarkWarning::FarFromRegistration {
                landmark,
                distance_mm,
                limit_mm,
            } => write!(
                f,
                "the registered atlas puts the {landmark} {distance_mm:.2} mm from its pick \
                 (more than {limit_mm:.1} mm): the image does not agree with the pick; check it \
                 (the crosses on the overlays), or compare with `otoatlas landmarks --auto`"
            ),
            LandmarkWarning::WeakEdgeSupport {
                ossicle,
                share,
                limit,
            } => write!(
                f,
                "only {:.0} % of the registered {ossicle}'s surface lies on a bone edge (below \
                 {:.0} %): its pose may be wrong (on test phantoms such a stapes lay 0.4-0.8 mm \
                 off, turned about its head); check it on the overlays, and the \
                 incudostapedial pick it is turned about",
                100.0 * share,
                100.0 * limit
            ),
        }
    }
}
