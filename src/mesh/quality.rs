//! Tetrahedron quality: dihedral angles, the radius–edge ratio (circumradius over shortest
//! edge; √6/4 ≈ 0.612 for the regular tet), per tet and summarised per region, and the shape
//! quality (volume over the regular tetrahedron's of the same RMS edge) that the registration's
//! surface level and `verify` bound.
//!
//! Dihedral angle at an edge = π − angle between the outward normals of the two faces that
//! meet there (Shewchuk, "What is a good linear finite element?", 2002). Circumcentre of
//! `a + x` with `u, v, w` the edges from `a`:
//! `x = (|u|² v×w + |v|² w×u + |w|² u×v) / (2 u·(v×w))`.

use nalgebra::{Point3, Vector3};

use super::TetMesh;
use super::tet::{TET_FACES, signed_volume};

/// Least shape quality ([`shape_quality`]; 1 regular, 0 flat) a registered tetrahedron may
/// keep. A near-flat element is stiff in some directions and nearly free in others, which
/// ill-conditions a simulator's stiffness of the whole chain: `verify` refuses a package
/// below it, and the registration never leaves an element there.
pub const MIN_SHAPE_QUALITY: f64 = 0.02;
/// Least volume a registered tetrahedron may keep over its counterpart's in the reference
/// (the atlas, scaled by the landmark fit): `verify`'s and the registration's floor too.
pub const MIN_VOLUME_RATIO: f64 = 0.05;

/// The registration's own floor on shape quality, a quarter above [`MIN_SHAPE_QUALITY`]: its
/// levels keep every element above it (or, one that starts lower, near what it had), so that
/// a package written with rounded coordinates still clears `verify`'s floor.
pub const REGISTRATION_SHAPE_QUALITY: f64 = 1.25 * MIN_SHAPE_QUALITY;

/// The registration's own floor on volume over the reference's, a quarter above
/// [`MIN_VOLUME_RATIO`], for the same reason.
pub const REGISTRATION_VOLUME_RATIO: f64 = 1.25 * MIN_VOLUME_RATIO;

/// The fraction of its shape quality that an element below a level's own floor may lose in
/// that level.
const SLIVER_KEEP: f64 = 0.9;

/// The least each tetrahedron may keep in one level of the registration, set at the level's
/// start: no element goes below the registration's floors
/// ([`REGISTRATION_SHAPE_QUALITY`], [`REGISTRATION_VOLUME_RATIO`] of its volume in the
/// reference) unless it starts there, and then no lower.
#[derive(Debug, Clone)]
pub struct ElementFloors {
    /// The tetrahedra, each ordered to a positive volume at the level's start.
    tets: Vec<[u32; 4]>,
    quality: Vec<f64>,
    volume: Vec<f64>,
}

impl ElementFloors {
    /// The floors of `tets` for a level starting at `start`, volumes compared with those at
    /// `reference` (the placed atlas). `least_quality` is the level's own floor on shape
    /// quality (at least the registration's): an element below it at `start` may lose a
    /// tenth of its quality, no more.
    pub fn new(
        tets: &[[u32; 4]],
        reference: &[Point3<f64>],
        start: &[Point3<f64>],
        least_quality: f64,
    ) -> ElementFloors {
        let tets: Vec<[u32; 4]> = tets
            .iter()
            .map(|&[a, b, c, d]| {
                if volume(start, &[a, b, c, d]) < 0.0 {
                    [b, a, c, d]
                } else {
                    [a, b, c, d]
                }
            })
            .collect();
        let quality = tets
            .iter()
            .map(|t| {
                let q = shape_quality(&corners(start, t));
                least_quality
                    .min(SLIVER_KEEP * q)
                    .max(REGISTRATION_SHAPE_QUALITY.min(q))
            })
            .collect();
        let volume = tets
            .iter()
            .map(|t| (REGISTRATION_VOLUME_RATIO * volume(reference, t).abs()).min(volume(start, t)))
            .collect();
        ElementFloors {
            tets,
            quality,
            volume,
        }
    }

    /// The tetrahedra that `x` leaves below their floors (inverted ones too), each with its
    /// shape quality there, in mesh order.
    pub fn failing(&self, x: &[Point3<f64>]) -> Vec<(usize, f64)> {
        self.tets
            .iter()
            .enumerate()
            .filter_map(|(e, t)| {
                let q = shape_quality(&corners(x, t));
                (q < self.quality[e] || volume(x, t) < self.volume[e]).then_some((e, q))
            })
            .collect()
    }
}

