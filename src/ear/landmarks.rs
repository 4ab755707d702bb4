//! The three landmarks of the method (Kazmitcheff et al. 2013, section 3): the umbo, the
//! incudomalleolar joint and the incudostapedial joint, in LPS millimetres, with the names and
//! aliases people write them with.

use nalgebra::Point3;
use serde::Serialize;

/// One of the three landmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LandmarkName {
    Umbo,
    Incudomalleolar,
    Incudostapedial,
}

impl LandmarkName {
    /// The three, in the order of the method (p_a, p_b, p_c).
    pub const ALL: [LandmarkName; 3] = [
        LandmarkName::Umbo,
        LandmarkName::Incudomalleolar,
        LandmarkName::Incudostapedial,
    ];

    /// Canonical file key.
    pub fn key(self) -> &'static str {
        match self {
            LandmarkName::Umbo => "umbo",
            LandmarkName::Incudomalleolar => "incudomalleolar",
            LandmarkName::Incudostapedial => "incudostapedial",
        }
    }

    /// A label as people write it: case-insensitive, with or without "joint", and the usual
    /// abbreviations (IMJ, ISJ).
    pub fn parse(label: &str) -> Option<LandmarkName> {
        let norm: String = label
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect::<String>()
            .to_ascii_lowercase();
        let norm = norm.strip_suffix("joint").unwrap_or(&norm);
        match norm {
            "umbo" | "u" => Some(LandmarkName::Umbo),
            "imj" | "im" | "incudomalleolar" | "incudomallear" | "incudomalleal"
            | "malleoincudal" => Some(LandmarkName::Incudomalleolar),
            "isj" | "is" | "incudostapedial" | "stapedioincudal" => {
                Some(LandmarkName::Incudostapedial)
            }
            _ => None,
        }
    }
}

/// The three landmarks in LPS millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmarks {
    pub umbo: Point3<f64>,
    pub incudomalleolar: Point3<f64>,
    pub incudostapedial: Point3<f64>,
}

impl Landmarks {
    /// The landmark named `name`.
    pub fn get(&self, name: LandmarkName) -> Point3<f64> {
        match name {
            LandmarkName::Umbo => self.umbo,
            LandmarkName::Incudomalleolar => self.incudomalleolar,
            LandmarkName::Incudostapedial => self.incudostapedial,
        }
    }

    /// The three points in method order.
    pub fn points(&self) -> [Point3<f64>; 3] {
        LandmarkName::ALL.map(|n| self.get(n))
    }

    /// Builds from points in method order.
    pub fn from_points(p: [Point3<f64>; 3]) -> Landmarks {
        Landmarks {
            umbo: p[0],
            incudomalleolar: p[1],
            incudostapedial: p[2],
        }
    }
}
