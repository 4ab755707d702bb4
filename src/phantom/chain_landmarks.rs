//! Landmarks and side proposed for a real chain that comes without them.
//!
//! Why: a chain folder for `phantom --anatomy` needs the chain's three landmarks and its side,
//! and someone with a new chain (a specimen library's surfaces, a segmentation) may have
//! neither. Picking them by hand is slow and differs between people; the project's own picks
//! (docs/anatomy.md, "Real chains") carry the atlas's landmarks onto the chain by a fit of the
//! atlas's ossicles, which is what is done here.
//!
//! Method: the atlas's ossicle surfaces (a right ear, mirrored in x = 0 for a left one) are
//! fitted onto the chain's surfaces by trimmed point-to-surface ICP with scale (Umeyama),
//! from 24 starting rotations per side (the chain's principal axes matched to the atlas's in
//! every proper way, so no start depends on which axis is longer), the centroids and the RMS
//! radii matched. Every start is fitted with a fifth of the points first; the best few of each
//! side (by the mean symmetric distance, which a fit shrunk into part of the chain cannot
//! make small) are fitted again with them all. The fit of the two sides that leaves the least mean symmetric distance
//! between the surfaces wins, and gives the side; the atlas's landmarks are carried by it. Two
//! are then put on the chain's own bone, as docs/anatomy.md's picks were: the umbo onto the
//! manubrium's tip (of the chain's vertices within 1 mm of the carried umbo, the farthest from
//! the carried IMJ), and the ISJ at the centre of the chain's bone within the atlas's ISJ
//! interface carried onto it (a joint's centre lies inside a chain that fuses it, where the
//! carried centre of an interface may fall on its surface).

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use crate::atlas::{Anatomy, Side};
use crate::ear::Landmarks;
use crate::mesh::TriMesh;
use crate::mesh::spatial::{Bvh, SignedSurface};
use crate::register::icp::{IcpOptions, Trim, trimmed_icp};
use crate::register::rigid::SimilarityTransform;

/// The ICP of each start: with scale, the closest 90 % of the pairs kept at each iteration.
const ICP: IcpOptions = IcpOptions {
    iterations: 60,
    trim: Trim::Share(0.9),
    with_scale: true,
    check_stride: 53,
    tolerance_mm: 1e-4,
};
/// The best few starts of each side are fitted again with all the samples.
const FINALISTS: usize = 4;
/// The umbo is moved onto the chain vertex farthest from the IMJ within this reach \[mm\].
const UMBO_REACH_MM: f64 = 1.0;
/// The carried ISJ interface is sampled on a grid of this step \[mm\].
const DISC_STEP_MM: f64 = 0.01;
/// At most this many surface points of each surface take part in the fit, and in the first
/// fit of every start.
const MAX_SAMPLES: usize = 3000;
const MAX_SCREEN_SAMPLES: usize = 600;

/// Surface points of the atlas and of the chain.
type Samples = (Vec<Point3<f64>>, Vec<Point3<f64>>);

/// What the fit proposes.
#[derive(Debug, Clone, Copy)]
pub struct ProposedLandmarks {
    pub landmarks: Landmarks,
    pub side: Side,
    /// Mean symmetric surface distance between the fitted atlas ossicles and the chain \[mm\].
    pub mean_distance_mm: f64,
    /// The same for the other side's best fit \[mm\].
    pub other_side_mm: f64,
    /// The fit's scale (the chain's size over the atlas's).
    pub scale: f64,
    /// How far the umbo moved onto the chain's manubrium tip \[mm\].
    pub umbo_moved_mm: f64,
    /// How far the ISJ moved from the carried interface's centre to its bone's \[mm\].
    pub isj_moved_mm: f64,
}

