//! Directed and symmetric surface-distance statistics from weighted samples.
//!
//! Definitions exactly as docs/metrics.md (with their sources: Metro, MESH, DeepMind):
//! directed A→B weighted mean, RMS, max and P95, where P95 is DeepMind
//! `compute_robust_hausdorff`'s weighted percentile (sort by distance, cumulative normalised
//! area, `searchsorted(0.95)` with numpy's default left side, index clamped to the last
//! sample); symmetric MASD = ½(mean_A→B + mean_B→A), ASSD and RMS pooled over both
//! directions by area, HD = max of directed maxima (Metro, MESH), HD95 = max of directed
//! P95, signed bias = area-weighted mean of the signed A→B distances, and Surface Dice at
//! tolerance τ = (Σ area_A[d ≤ τ] + Σ area_B[d ≤ τ]) / (Σ area_A + Σ area_B) (DeepMind
//! `compute_surface_dice_at_tolerance`). A is the test (registered) surface, B the reference.

use rayon::prelude::*;

/// Statistics of one direction (samples of one surface against the other), in mm and mm².
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Directed {
    /// Number of samples.
    pub samples: usize,
    /// Sum of sample weights (the sampled surface's area, mm²).
    pub area_mm2: f64,
    pub mean: f64,
    pub rms: f64,
    pub max: f64,
    pub p95: f64,
    /// Area whose distance is within the Surface Dice tolerance (mm²).
    pub within_tolerance_mm2: f64,
}

/// The symmetric comparison of a test surface with a reference (mm; `surface_dice` in 0..1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceDistances {
    /// Mean absolute surface distance ½(mean test→ref + mean ref→test): the headline.
    pub masd: f64,
    /// Average symmetric surface distance, pooled by area over both directions.
    pub assd: f64,
    /// Root mean square distance, pooled by area over both directions.
    pub rms: f64,
    /// Hausdorff distance: max of the directed maxima.
    pub hd: f64,
    /// Max of the directed weighted 95th percentiles.
    pub hd95: f64,
    /// Area-weighted mean signed test→ref distance; positive = test outside the reference.
    pub bias: f64,
    /// Surface Dice at `tolerance_mm`.
    pub surface_dice: f64,
    pub mean_test_to_ref: f64,
    pub mean_ref_to_test: f64,
    /// MeshDev-compatible one-sided mean over test vertices (one vertex, one vote).
    pub meshdev_mean: f64,
    /// MeshDev-compatible one-sided max over test vertices.
    pub meshdev_max: f64,
    /// Surface Dice tolerance τ (mm).
    pub tolerance_mm: f64,
    pub test_to_ref: Directed,
    pub ref_to_test: Directed,
}

/// The weighted `fraction`-quantile as DeepMind `compute_robust_hausdorff`: with samples
/// sorted by distance, the distance at the first index whose cumulative weight divided by
/// the total weight is ≥ `fraction` (the last sample if none). `sorted` holds
/// (distance, weight) in ascending distance; NaN if it is empty.
pub fn weighted_percentile(sorted: &[(f64, f64)], fraction: f64) -> f64 {
    let total: f64 = sorted.iter().map(|s| s.1).sum();
    let mut cumulative = 0.0;
    for (i, &(d, w)) in sorted.iter().enumerate() {
        cumulative += w;
        if cumulative / total >= fraction || i + 1 == sorted.len() {
            return d;
        }
    }
    f64::NAN
}

/// Area-weighted mean of `values` (summed sequentially, so the result does not depend on
/// the thread count).
pub fn weighted_mean(values: &[f64], weights: &[f64]) -> f64 {
    let (sum, total) = values
        .iter()
        .zip(weights)
        .fold((0.0, 0.0), |a, (v, w)| (a.0 + v * w, a.1 + w));
    sum / total
}

/// Directed statistics of unsigned `distances` with sample `weights`; `tolerance` is the
/// Surface Dice τ (mm).
pub fn directed(distances: &[f64], weights: &[f64], tolerance: f64) -> Directed {
    let mut sorted: Vec<(f64, f64)> = distances
        .iter()
        .copied()
        .zip(weights.iter().copied())
        .collect();
    // Ties broken by weight: identical inputs give identical sums whatever the thread count.
    sorted.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let (mut area, mut sum, mut sum2, mut within) = (0.0, 0.0, 0.0, 0.0);
    for &(d, w) in &sorted {
        area += w;
        sum += w * d;
        sum2 += w * d * d;
        if d <= tolerance {
            within += w;
        }
    }
    Directed {
        samples: sorted.len(),
        area_mm2: area,
        mean: sum / area,
        rms: (sum2 / area).sqrt(),
        max: sorted.last().map_or(f64::NAN, |s| s.0),
        p95: weighted_percentile(&sorted, 0.95),
        within_tolerance_mm2: within,
    }
}

