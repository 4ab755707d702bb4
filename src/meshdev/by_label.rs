//! Where on a scored surface the distances lie: the deviation map summed per label of the
//! surface's triangles (the atlas region each registered triangle bounds), so that a tail of
//! distances is seen as "the stapes's footplate" or "the malleus head", not only as an HD95.
//!
//! Each triangle carries the mean of its three vertices' signed deviations and weighs by its
//! area. "Far" is a distance the caller chooses (`run`: two voxels, the HD95 target), so that a
//! region's far share says how much of it stands beyond what the target allows, and on which
//! side of the reference.

use serde::{Deserialize, Serialize};

use crate::mesh::TriMesh;

/// One label's share of a surface's deviation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LabelDeviation {
    pub label: u16,
    /// Area of the label's triangles \[mm²\].
    pub area_mm2: f64,
    /// Area-weighted mean signed deviation \[mm\] (positive: outside the reference).
    pub mean_signed_mm: f64,
    /// Area-weighted mean |deviation| \[mm\].
    pub mean_abs_mm: f64,
    /// Largest |deviation| of the label's triangles \[mm\].
    pub max_abs_mm: f64,
    /// Share of the label's area farther than `far_mm` outside the reference.
    pub far_outside_share: f64,
    /// Share of the label's area farther than `far_mm` inside the reference.
    pub far_inside_share: f64,
}

/// Sums `deviation` (signed, per vertex of `surface`) per label of `labels` (one per triangle
/// of `surface`), labels in ascending order; `far_mm` splits off the far shares. Triangles
/// without area, without a label (beyond `labels`' end) or with a vertex beyond
/// `deviation`'s end are left out, and so are labels without triangles.
pub fn deviation_by_label(
    surface: &TriMesh,
    deviation: &[f64],
    labels: &[u16],
    far_mm: f64,
) -> Vec<LabelDeviation> {
    // (area, signed, abs, max, far outside, far inside) per label
    let mut sums: std::collections::BTreeMap<u16, [f64; 6]> = std::collections::BTreeMap::new();
    for (t, (triangle, &label)) in surface.triangles.iter().zip(labels).enumerate() {
        let area = surface.triangle_area(t);
        let Some(d) = triangle
            .iter()
            .map(|&v| deviation.get(v as usize).copied())
            .sum::<Option<f64>>()
            .map(|sum| sum / 3.0)
        else {
            continue;
        };
        if !(area > 0.0 && d.is_finite()) {
            continue;
        }
        let s = sums.entry(label).or_insert([0.0; 6]);
        s[0] += area;
        s[1] += area * d;
        s[2] += area * d.abs();
        s[3] = s[3].max(d.abs());
        if d > far_mm {
            s[4] += area;
        } else if d < -far_mm {
            s[5] += area;
        }
    }
    sums.into_iter()
        .map(
            |(label, [area, signed, abs, max, outside, inside])| LabelDeviation {
                label,
                area_mm2: area,
                mean_signed_mm: signed / area,
                mean_abs_mm: abs / area,
                max_abs_mm: max,
                far_outside_share: outside / area,
                far_inside_share: inside / area,
            },
        )
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// Two unit right triangles (area 0.5 each) and one of area 2, three labels.
    fn strip() -> TriMesh {
        TriMesh {
            vertices: vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(1.0, 1.0, 0.0),
                Point3::new(3.0, 0.0, 0.0),
                Point3::new(1.0, 2.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [1, 3, 2], [1, 4, 5]],
        }
    }

    #[test]
    fn each_label_gets_its_triangles_area_weighted_means_and_far_shares() {
        let mesh = strip();
        // triangle means: [0,1,2] (0.3+0.3+0.3)/3 = 0.3; [1,3,2] (0.3-0.9+0.3)/3 = -0.1;
        // [1,4,5] (0.3+0.6+0.6)/3 = 0.5
        let deviation = [0.3, 0.3, 0.3, -0.9, 0.6, 0.6];
        let out = deviation_by_label(&mesh, &deviation, &[7, 7, 2], 0.25);
        assert_eq!(out.len(), 2);
        let (two, seven) = (&out[0], &out[1]);
        assert_eq!((two.label, seven.label), (2, 7));
        // label 2: one triangle of area |(2,0)x(0,2)|/2 = 2, mean 0.5, all of it far outside
        assert!((two.area_mm2 - 2.0).abs() < 1e-12);
        assert!((two.mean_signed_mm - 0.5).abs() < 1e-12);
        assert!((two.far_outside_share - 1.0).abs() < 1e-12 && two.far_inside_share == 0.0);
        // label 7: areas 0.5 and 0.5, means 0.3 and -0.1
        assert!((seven.area_mm2 - 1.0).abs() < 1e-12);
        assert!((seven.mean_signed_mm - 0.1).abs() < 1e-12);
        assert!((seven.mean_abs_mm - 0.2).abs() < 1e-12);
        assert!((seven.max_abs_mm - 0.3).abs() < 1e-12);
        assert!((seven.far_outside_share - 0.5).abs() < 1e-12);
        assert_eq!(seven.far_inside_share, 0.0);
    }

    #[test]
    fn a_far_inside_triangle_counts_on_the_inside() {
        let mesh = strip();
        let deviation = [-0.4, -0.4, -0.4, 0.0, 0.0, 0.0];
        let out = deviation_by_label(&mesh, &deviation, &[1, 1, 1], 0.3);
        // only [0,1,2] (area 0.5, mean -0.4) is far, inside, of 3 mm² in all
        assert!((out[0].far_inside_share - 0.5 / 3.0).abs() < 1e-12);
        assert_eq!(out[0].far_outside_share, 0.0);
    }
}