/// What `truth.json` records of landmarks proposed for a chain folder without a landmark file
/// ([`propose`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LandmarksProposed {
    /// Mean symmetric distance of the fitted atlas ossicles to the chain, on the side chosen
    /// and on the other \[mm\].
    pub mean_distance_mm: f64,
    pub other_side_mm: f64,
    /// The fit's scale (the chain's size over the atlas's).
    pub scale: f64,
    /// How far the umbo moved from the carried one onto the manubrium's tip \[mm\].
    pub umbo_moved_mm: f64,
    /// How far the ISJ moved from the carried interface's centre to its bone's \[mm\].
    pub isj_moved_mm: f64,
}

impl From<&ProposedLandmarks> for LandmarksProposed {
    fn from(p: &ProposedLandmarks) -> Self {
        LandmarksProposed {
            mean_distance_mm: p.mean_distance_mm,
            other_side_mm: p.other_side_mm,
            scale: p.scale,
            umbo_moved_mm: p.umbo_moved_mm,
            isj_moved_mm: p.isj_moved_mm,
        }
    }
}

/// Proposes landmarks and side for `chain` (its surfaces, in its own frame) from the atlas
/// `anatomy` (a right ear) and its ossicle surfaces `atlas`; `None` if a surface is empty.
pub fn propose(
    chain: &[&TriMesh],
    atlas: &[TriMesh; 3],
    anatomy: &Anatomy,
) -> Option<ProposedLandmarks> {
    let atlas_landmarks = anatomy.landmarks();
    let chain_mesh = TriMesh::concatenated(chain);
    let chain_bvh = Bvh::new(&chain_mesh, "chain").ok()?;
    let chain_fine = thinned(&chain_mesh.vertices, MAX_SAMPLES);
    let chain_coarse = thinned(&chain_mesh.vertices, MAX_SCREEN_SAMPLES);
    let right = TriMesh::concatenated(&atlas.iter().collect::<Vec<_>>());
    let fits: Vec<(Side, SimilarityTransform, f64)> = [Side::Right, Side::Left]
        .par_iter()
        .filter_map(|&side| {
            let atlas_mesh = TriMesh {
                vertices: right.vertices.iter().map(|p| on_side(side, p)).collect(),
                triangles: right.triangles.clone(),
            };
            let fine = (
                thinned(&atlas_mesh.vertices, MAX_SAMPLES),
                chain_fine.clone(),
            );
            let coarse = (
                thinned(&atlas_mesh.vertices, MAX_SCREEN_SAMPLES),
                chain_coarse.clone(),
            );
            let scored = |t: SimilarityTransform, (atlas_points, chain_points): &Samples| {
                symmetric_distance(&atlas_mesh, t, atlas_points, chain_points, &chain_bvh)
                    .map(|d| (t, d))
            };
            let mut screened: Vec<(SimilarityTransform, f64)> = starts(&fine.0, &fine.1)
                .into_par_iter()
                .filter_map(|start| {
                    scored(
                        trimmed_icp(&coarse.0, &chain_bvh, start, &ICP).transform,
                        &coarse,
                    )
                })
                .collect();
            screened.sort_by(|a, b| a.1.total_cmp(&b.1));
            screened.truncate(FINALISTS);
            let best = screened
                .into_par_iter()
                .filter_map(|(t, _)| {
                    scored(trimmed_icp(&fine.0, &chain_bvh, t, &ICP).transform, &fine)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            Some((side, best.0, best.1))
        })
        .collect();
    let (side, fit, distance) = *fits.iter().min_by(|a, b| a.2.total_cmp(&b.2))?;
    let other_side_mm = fits
        .iter()
        .find(|f| f.0 != side)
        .map_or(f64::INFINITY, |f| f.2);
    let carried = Landmarks::from_points(
        atlas_landmarks
            .points()
            .map(|p| fit.apply(&on_side(side, &p))),
    );
    let joint = anatomy.incudostapedial_joint();
    let carry_vector = |v: &Vector3<f64>| {
        fit.apply_vector(&on_side(side, &Point3::from(*v)).coords)
            .normalize()
    };
    let radius = joint.semi_axes[0].min(joint.semi_axes[1]) * fit.scale;
    let inside = SignedSurface::new(&chain_mesh, "chain").ok()?;
    let isj = bone_centre(
        &carried.incudostapedial,
        &carry_vector(&joint.frame.e1),
        &carry_vector(&joint.frame.e2),
        radius,
        &inside,
    )
    .unwrap_or(carried.incudostapedial);
    let tip = chain_mesh
        .vertices
        .iter()
        .filter(|v| (*v - carried.umbo).norm() <= UMBO_REACH_MM)
        .max_by(|a, b| {
            let (da, db) = (
                (*a - carried.incudomalleolar).norm(),
                (*b - carried.incudomalleolar).norm(),
            );
            da.total_cmp(&db)
        })
        .copied()
        .unwrap_or(carried.umbo);
    Some(ProposedLandmarks {
        landmarks: Landmarks {
            umbo: tip,
            incudostapedial: isj,
            ..carried
        },
        side,
        mean_distance_mm: distance,
        other_side_mm,
        scale: fit.scale,
        umbo_moved_mm: (tip - carried.umbo).norm(),
        isj_moved_mm: (isj - carried.incudostapedial).norm(),
    })
}

/// The centroid of the points of the disc (`centre`, in-plane unit axes `u` and `v`,
/// `radius`) that lie inside `bone`, on a [`DISC_STEP_MM`] grid; `None` if none does.
fn bone_centre(
    centre: &Point3<f64>,
    u: &Vector3<f64>,
    v: &Vector3<f64>,
    radius: f64,
    bone: &SignedSurface,
) -> Option<Point3<f64>> {
    let n = (radius / DISC_STEP_MM).floor() as i64;
    let (sum, count) = (-n..=n)
        .flat_map(|i| (-n..=n).map(move |j| (i as f64 * DISC_STEP_MM, j as f64 * DISC_STEP_MM)))
        .filter(|(x, y)| x * x + y * y <= radius * radius)
        .map(|(x, y)| centre + u * x + v * y)
        .filter(|p| bone.signed_distance(p) < 0.0)
        .fold((Vector3::zeros(), 0usize), |(s, k), p| {
            (s + p.coords, k + 1)
        });
    (count > 0).then(|| Point3::from(sum / count as f64))
}

/// `p` of the right-ear atlas on the ear `side` (mirrored in x = 0 for the left).
fn on_side(side: Side, p: &Point3<f64>) -> Point3<f64> {
    match side {
        Side::Right => *p,
        Side::Left => Point3::new(-p.x, p.y, p.z),
    }
}

/// At most `most` of `points`, evenly taken.
fn thinned(points: &[Point3<f64>], most: usize) -> Vec<Point3<f64>> {
    let step = points.len().div_ceil(most).max(1);
    points.iter().step_by(step).copied().collect()
}

fn centroid(points: &[Point3<f64>]) -> Point3<f64> {
    let sum = points.iter().fold(Vector3::zeros(), |s, p| s + p.coords);
    Point3::from(sum / points.len().max(1) as f64)
}

/// The principal axes of `points` (columns, a proper rotation) and their RMS radius.
fn principal_frame(points: &[Point3<f64>]) -> (Matrix3<f64>, f64) {
    let c = centroid(points);
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = p - c;
        cov += d * d.transpose();
    }
    cov /= points.len().max(1) as f64;
    let eig = SymmetricEigen::new(cov);
    let mut axes = eig.eigenvectors;
    if axes.determinant() < 0.0 {
        axes.set_column(2, &(-axes.column(2)));
    }
    (axes, cov.trace().sqrt())
}

/// The 24 proper rotations that map the coordinate axes onto themselves (signed).
fn axis_rotations() -> Vec<Matrix3<f64>> {
    let mut out = Vec::with_capacity(24);
    for perm in [
        [0, 1, 2],
        [1, 2, 0],
        [2, 0, 1],
        [0, 2, 1],
        [2, 1, 0],
        [1, 0, 2],
    ] {
        for signs in [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, -1.0],
            [-1.0, 1.0, -1.0],
            [-1.0, -1.0, 1.0],
        ] {
            let m = Matrix3::from_fn(|r, c| if perm[c] == r { signs[c] } else { 0.0 });
            let m = if m.determinant() < 0.0 { -m } else { m };
            out.push(m);
        }
    }
    out
}

