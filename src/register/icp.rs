//! Trimmed point-to-surface ICP: a similarity that carries sample points onto a surface,
//! refined from a start by alternating closest points and a least-squares fit.
//!
//! Why trimmed: the points and the surface rarely cover the same anatomy (an atlas's processes
//! a segmentation lacks, a chain's fused joints), and the pairs that reach across such a
//! difference would pull the fit; each iteration keeps only the closest pairs, by a share of
//! them or by a distance. The scale is fitted (Umeyama) or kept from the start (a CT-derived
//! surface is inflated by partial volume, which a fitted scale would absorb).

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::rigid::{SimilarityTransform, fit_similarity};
use crate::mesh::spatial::Bvh;

/// Which pairs each iteration keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Trim {
    /// This share of the pairs, the closest \[fraction\].
    Share(f64),
    /// The pairs closer than this \[mm\].
    Distance(f64),
}

/// How an ICP runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpOptions {
    pub iterations: usize,
    pub trim: Trim,
    /// Fit the scale; otherwise keep the start's.
    pub with_scale: bool,
    /// Done when no point of every `check_stride`-th sample moved more than `tolerance_mm`
    /// in an iteration.
    pub check_stride: usize,
    pub tolerance_mm: f64,
}

/// Where an ICP ended: the transform, and the mean distance of the pairs the last fit kept
/// \[mm\] (infinite if no fit was made).
#[derive(Debug, Clone, Copy)]
pub struct IcpFit {
    pub transform: SimilarityTransform,
    pub mean_kept_mm: f64,
}

/// Refines `start` so that it carries `samples` onto `surface`. Stops early when fewer than
/// three pairs are kept or their fit is degenerate, keeping the transform reached.
pub fn trimmed_icp(
    samples: &[Point3<f64>],
    surface: &Bvh,
    start: SimilarityTransform,
    options: &IcpOptions,
) -> IcpFit {
    let mut t = start;
    let mut mean = f64::INFINITY;
    for _ in 0..options.iterations {
        let mut pairs: Vec<(Point3<f64>, Point3<f64>, f64)> = samples
            .par_iter()
            .map(|a| {
                let hit = surface.closest(&t.apply(a));
                (*a, hit.point, hit.distance)
            })
            .collect();
        match options.trim {
            Trim::Share(share) => {
                pairs.sort_by(|a, b| a.2.total_cmp(&b.2));
                pairs.truncate(((pairs.len() as f64) * share).ceil() as usize);
            }
            Trim::Distance(limit) => pairs.retain(|p| p.2 < limit),
        }
        if pairs.len() < 3 {
            break;
        }
        mean = pairs.iter().map(|p| p.2).sum::<f64>() / pairs.len() as f64;
        // with the scale kept, a rigid fit of the samples scaled by it
        let scale = if options.with_scale { 1.0 } else { t.scale };
        let source: Vec<Point3<f64>> = pairs.iter().map(|p| p.0 * scale).collect();
        let target: Vec<Point3<f64>> = pairs.iter().map(|p| p.1).collect();
        let Some(fit) = fit_similarity(&source, &target, options.with_scale) else {
            break;
        };
        let next = if options.with_scale {
            fit.transform
        } else {
            SimilarityTransform::new(
                fit.transform.rotation_matrix(),
                Vector3::from(fit.transform.translation),
                t.scale,
            )
        };
        let moved = samples
            .iter()
            .step_by(options.check_stride.max(1))
            .map(|a| (next.apply(a) - t.apply(a)).norm())
            .fold(0.0, f64::max);
        t = next;
        if moved < options.tolerance_mm {
            break;
        }
    }
    IcpFit {
        transform: t,
        mean_kept_mm: mean,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::icosphere;
    use nalgebra::Rotation3;

    /// An ellipsoid's vertices, turned, moved and scaled, are brought back onto the ellipsoid
    /// from a start 6° and 0.3 mm off: with the scale fitted, the known similarity; with the
    /// scale kept, the known rotation and translation when the start has the true scale, and
    /// the start's scale when it has not.
    #[test]
    fn icp_recovers_a_known_similarity() {
        let mut mesh = icosphere(Point3::origin(), 1.0, 4);
        mesh.vertices
            .iter_mut()
            .for_each(|p| *p = Point3::new(2.0 * p.x, 1.2 * p.y, 0.8 * p.z));
        let surface = Bvh::new(&mesh, "ellipsoid").unwrap();
        let truth = SimilarityTransform::new(
            *Rotation3::from_euler_angles(0.3, -0.2, 0.5).matrix(),
            Vector3::new(1.0, -2.0, 0.5),
            1.1,
        );
        let inverse = truth.inverse();
        let samples: Vec<Point3<f64>> = mesh.vertices.iter().map(|p| inverse.apply(p)).collect();
        let nudge = Rotation3::from_euler_angles(0.06, 0.05, -0.08);
        for (with_scale, start_scale, trim) in [
            (true, 1.0, Trim::Share(0.9)),
            (false, truth.scale, Trim::Distance(1.0)),
            (false, 1.2, Trim::Distance(1.0)),
        ] {
            let start = SimilarityTransform::new(
                nudge.matrix() * truth.rotation_matrix(),
                Vector3::from(truth.translation) + Vector3::new(0.3, -0.2, 0.1),
                start_scale,
            );
            let options = IcpOptions {
                iterations: 200,
                trim,
                with_scale,
                check_stride: 1,
                tolerance_mm: 1e-9,
            };
            let fit = trimmed_icp(&samples, &surface, start, &options);
            if with_scale || start_scale == truth.scale {
                let worst = samples
                    .iter()
                    .map(|p| (fit.transform.apply(p) - truth.apply(p)).norm())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-4, "with_scale {with_scale}: {worst} mm");
                assert!(fit.mean_kept_mm < 1e-4, "{}", fit.mean_kept_mm);
            } else {
                assert_eq!(fit.transform.scale, start_scale);
                assert!(fit.mean_kept_mm > 1e-3, "{}", fit.mean_kept_mm);
            }
        }
    }
}
