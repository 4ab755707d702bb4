//! Exact closest point on a triangle to a query point, with the feature (face interior, edge
//! or vertex) it lies on.
//!
//! Region method of Ericson, "Real-Time Collision Detection" (2005), §5.1.5
//! `ClosestPtPointTriangle`: the Voronoi regions of the three vertices and three edges are
//! tested with dot products; what remains is the face interior, solved in barycentric
//! coordinates. The feature is what the sign (angle-weighted pseudonormals) needs.

use nalgebra::{Point3, Vector3};

/// Where on a triangle the closest point lies. Local indices: vertex `i` is corner `i`;
/// edge 0 joins corners 0–1, edge 1 joins 1–2, edge 2 joins 2–0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Feature {
    Face,
    Edge(u8),
    Vertex(u8),
}

/// The closest point of triangle (`a`, `b`, `c`) to `p`, and its feature.
///
/// Degenerate (zero-area) triangles are handled as the union of their three edges.
#[inline]
pub fn closest_point_on_triangle(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> (Point3<f64>, Feature) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let denom = va + vb + vc;
    if denom > 0.0 && denom.is_finite() {
        let v = vb / denom;
        let w = vc / denom;
        (a + ab * v + ac * w, Feature::Face)
    } else {
        closest_on_edges(p, a, b, c)
    }
}

/// Fallback for degenerate triangles: the nearest of the three edge segments.
#[cold]
fn closest_on_edges(
    p: &Point3<f64>,
    a: &Point3<f64>,
    b: &Point3<f64>,
    c: &Point3<f64>,
) -> (Point3<f64>, Feature) {
    let corners = [a, b, c];
    let mut best = (*a, Feature::Vertex(0), f64::INFINITY);
    for e in 0..3u8 {
        let (s, t) = (corners[e as usize], corners[(e as usize + 1) % 3]);
        let st: Vector3<f64> = t - s;
        let len2 = st.norm_squared();
        let u = if len2 > 0.0 {
            ((p - s).dot(&st) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = s + st * u;
        let feature = if u <= 0.0 {
            Feature::Vertex(e)
        } else if u >= 1.0 {
            Feature::Vertex((e + 1) % 3)
        } else {
            Feature::Edge(e)
        };
        let d2 = (p - q).norm_squared();
        if d2 < best.2 {
            best = (q, feature, d2);
        }
    }
    (best.0, best.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers in [-1, 1) (SplitMix64).
    fn rng(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *seed;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn point(seed: &mut u64, scale: f64) -> Point3<f64> {
        Point3::new(rng(seed) * scale, rng(seed) * scale, rng(seed) * scale)
    }

    /// q is the closest point of a convex triangle iff (p - q)·(v - q) ≤ 0 for every corner v;
    /// the feature must match q's barycentric position.
    #[test]
    fn optimality_conditions_hold_on_random_triangles() {
        let mut seed = 7;
        let mut seen = std::collections::HashSet::new();
        for _ in 0..20_000 {
            let (a, b, c) = (
                point(&mut seed, 1.0),
                point(&mut seed, 1.0),
                point(&mut seed, 1.0),
            );
            let p = point(&mut seed, 2.0);
            let (q, feature) = closest_point_on_triangle(&p, &a, &b, &c);
            seen.insert(feature);
            let scale = 1.0 + (p - q).norm();
            for v in [a, b, c] {
                assert!((p - q).dot(&(v - q)) <= 1e-12 * scale, "{feature:?}");
            }
            // Barycentric coordinates of q (q lies in the triangle's plane).
            let n = (b - a).cross(&(c - a));
            let bary = |x: &Point3<f64>, y: &Point3<f64>| {
                (x - q).cross(&(y - q)).dot(&n) / n.norm_squared()
            };
            let (l0, l1, l2) = (bary(&b, &c), bary(&c, &a), bary(&a, &b));
            assert!((l0 + l1 + l2 - 1.0).abs() < 1e-9);
            let tol = 1e-9;
            match feature {
                Feature::Face => assert!(l0 > -tol && l1 > -tol && l2 > -tol),
                Feature::Edge(0) => assert!(l2.abs() < tol),
                Feature::Edge(1) => assert!(l0.abs() < tol),
                Feature::Edge(2) => assert!(l1.abs() < tol),
                Feature::Vertex(i) => assert!((q - [a, b, c][i as usize]).norm() < tol),
                Feature::Edge(_) => unreachable!(),
            }
        }
        assert_eq!(seen.len(), 7, "all seven regions exercised: {seen:?}");
    }

    #[test]
    fn degenerate_triangles_fall_back_to_segments() {
        let a = Point3::new(0.0, 0.0, 0.0);
        let b = Point3::new(1.0, 0.0, 0.0);
        let c = Point3::new(2.0, 0.0, 0.0);
        let p = Point3::new(1.5, 1.0, 0.0);
        let (q, _) = closest_point_on_triangle(&p, &a, &b, &c);
        assert!((q - Point3::new(1.5, 0.0, 0.0)).norm() < 1e-15);
        let (q, f) = closest_point_on_triangle(&p, &a, &a, &a);
        assert_eq!((q, f), (a, Feature::Vertex(0)));
    }

    #[test]
    fn face_interior_projects_orthogonally() {
        let a = Point3::new(0.0, 0.0, 0.0);
        let b = Point3::new(1.0, 0.0, 0.0);
        let c = Point3::new(0.0, 1.0, 0.0);
        let (q, f) = closest_point_on_triangle(&Point3::new(0.25, 0.25, -3.0), &a, &b, &c);
        assert_eq!(f, Feature::Face);
        assert_eq!(q, Point3::new(0.25, 0.25, 0.0));
    }
}
