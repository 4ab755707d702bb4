//! The side of the ear. Three landmarks cannot tell a left ear from a right one (a triangle
//! and its mirror image are congruent), so the side always comes from data or from the user.

use serde::{Deserialize, Serialize};

/// Left or right ear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}

impl Side {
    /// Parses DICOM Laterality/ImageLaterality ("R", "L") or a word ("right", "left").
    /// "B" (both) and "U" (unpaired) say nothing about one ear and give `None`.
    pub fn parse(text: &str) -> Option<Side> {
        match text.trim().to_ascii_lowercase().as_str() {
            "r" | "right" => Some(Side::Right),
            "l" | "left" => Some(Side::Left),
            _ => None,
        }
    }

    /// "left" or "right".
    pub fn as_str(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// The other ear: the side of this ear's mirror image.
    pub fn other(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }

    /// The DICOM Laterality code.
    pub fn dicom_code(self) -> &'static str {
        match self {
            Side::Left => "L",
            Side::Right => "R",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_dicom_codes_and_words() {
        assert_eq!(Side::parse("R"), Some(Side::Right));
        assert_eq!(Side::parse(" left "), Some(Side::Left));
        assert_eq!(Side::parse("B"), None);
        assert_eq!(Side::parse("U"), None);
        assert_eq!(Side::parse(Side::Left.dicom_code()), Some(Side::Left));
    }

    #[test]
    fn the_other_side_of_the_other_side_is_the_side() {
        assert_eq!(Side::Left.other(), Side::Right);
        assert_eq!(Side::Right.other(), Side::Left);
        assert_eq!(Side::Left.other().other(), Side::Left);
    }
}
