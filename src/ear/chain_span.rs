//! How large an ossicular chain is, to tell surfaces in other units than mm.
//!
//! Why: surface files carry no units, and specimen libraries export in µm, cm, m or voxel
//! indices as often as in mm. A chain read in the wrong units would size an image or a mesh
//! lattice 1,000 times too large (or too small) before anything else could notice. The span
//! of the chain's surfaces, their bounding box's diagonal, tells: the real chains at hand span
//! 13.0 mm (SOFA's) and 13.6 mm (the CT-derived one), and ossicle sizes vary by about ±10 %.

use nalgebra::{Point3, Vector3};

/// The bounding-box diagonal an ossicular chain's surfaces may have \[mm\]: about three times
/// either way of a real chain's, so that only other units fall outside.
pub const CHAIN_SPAN_MM: (f64, f64) = (4.0, 40.0);

/// The diagonal of the bounding box of `points` \[mm\] (0 for none).
pub fn span_mm<'a>(points: impl IntoIterator<Item = &'a Point3<f64>>) -> f64 {
    let (lo, hi) = points.into_iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(&p.coords), hi.sup(&p.coords)),
    );
    if lo.x.is_finite() {
        (hi - lo).norm()
    } else {
        0.0
    }
}

/// Whether a chain spanning `span_mm` is in mm ([`CHAIN_SPAN_MM`]).
pub fn is_chain_span(span_mm: f64) -> bool {
    (CHAIN_SPAN_MM.0..=CHAIN_SPAN_MM.1).contains(&span_mm)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_in_mm_spans_within_the_band_and_in_other_units_outside() {
        // a 6 x 8 x 9 mm box, about a real chain's extent: 13.45 mm
        let corners = [Point3::new(1.0, 2.0, 3.0), Point3::new(7.0, 10.0, 12.0)];
        let span = span_mm(&corners);
        assert!((span - 181f64.sqrt()).abs() < 1e-12, "{span}");
        assert!(is_chain_span(span));
        for factor in [1000.0, 100.0, 0.1, 0.001] {
            let scaled: Vec<Point3<f64>> = corners.iter().map(|p| p * factor).collect();
            assert!(!is_chain_span(span_mm(&scaled)), "{factor}");
        }
        assert_eq!(span_mm(&[]), 0.0);
        assert!(!is_chain_span(f64::NAN));
    }
}
