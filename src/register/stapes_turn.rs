//! The stapes's turn about its head, searched over a wide cone before the articulation.
//!
//! Why: the landmarks place the malleus and the incus (the umbo and both joints lie on them),
//! but of the stapes they fix only the head (the incudostapedial joint). Its direction, to the
//! footplate in the oval window, is the atlas's, and people differ: on the CT-derived test
//! chain the atlas's stapes lies 20-25° off about its head, so its footplate and crura miss
//! the image's by more than the articulation's probes (1.5 mm) reach, and the local fit stays
//! where it started.
//!
//! Method: every turn about the head on a grid (tilts of the head-to-footplate axis up to
//! `max_tilt_deg` in 5° steps and 15° of azimuth, each with a spin about the turned axis of
//! ±40° in 10° steps) is scored by the bone-edge contrast across the stapes's surface: the
//! area-weighted mean of the image just inside minus just outside each outer triangle. A
//! surface lying on the bone's edges scores high; one in air or buried in the otic capsule
//! scores near zero. The best turn (no turn among the candidates) is the articulation's start.
//!
//! The head is where the landmark placement put the atlas's, and on a chain of other
//! proportions that is a few tenths of a millimetre off the image's: a turn about the wrong
//! point cannot lay the crura and the footplate on their edges, and the search then chose
//! turns of 30-60° that the articulation's local fit could not undo (stapes 0.3-0.6 mm off on
//! 5 of 16 randomly varied CT-chain cases). So the best finalists are scored again with the
//! head shifted by 0 or ±0.25 mm along each axis; the joint ties of the articulation then
//! hold the incus and the stapes together from there.
//!
//! Speed: the 2,601 turns are first screened on every 4th triangle of the surface (the
//! contrast is an area-weighted mean, and a quarter of the triangles still covers the whole
//! stapes), then the 32 best are scored on every triangle, and the 8 best of those with the 26
//! other head shifts (no shift is the finalist's own score): about a third of the samples of
//! scoring every turn on every triangle (the head shifts add a third to the search's cost).

use nalgebra::{Point3, Rotation3, Unit, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::deform::ProbeTriangle;
use crate::image::Sampler;

/// How far inside and outside each triangle the contrast is sampled \[mm\].
const CONTRAST_DEPTH_MM: f64 = 0.1;
/// Grid steps of the tilt, the azimuth and the spin \[deg\].
const TILT_STEP_DEG: f64 = 5.0;
const AZIMUTH_STEP_DEG: f64 = 15.0;
const SPIN_STEP_DEG: f64 = 10.0;
/// Largest spin about the stapes's own axis \[deg\].
const MAX_SPIN_DEG: f64 = 40.0;
/// The screening pass scores every turn on every this many-th surface triangle...
const SCREEN_STRIDE: usize = 4;
/// ... and this many of its best turns are scored again on every triangle.
const FINALISTS: usize = 32;
/// The best this many finalists are scored again with the head shifted by this step along
/// each axis (a 3 x 3 x 3 grid) \[mm\].
const SHIFTED_FINALISTS: usize = 8;
const HEAD_SHIFT_MM: f64 = 0.25;

/// What the search found (part of the articulation's record).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StapesTurn {
    /// Angle of the turn chosen \[deg\] (0: the landmark placement's direction).
    pub turn_deg: f64,
    /// Edge contrast across the stapes's surface before and after the turn \[HU\].
    pub contrast_before_hu: f64,
    pub contrast_after_hu: f64,
    /// Turns scored.
    pub candidates: usize,
    /// How far the stapes's head was moved with the turn chosen \[mm\].
    #[serde(default)]
    pub head_shift_mm: f64,
}