/// The starting fits: the atlas's principal axes onto the chain's in each of the 24 proper
/// ways, centroids and RMS radii matched.
fn starts(atlas: &[Point3<f64>], chain: &[Point3<f64>]) -> Vec<SimilarityTransform> {
    let (fa, ra) = principal_frame(atlas);
    let (fc, rc) = principal_frame(chain);
    let (ca, cc) = (centroid(atlas), centroid(chain));
    let scale = if ra > 0.0 { rc / ra } else { 1.0 };
    axis_rotations()
        .into_iter()
        .map(|q| {
            let rotation = fc * q * fa.transpose();
            let translation = cc.coords - rotation * ca.coords * scale;
            SimilarityTransform::new(rotation, translation, scale)
        })
        .collect()
}

/// The mean of the mean distances from the atlas's points carried by `t` to the chain and
/// from the chain's points to the carried atlas surface.
fn symmetric_distance(
    atlas: &TriMesh,
    t: SimilarityTransform,
    atlas_points: &[Point3<f64>],
    chain_points: &[Point3<f64>],
    chain: &Bvh,
) -> Option<f64> {
    let moved = TriMesh {
        vertices: atlas.vertices.iter().map(|p| t.apply(p)).collect(),
        triangles: atlas.triangles.clone(),
    };
    let bvh = Bvh::new(&moved, "atlas").ok()?;
    let there = mean_distance(atlas_points, |p| t.apply(p), chain);
    let back = mean_distance(chain_points, |p| *p, &bvh);
    Some(0.5 * (there + back))
}