/// Symmetric statistics from the two directions, the signed test→ref bias, and the
/// MeshDev-mode per-vertex test→ref distances.
pub fn symmetric(
    test_to_ref: Directed,
    ref_to_test: Directed,
    bias: f64,
    vertex_distances: &[f64],
    tolerance_mm: f64,
) -> SurfaceDistances {
    let (a, b) = (&test_to_ref, &ref_to_test);
    let area = a.area_mm2 + b.area_mm2;
    let meshdev_mean = vertex_distances.iter().sum::<f64>() / vertex_distances.len() as f64;
    let meshdev_max = vertex_distances.iter().copied().fold(f64::NAN, f64::max);
    SurfaceDistances {
        masd: 0.5 * (a.mean + b.mean),
        assd: (a.mean * a.area_mm2 + b.mean * b.area_mm2) / area,
        rms: ((a.rms * a.rms * a.area_mm2 + b.rms * b.rms * b.area_mm2) / area).sqrt(),
        hd: a.max.max(b.max),
        hd95: a.p95.max(b.p95),
        bias,
        surface_dice: (a.within_tolerance_mm2 + b.within_tolerance_mm2) / area,
        mean_test_to_ref: a.mean,
        mean_ref_to_test: b.mean,
        meshdev_mean,
        meshdev_max,
        tolerance_mm,
        test_to_ref,
        ref_to_test,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p95_of_equal_weights_is_the_95th_value() {
        // d = 1..100 shuffled, equal weights: cumulative k/100 reaches 0.95 at d = 95.
        let d: Vec<f64> = (0..100).map(|i| ((i * 37) % 100 + 1) as f64).collect();
        let s = directed(&d, &vec![2.0; 100], 10.0);
        assert_eq!(s.p95, 95.0);
        assert_eq!(s.max, 100.0);
        assert!((s.mean - 50.5).abs() < 1e-12);
        assert!((s.rms - (338_350.0f64 / 100.0).sqrt()).abs() < 1e-12);
        assert_eq!(s.within_tolerance_mm2, 20.0);
        assert_eq!(s.area_mm2, 200.0);
    }

    #[test]
    fn p95_follows_the_area_not_the_count() {
        // Cumulative normalised weights 0.5, 0.8, 0.95, 1.0: searchsorted(0.95) is index 2.
        let s = directed(&[4.0, 1.0, 3.0, 2.0], &[1.0, 10.0, 3.0, 6.0], 0.0);
        assert_eq!(s.p95, 3.0);
        // One sample past 95 % of the area: the big-weight sample sets P95.
        let s = directed(&[0.1, 7.0], &[1.0, 99.0], 0.0);
        assert_eq!(s.p95, 7.0);
        // A heavy small distance hides a light outlier from P95 but not from the max.
        let s = directed(&[0.1, 7.0], &[99.0, 1.0], 0.0);
        assert_eq!((s.p95, s.max), (0.1, 7.0));
    }

    #[test]
    fn symmetric_definitions() {
        let a = directed(&[1.0, 3.0], &[1.0, 1.0], 1.5); // mean 2, area 2
        let b = directed(&[2.0], &[6.0], 1.5); // mean 2... area 6
        let s = symmetric(a, b, -0.25, &[0.5, 1.5, 4.0], 1.5);
        assert!((s.masd - 2.0).abs() < 1e-15);
        assert!((s.assd - (4.0 + 12.0) / 8.0).abs() < 1e-15);
        assert!((s.rms - ((1.0 + 9.0 + 24.0) / 8.0f64).sqrt()).abs() < 1e-15);
        assert_eq!((s.hd, s.hd95, s.bias), (3.0, 3.0, -0.25));
        assert!((s.surface_dice - 1.0 / 8.0).abs() < 1e-15);
        assert_eq!((s.meshdev_mean, s.meshdev_max), (2.0, 4.0));
    }
}