/// The best turn about `head` of the stapes surface `triangles` (nodes at `x`), tilting its
/// axis by up to `max_tilt_deg`; the identity if no candidate scores better or the surface
/// has no area.
pub fn search(
    triangles: &[ProbeTriangle],
    x: &[Point3<f64>],
    head: &Point3<f64>,
    sampler: &Sampler,
    max_tilt_deg: f64,
) -> (Rotation3<f64>, Vector3<f64>, StapesTurn) {
    let patches: Vec<(Point3<f64>, Vector3<f64>, f64)> = triangles
        .iter()
        .filter_map(|t| {
            let [a, b, c] = t.nodes.map(|k| x[k as usize]);
            let cross = (b - a).cross(&(c - a));
            let norm = cross.norm();
            (norm > 0.0).then(|| {
                let centre = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                (centre, cross / norm, 0.5 * norm)
            })
        })
        .collect();
    let area: f64 = patches.iter().map(|p| p.2).sum();
    let centroid = patches
        .iter()
        .fold(Vector3::zeros(), |s, (c, _, a)| s + c.coords * *a)
        / area.max(f64::MIN_POSITIVE);
    // the area-weighted mean contrast of `patches` (total area `area`) after `turn`
    let score_at = |patches: &[(Point3<f64>, Vector3<f64>, f64)],
                    area: f64,
                    turn: &Rotation3<f64>,
                    shift: &Vector3<f64>| {
        patches
            .iter()
            .map(|(c, n, a)| {
                let p = head + shift + turn * (c - head);
                let n = turn * n;
                match (
                    sampler.sample(&(p - n * CONTRAST_DEPTH_MM)),
                    sampler.sample(&(p + n * CONTRAST_DEPTH_MM)),
                ) {
                    (Some(inside), Some(outside)) => a * f64::from(inside - outside),
                    _ => 0.0,
                }
            })
            .sum::<f64>()
            / area
    };
    let score = |patches: &[(Point3<f64>, Vector3<f64>, f64)], area: f64, turn: &Rotation3<f64>| {
        score_at(patches, area, turn, &Vector3::zeros())
    };
    let before = if area > 0.0 {
        score(&patches, area, &Rotation3::identity())
    } else {
        0.0
    };
    let mut record = StapesTurn {
        turn_deg: 0.0,
        contrast_before_hu: before,
        contrast_after_hu: before,
        candidates: 0,
        head_shift_mm: 0.0,
    };
    let axis = centroid - head.coords;
    if area <= 0.0 || axis.norm() <= 0.0 {
        return (Rotation3::identity(), Vector3::zeros(), record);
    }
    let candidates = turns(&Unit::new_normalize(axis), max_tilt_deg);
    record.candidates = candidates.len();
    let screen: Vec<_> = patches.iter().step_by(SCREEN_STRIDE).copied().collect();
    let screen_area: f64 = screen.iter().map(|p| p.2).sum();
    let mut ranked: Vec<(f64, usize)> = candidates
        .par_iter()
        .enumerate()
        .map(|(k, turn)| (score(&screen, screen_area, turn), k))
        .collect();
    // best first; ties in grid order, so the result does not depend on the thread count
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut finalists: Vec<(f64, usize)> = ranked
        .par_iter()
        .take(FINALISTS)
        .map(|&(_, k)| (score(&patches, area, &candidates[k]), k))
        .collect();
    finalists.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    // the best finalists, each with the head where the placement left it (the finalist's own
    // score, first: a tie keeps the head there) or shifted on a grid; the first scoring above
    // every earlier one (and above no turn at all) is kept
    let shifted: Vec<(usize, Vector3<f64>, Option<f64>)> = finalists
        .iter()
        .take(SHIFTED_FINALISTS)
        .flat_map(|&(value, k)| {
            std::iter::once((k, Vector3::zeros(), Some(value)))
                .chain(head_shifts().map(move |shift| (k, shift, None)))
        })
        .collect();
    let (contrast, turn, shift) = shifted
        .par_iter()
        .map(|&(k, shift, known)| {
            let value = known.unwrap_or_else(|| score_at(&patches, area, &candidates[k], &shift));
            (value, k, shift)
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold(
            (before, Rotation3::identity(), Vector3::zeros()),
            |best, (value, k, shift)| {
                if value > best.0 {
                    (value, candidates[k], shift)
                } else {
                    best
                }
            },
        );
    record.turn_deg = turn.angle().to_degrees();
    record.contrast_after_hu = contrast;
    record.head_shift_mm = shift.norm();
    (turn, shift, record)
}

/// The shifts of the head tried with the best finalists besides none: every other
/// combination of 0, +1 and -1 steps along the three axes (26).
fn head_shifts() -> impl Iterator<Item = Vector3<f64>> {
    const STEPS: [f64; 3] = [0.0, HEAD_SHIFT_MM, -HEAD_SHIFT_MM];
    (1..27).map(|k| Vector3::new(STEPS[k % 3], STEPS[k / 3 % 3], STEPS[k / 9]))
}

/// The grid of turns: the stapes's `axis` tilted by 0, 5, ... `max_tilt_deg` degrees towards
/// every azimuth, then spun about the tilted axis.
fn turns(axis: &Unit<Vector3<f64>>, max_tilt_deg: f64) -> Vec<Rotation3<f64>> {
    let helper = if axis.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    let spins = (MAX_SPIN_DEG / SPIN_STEP_DEG).round() as i32;
    let tilts = (max_tilt_deg.max(0.0) / TILT_STEP_DEG).floor() as i32;
    let azimuths = (360.0 / AZIMUTH_STEP_DEG).round() as i32;
    let mut out = Vec::new();
    for tilt in 0..=tilts {
        let tilt = f64::from(tilt) * TILT_STEP_DEG;
        for azimuth in 0..if tilt == 0.0 { 1 } else { azimuths } {
            let azimuth = (f64::from(azimuth) * AZIMUTH_STEP_DEG).to_radians();
            let towards = Unit::new_normalize(u * azimuth.cos() + v * azimuth.sin());
            let tilted = Rotation3::from_axis_angle(&towards, tilt.to_radians());
            for spin in -spins..=spins {
                let spin = (f64::from(spin) * SPIN_STEP_DEG).to_radians();
                out.push(tilted * Rotation3::from_axis_angle(axis, spin));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Volume;
    use crate::register::deform::ProbeKind;
    use nalgebra::Matrix3;

    /// A flat box (1.4 x 0.6 x 3 mm, a stand-in for the stapes: not symmetric under a spin)
    /// hanging from the head at the origin along +z, its faces cut into 0.1 mm squares, each
    /// two triangles counter-clockwise from outside.
    fn plank() -> (Vec<Point3<f64>>, Vec<ProbeTriangle>) {
        let (lo, hi) = (
            Vector3::<f64>::new(-0.7, -0.3, 0.3),
            Vector3::<f64>::new(0.7, 0.3, 3.3),
        );
        let mut nodes = Vec::new();
        let mut triangles = Vec::new();
        for axis in 0..3 {
            for top in [false, true] {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let (nu, nv) = (
                    ((hi[u] - lo[u]) / 0.1).round() as usize,
                    ((hi[v] - lo[v]) / 0.1).round() as usize,
                );
                let base = nodes.len() as u32;
                for j in 0..=nv {
                    for i in 0..=nu {
                        let mut p = lo;
                        p[axis] = if top { hi[axis] } else { lo[axis] };
                        p[u] = lo[u] + (hi[u] - lo[u]) * i as f64 / nu as f64;
                        p[v] = lo[v] + (hi[v] - lo[v]) * j as f64 / nv as f64;
                        nodes.push(Point3::from(p));
                    }
                }
                let at = |i: usize, j: usize| base + (i + j * (nu + 1)) as u32;
                for j in 0..nv {
                    for i in 0..nu {
                        // u x v points along +axis: counter-clockwise seen from +axis
                        let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                        let quad = if top {
                            [[a, b, c], [a, c, d]]
                        } else {
                            [[a, c, b], [a, d, c]]
                        };
                        triangles.extend(quad.map(|nodes| ProbeTriangle {
                            nodes,
                            kind: ProbeKind::Bone,
                        }));
                    }
                }
            }
        }
        (nodes, triangles)
    }

    /// An image of the plank turned by `turn` about the origin, then moved by `shift`: 1500 HU
    /// inside, -1000 HU outside, at 0.1 mm voxels.
    fn image_of_moved_plank(turn: &Rotation3<f64>, shift: &Vector3<f64>) -> Volume {
        let spacing = 0.1;
        let n = 90;
        let origin = Vector3::new(-4.5, -4.5, -4.5);
        let back = turn.inverse();
        let mut data = Vec::with_capacity(n * n * n);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let p = origin + Vector3::new(i as f64, j as f64, k as f64) * spacing;
                    let q = back * (p - shift);
                    let inside = q.x.abs() <= 0.7 && q.y.abs() <= 0.3 && (0.3..=3.3).contains(&q.z);
                    data.push(if inside { 1500.0 } else { -1000.0 });
                }
            }
        }
        Volume {
            dims: [n; 3],
            spacing: [spacing; 3],
            origin,
            direction: Matrix3::identity(),
            data,
        }
    }

    #[test]
    fn finds_a_known_turn_of_the_stapes_about_its_head() {
        let (nodes, triangles) = plank();
        // 20° of tilt towards +x and a 10° spin: both on the search grid
        let axis = Unit::new_normalize(Vector3::z());
        let truth =
            Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::y()), 20f64.to_radians())
                * Rotation3::from_axis_angle(&axis, 10f64.to_radians());
        let volume = image_of_moved_plank(&truth, &Vector3::zeros());
        let Some(sampler) = Sampler::new(&volume) else {
            panic!("the test image has a degenerate geometry");
        };
        let (found, _, record) = search(&triangles, &nodes, &Point3::origin(), &sampler, 60.0);
        let error = (found * truth.inverse()).angle().to_degrees();
        assert!(error < 1.0, "found a turn {error:.1}° from the truth");
        assert!((record.turn_deg - truth.angle().to_degrees()).abs() < 1.0);
        assert!(record.contrast_after_hu > 2.0 * record.contrast_before_hu.max(1.0));
        assert_eq!(record.candidates, 2601);
    }

    #[test]
    fn keeps_a_stapes_that_already_lies_on_its_edges() {
        let (nodes, triangles) = plank();
        let volume = image_of_moved_plank(&Rotation3::identity(), &Vector3::zeros());
        let Some(sampler) = Sampler::new(&volume) else {
            panic!("the test image has a degenerate geometry");
        };
        let (found, _, record) = search(&triangles, &nodes, &Point3::origin(), &sampler, 60.0);
        assert!(found.angle() < 1e-9, "turned by {:.1}°", record.turn_deg);
        assert_eq!(record.contrast_after_hu, record.contrast_before_hu);
        assert_eq!(record.head_shift_mm, 0.0);
    }

    #[test]
    fn finds_a_turn_about_a_head_the_placement_left_off() {
        let (nodes, triangles) = plank();
        // the image's stapes 15° tilted about a head 0.35 mm off the placed one (along its
        // axis and its width): no turn about the placed head covers it
        let truth =
            Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::x()), 15f64.to_radians());
        let shift = Vector3::new(0.25, 0.0, 0.25);
        let volume = image_of_moved_plank(&truth, &shift);
        let Some(sampler) = Sampler::new(&volume) else {
            panic!("the test image has a degenerate geometry");
        };
        let (found, found_shift, record) =
            search(&triangles, &nodes, &Point3::origin(), &sampler, 60.0);
        // where the plank's nodes end against where the image has them
        let mean_error = |turn: &Rotation3<f64>, moved: &Vector3<f64>| {
            nodes
                .iter()
                .map(|p| ((turn * p + moved) - (truth * p + shift)).norm())
                .sum::<f64>()
                / nodes.len() as f64
        };
        let error = mean_error(&found, &found_shift);
        // the best any turn of the grid about the placed head could do
        let axis = Unit::new_normalize(Vector3::z());
        let best_turn = turns(&axis, 60.0)
            .iter()
            .map(|t| mean_error(t, &Vector3::zeros()))
            .fold(f64::INFINITY, f64::min);
        assert!(
            error < 0.5 * best_turn,
            "the plank's nodes end {error:.3} mm off on average; the best turn alone {best_turn:.3} mm"
        );
        assert!(found_shift.norm() > 0.0);
        assert!((record.head_shift_mm - found_shift.norm()).abs() < 1e-12);
    }
}
