//! Diverging blue–white–red colours for signed deviations over a fixed range.
//!
//! The range is fixed by the caller, not fitted to the data, so maps of different patients
//! compare (Metro's `-C min max` rationale; docs/metrics.md, "The deviation map"). The ramp is
//! ColorBrewer RdBu with 11 classes (Brewer, colorbrewer2.org), ordered blue (min, inside) →
//! white (mid-range) → red (max, outside), linearly interpolated in sRGB; values beyond the
//! range take the end colours.

use super::error::MeshDevError;

/// ColorBrewer RdBu-11, reversed: index 0 = most negative.
const RAMP: [[u8; 3]; 11] = [
    [0x05, 0x30, 0x61],
    [0x21, 0x66, 0xac],
    [0x43, 0x93, 0xc3],
    [0x92, 0xc5, 0xde],
    [0xd1, 0xe5, 0xf0],
    [0xf7, 0xf7, 0xf7],
    [0xfd, 0xdb, 0xc7],
    [0xf4, 0xa5, 0x82],
    [0xd6, 0x60, 0x4d],
    [0xb2, 0x18, 0x2b],
    [0x67, 0x00, 0x1f],
];

/// The signed-distance range (mm) the colour ramp spans.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColourRange {
    pub min_mm: f64,
    pub max_mm: f64,
}

impl Default for ColourRange {
    /// −0.5 … +0.5 mm (about ±2 CBCT voxels; docs/metrics.md).
    fn default() -> Self {
        ColourRange {
            min_mm: -0.5,
            max_mm: 0.5,
        }
    }
}

impl ColourRange {
    /// Checks that the range is finite and not empty.
    pub fn validate(&self) -> Result<(), MeshDevError> {
        if self.min_mm.is_finite() && self.max_mm.is_finite() && self.min_mm < self.max_mm {
            Ok(())
        } else {
            Err(MeshDevError::InvalidOption {
                field: "colour_range",
                value: format!("{} .. {}", self.min_mm, self.max_mm),
                expected: "finite min_mm < max_mm",
            })
        }
    }

    /// The RGB colour of signed deviation `value` (mm); NaN maps to mid-range white.
    pub fn colour(&self, value: f64) -> [u8; 3] {
        let t = ((value - self.min_mm) / (self.max_mm - self.min_mm)).clamp(0.0, 1.0);
        let x = if t.is_nan() { 0.5 } else { t } * (RAMP.len() - 1) as f64;
        let i = (x.floor() as usize).min(RAMP.len() - 2);
        let f = x - i as f64;
        let (lo, hi) = (RAMP[i], RAMP[i + 1]);
        std::array::from_fn(|k| (lo[k] as f64 + (hi[k] as f64 - lo[k] as f64) * f).round() as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_centre_and_monotone_halves() {
        let r = ColourRange::default();
        assert_eq!(r.colour(-0.5), [0x05, 0x30, 0x61]);
        assert_eq!(r.colour(-3.0), [0x05, 0x30, 0x61]);
        assert_eq!(r.colour(0.0), [0xf7, 0xf7, 0xf7]);
        assert_eq!(r.colour(0.5), [0x67, 0x00, 0x1f]);
        assert_eq!(r.colour(9.0), [0x67, 0x00, 0x1f]);
        assert_eq!(r.colour(f64::NAN), [0xf7, 0xf7, 0xf7]);
        // Negative values are blue-dominant, positive red-dominant.
        for i in 1..50 {
            let v = i as f64 / 100.0;
            let (neg, pos) = (r.colour(-v), r.colour(v));
            assert!(neg[2] > neg[0] && pos[0] > pos[2], "{v}: {neg:?} {pos:?}");
        }
        // A different fixed range rescales, it does not refit.
        let wide = ColourRange {
            min_mm: -1.0,
            max_mm: 1.0,
        };
        assert_eq!(wide.colour(0.5), r.colour(0.25));
    }

    #[test]
    fn invalid_ranges_are_rejected() {
        for (a, b) in [
            (0.5, 0.5),
            (1.0, -1.0),
            (f64::NAN, 1.0),
            (0.0, f64::INFINITY),
        ] {
            let r = ColourRange {
                min_mm: a,
                max_mm: b,
            };
            assert!(matches!(
                r.validate(),
                Err(MeshDevError::InvalidOption {
                    field: "colour_range",
                    ..
                })
            ));
        }
    }
}