/// The corners of tetrahedron `t` at `p`.
fn corners(p: &[Point3<f64>], t: &[u32; 4]) -> [Point3<f64>; 4] {
    t.map(|k| p[k as usize])
}

/// The signed volume of tetrahedron `t` at `p`.
fn volume(p: &[Point3<f64>], t: &[u32; 4]) -> f64 {
    let [a, b, c, d] = corners(p, t);
    signed_volume(&a, &b, &c, &d)
}

/// The tetrahedron of a registered mesh that is furthest below [`MIN_SHAPE_QUALITY`] or
/// [`MIN_VOLUME_RATIO`], with both of its figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatElement {
    /// Its index in mesh order (0-based).
    pub tetrahedron: usize,
    pub shape_quality: f64,
    pub volume_ratio: f64,
}

/// The worst tetrahedron of `tets` at `x` that breaks either floor, its volume compared with
/// that at `reference` (the same nodes, similar to the atlas); `None` if none breaks them.
pub fn flattest_below_floors(
    tets: &[[u32; 4]],
    reference: &[Point3<f64>],
    x: &[Point3<f64>],
) -> Option<FlatElement> {
    tets.iter()
        .enumerate()
        .map(|(t, tet)| FlatElement {
            tetrahedron: t,
            shape_quality: shape_quality(&corners(x, tet)),
            volume_ratio: volume(x, tet) / volume(reference, tet).max(f64::MIN_POSITIVE),
        })
        .filter(|e| e.shape_quality < MIN_SHAPE_QUALITY || e.volume_ratio < MIN_VOLUME_RATIO)
        .min_by(|e, f| {
            let below = |e: &FlatElement| {
                (e.shape_quality / MIN_SHAPE_QUALITY).min(e.volume_ratio / MIN_VOLUME_RATIO)
            };
            below(e).total_cmp(&below(f))
        })
}

/// Quality summary of a set of tets. Angles in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct QualityStats {
    pub tets: usize,
    /// Smallest dihedral angle over all tets.
    pub min_dihedral_deg: f64,
    /// Median over tets of each tet's smallest dihedral angle.
    pub median_min_dihedral_deg: f64,
    /// Largest dihedral angle over all tets.
    pub max_dihedral_deg: f64,
    /// Median radius–edge ratio.
    pub median_radius_edge: f64,
    /// Largest radius–edge ratio (infinite for a degenerate tet).
    pub max_radius_edge: f64,
}