/// Mean distance from `points` (mapped by `map`) to `surface`.
fn mean_distance(
    points: &[Point3<f64>],
    map: impl Fn(&Point3<f64>) -> Point3<f64>,
    surface: &Bvh,
) -> f64 {
    let sum: f64 = points
        .iter()
        .map(|p| surface.closest(&map(p)).distance)
        .sum();
    sum / points.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::icosphere;

    #[test]
    fn the_starting_rotations_are_the_24_proper_axis_rotations() {
        let all = axis_rotations();
        assert_eq!(all.len(), 24);
        for (i, m) in all.iter().enumerate() {
            assert!((m.determinant() - 1.0).abs() < 1e-12);
            assert!((m * m.transpose() - Matrix3::identity()).norm() < 1e-12);
            assert!(all[..i].iter().all(|o| (o - m).norm() > 0.5), "{i} repeats");
        }
    }

    /// The bone within a unit disc at the origin of a unit ball centred at x = 1 is a lens
    /// symmetric about x = 0.5: its centroid is (0.5, 0, 0).
    #[test]
    fn the_isj_moves_to_the_centroid_of_the_bone_within_its_interface() {
        let ball = icosphere(Point3::new(1.0, 0.0, 0.0), 1.0, 4);
        let bone = SignedSurface::new(&ball, "ball").unwrap();
        let centre =
            bone_centre(&Point3::origin(), &Vector3::x(), &Vector3::y(), 1.0, &bone).unwrap();
        assert!(
            (centre - Point3::new(0.5, 0.0, 0.0)).norm() < 0.01,
            "{centre}"
        );
        // a disc that misses the bone leaves no centre
        let far = bone_centre(
            &Point3::new(5.0, 0.0, 0.0),
            &Vector3::x(),
            &Vector3::y(),
            0.5,
            &bone,
        );
        assert!(far.is_none());
    }
}
