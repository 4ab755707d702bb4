//! Checks on the three landmarks before anything runs: each inside the image, the three not
//! collinear, and their distances plausible against the atlas's (a swapped pair is detected
//! and named). Each failure is a message with the numbers.
//!
//! Exchanging two labels keeps their own distance and exchanges the two distances to the third
//! landmark, so a swap is visible here only when those two distances differ by more than the
//! shape tolerance.

use serde::{Deserialize, Serialize};

use super::{LandmarkError, LandmarkName, Landmarks};
use crate::image::Sampler;

/// Tolerances of the landmark checks (`[landmarks]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckConfig {
    /// Smallest height of the landmark triangle [mm]; below it the rigid fit is undetermined.
    pub min_triangle_height_mm: f64,
    /// Allowed patient/atlas ratio of the overall landmark scale [unitless, min and max].
    pub scale_ratio_range: [f64; 2],
    /// Largest relative deviation of one landmark distance from the atlas's after the overall
    /// scale is taken out [fraction].
    pub shape_tolerance: f64,
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

fn distances(l: &Landmarks) -> [f64; 3] {
    PAIRS.map(|(a, b, _)| (l.get(a) - l.get(b)).norm())
}

/// Best overall scale and the worst relative residual of the three distances after it.
fn shape_error(patient: &[f64; 3], atlas: &[f64; 3]) -> (f64, f64) {
    let ratios: Vec<f64> = patient.iter().zip(atlas).map(|(p, a)| p / a).collect();
    let scale = ratios.iter().sum::<f64>() / 3.0;
    let worst = ratios
        .iter()
        .map(|r| (r / scale - 1.0).abs())
        .fold(0.0, f64::max);
    (scale, worst)
}

/// Runs every check that its inputs allow: the image checks with a sampler, the distance
/// checks with the atlas's landmarks.
pub fn check_landmarks(
    landmarks: &Landmarks,
    image: Option<&Sampler>,
    atlas: Option<&Landmarks>,
    cfg: &CheckConfig,
) -> Result<(), LandmarkError> {
    if let Some(sampler) = image {
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
    let d = distances(landmarks);
    let [a, b, c] = landmarks.points();
    let area2 = (b - a).cross(&(c - a)).norm();
    let height = area2 / d.iter().copied().fold(f64::MIN_POSITIVE, f64::max);
    if height < cfg.min_triangle_height_mm {
        return Err(LandmarkError::Collinear {
            height_mm: height,
            min_mm: cfg.min_triangle_height_mm,
        });
    }
    let Some(atlas) = atlas else { return Ok(()) };
    let da = distances(atlas);
    let (scale, error) = shape_error(&d, &da);
    if error > cfg.shape_tolerance {
        // would exchanging two labels explain it?
        let swaps = [
            (LandmarkName::Umbo, LandmarkName::Incudomalleolar),
            (LandmarkName::Umbo, LandmarkName::Incudostapedial),
            (LandmarkName::Incudomalleolar, LandmarkName::Incudostapedial),
        ];
        let best = swaps
            .iter()
            .map(|&(x, y)| {
                let mut pts = landmarks.points();
                let (ix, iy) = (x as usize, y as usize);
                pts.swap(ix, iy);
                let (_, e) = shape_error(&distances(&Landmarks::from_points(pts)), &da);
                (x, y, e)
            })
            .min_by(|p, q| p.2.total_cmp(&q.2));
        if let Some((x, y, e)) = best
            && e <= cfg.shape_tolerance
            && e < 0.5 * error
        {
            return Err(LandmarkError::Swapped {
                a: x.key(),
                b: y.key(),
                error: 100.0 * error,
                swapped_error: 100.0 * e,
                patient: d,
                atlas: da,
            });
        }
        let k = (0..3)
            .max_by(|&i, &j| {
                ((d[i] / da[i] / scale) - 1.0)
                    .abs()
                    .total_cmp(&((d[j] / da[j] / scale) - 1.0).abs())
            })
            .unwrap_or(0);
        return Err(LandmarkError::Implausible {
            pair: PAIRS[k].2,
            patient_mm: d[k],
            atlas_mm: da[k],
            ratio: d[k] / da[k],
            min_ratio: scale * (1.0 - cfg.shape_tolerance),
            max_ratio: scale * (1.0 + cfg.shape_tolerance),
        });
    }
    let [lo, hi] = cfg.scale_ratio_range;
    if !(lo..=hi).contains(&scale) {
        let k = 2;
        return Err(LandmarkError::Implausible {
            pair: PAIRS[k].2,
            patient_mm: d[k],
            atlas_mm: da[k],
            ratio: d[k] / da[k],
            min_ratio: lo,
            max_ratio: hi,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Rotation3, Vector3};

    fn cfg() -> CheckConfig {
        CheckConfig {
            min_triangle_height_mm: 1.0,
            scale_ratio_range: [0.7, 1.4],
            shape_tolerance: 0.15,
        }
    }

    /// Landmarks with umbo-IMJ 6.75, umbo-ISJ 3.0, IMJ-ISJ 4.5 mm: every two distances differ
    /// by 50 %, so every swap of two labels is visible in the distances. (A swap exchanges
    /// two of the three distances; where those are alike, no distance check can see it.)
    fn atlas() -> Landmarks {
        Landmarks {
            umbo: Point3::new(0.0, 0.0, 0.0),
            incudomalleolar: Point3::new(0.0, 0.0, 6.75),
            incudostapedial: Point3::new(-1.593_738, 0.0, 2.541_667),
        }
    }

    fn moved(l: &Landmarks, scale: f64) -> Landmarks {
        let r = Rotation3::from_euler_angles(0.4, 1.0, -0.7);
        let t = Vector3::new(10.0, -20.0, 35.0);
        Landmarks::from_points(l.points().map(|p| Point3::from(r * (p.coords * scale) + t)))
    }

    #[test]
    fn a_moved_and_scaled_atlas_passes() {
        check_landmarks(&moved(&atlas(), 1.08), None, Some(&atlas()), &cfg()).unwrap();
    }

    #[test]
    fn each_swapped_pair_is_named() {
        for (x, y) in [(0, 1), (0, 2), (1, 2)] {
            let mut pts = moved(&atlas(), 0.95).points();
            pts.swap(x, y);
            let err = check_landmarks(&Landmarks::from_points(pts), None, Some(&atlas()), &cfg())
                .unwrap_err();
            match err {
                LandmarkError::Swapped { a, b, .. } => {
                    assert_eq!(
                        [a, b],
                        [LandmarkName::ALL[x].key(), LandmarkName::ALL[y].key()]
                    );
                }
                other => panic!("swap {x}<->{y}: {other}"),
            }
        }
    }

    #[test]
    fn collinear_and_implausible_scale_are_rejected() {
        let line = Landmarks {
            umbo: Point3::new(0.0, 0.0, 0.0),
            incudomalleolar: Point3::new(0.0, 0.0, 6.0),
            incudostapedial: Point3::new(0.0, 0.3, 3.0),
        };
        assert!(matches!(
            check_landmarks(&line, None, None, &cfg()),
            Err(LandmarkError::Collinear { .. })
        ));
        let huge = moved(&atlas(), 2.0);
        assert!(matches!(
            check_landmarks(&huge, None, Some(&atlas()), &cfg()),
            Err(LandmarkError::Implausible { .. })
        ));
    }
}