/// Smallest and largest dihedral angle (radians) of the tet `p` (any orientation).
pub fn dihedral_range(p: &[Point3<f64>; 4]) -> (f64, f64) {
    let sign = if (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let normals: [Vector3<f64>; 4] = TET_FACES.map(|[a, b, c]| {
        let n = (p[b] - p[a]).cross(&(p[c] - p[a])) * sign;
        let len = n.norm();
        if len > 0.0 { n / len } else { n }
    });
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for i in 0..4 {
        for j in i + 1..4 {
            let cos = normals[i].dot(&normals[j]).clamp(-1.0, 1.0);
            let angle = std::f64::consts::PI - cos.acos();
            lo = lo.min(angle);
            hi = hi.max(angle);
        }
    }
    (lo, hi)
}

/// Circumradius over shortest edge of the tet `p` (infinite when degenerate).
pub fn radius_edge_ratio(p: &[Point3<f64>; 4]) -> f64 {
    let (u, v, w) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let denom = 2.0 * u.dot(&v.cross(&w));
    if denom == 0.0 {
        return f64::INFINITY;
    }
    let x = (v.cross(&w) * u.norm_squared()
        + w.cross(&u) * v.norm_squared()
        + u.cross(&v) * w.norm_squared())
        / denom;
    let mut shortest = f64::INFINITY;
    for i in 0..4 {
        for j in i + 1..4 {
            shortest = shortest.min((p[i] - p[j]).norm());
        }
    }
    x.norm() / shortest
}

/// The tetrahedron's volume over that of the regular one with its RMS edge length: 1 for a
/// regular tetrahedron, 0 when flat, negative when inverted (the mean-ratio family of
/// measures; scale invariant, and like gmsh's gamma it vanishes with the volume).
pub fn shape_quality(p: &[Point3<f64>; 4]) -> f64 {
    let [a, b, c, d] = p;
    let squares = [(a, b), (a, c), (a, d), (b, c), (b, d), (c, d)]
        .iter()
        .map(|(u, v)| (*u - *v).norm_squared())
        .sum::<f64>()
        / 6.0;
    let regular = squares.powf(1.5) / (6.0 * std::f64::consts::SQRT_2);
    if regular > 0.0 {
        signed_volume(a, b, c, d) / regular
    } else {
        0.0
    }
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_unstable_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Quality summary of the tets for which `keep(t)` holds.
pub fn quality_stats(mesh: &TetMesh, keep: impl Fn(usize) -> bool) -> QualityStats {
    let mut min_dihedrals = Vec::new();
    let mut ratios = Vec::new();
    let mut stats = QualityStats {
        min_dihedral_deg: f64::INFINITY,
        ..QualityStats::default()
    };
    for t in (0..mesh.tets.len()).filter(|&t| keep(t)) {
        let p = mesh.corners(t);
        let (lo, hi) = dihedral_range(&p);
        stats.min_dihedral_deg = stats.min_dihedral_deg.min(lo.to_degrees());
        stats.max_dihedral_deg = stats.max_dihedral_deg.max(hi.to_degrees());
        min_dihedrals.push(lo.to_degrees());
        ratios.push(radius_edge_ratio(&p));
    }
    stats.tets = ratios.len();
    stats.median_min_dihedral_deg = median(&mut min_dihedrals);
    stats.median_radius_edge = median(&mut ratios);
    stats.max_radius_edge = ratios.last().copied().unwrap_or(f64::NAN);
    if stats.tets == 0 {
        stats.min_dihedral_deg = f64::NAN;
    }
    stats
}

/// Quality of each region present in `mesh`, in ascending region order.
pub fn quality_by_region(mesh: &TetMesh) -> Vec<(u16, QualityStats)> {
    mesh.region_ids()
        .into_iter()
        .map(|r| (r, quality_stats(mesh, |t| mesh.regions[t] == r)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular() -> [Point3<f64>; 4] {
        [
            Point3::new(1., 1., 1.),
            Point3::new(1., -1., -1.),
            Point3::new(-1., 1., -1.),
            Point3::new(-1., -1., 1.),
        ]
    }

    #[test]
    fn regular_tet_has_the_textbook_values() {
        let (lo, hi) = dihedral_range(&regular());
        let expected = (1.0f64 / 3.0).acos();
        assert!((lo - expected).abs() < 1e-12 && (hi - expected).abs() < 1e-12);
        assert!((radius_edge_ratio(&regular()) - 6f64.sqrt() / 4.0).abs() < 1e-12);
        // negatively oriented as listed
        assert!((shape_quality(&regular()) + 1.0).abs() < 1e-12);
    }

    #[test]
    fn corner_tet_has_right_angles() {
        let p = [
            Point3::new(0., 0., 0.),
            Point3::new(1., 0., 0.),
            Point3::new(0., 1., 0.),
            Point3::new(0., 0., 1.),
        ];
        let (lo, hi) = dihedral_range(&p);
        // Three 90° edges at the corner; the others are acos(1/√3) ≈ 54.7°.
        assert!((hi.to_degrees() - 90.0).abs() < 1e-9);
        assert!((lo - (1.0f64 / 3f64.sqrt()).acos()).abs() < 1e-12);
        // Circumcentre (½,½,½): R = √3/2, shortest edge 1.
        assert!((radius_edge_ratio(&p) - 3f64.sqrt() / 2.0).abs() < 1e-12);
    }

    #[test]
    fn flat_tet_is_degenerate() {
        let p = [
            Point3::new(0., 0., 0.),
            Point3::new(1., 0., 0.),
            Point3::new(0., 1., 0.),
            Point3::new(0.25, 0.25, 0.),
        ];
        assert!(radius_edge_ratio(&p).is_infinite());
        assert_eq!(shape_quality(&p), 0.0);
        assert!(dihedral_range(&p).0 < 1e-9);
    }
}
