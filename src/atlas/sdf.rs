//! Signed-distance primitives the parametric anatomy is built from: tapered tubes along
//! polylines (chains of round cones), ellipsoids and elliptic discs, and the polynomial smooth
//! union that blends them.
//!
//! Formulas: round cone and polynomial smooth minimum after Quílez, "Distance functions"
//! (iquilezles.org/articles/distfunctions, exact round cone; `smin` with quadratic kernel);
//! ellipsoid and ellipse by Quílez's first-order bound `k0 (k0 - 1) / k1`, accurate near the
//! surface and of the right sign everywhere. All distances are in mm, negative inside.

use nalgebra::{Point3, Vector3};

/// Polynomial smooth minimum with blend radius `k` (mm); `k = 0` is the hard minimum.
#[inline]
pub fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// Exact signed distance to a round cone: spheres of radius `ra` at `a` and `rb` at `b` and
/// their tangent cone. Requires `|a - b| > |ra - rb|` (checked when the anatomy is read).
#[inline]
pub fn round_cone(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>, ra: f64, rb: f64) -> f64 {
    let ba = b - a;
    let l2 = ba.norm_squared();
    let rr = ra - rb;
    let a2 = l2 - rr * rr;
    let il2 = 1.0 / l2;
    let pa = p - a;
    let y = pa.dot(&ba);
    let z = y - l2;
    let x2 = (pa * l2 - ba * y).norm_squared();
    let y2 = y * y * l2;
    let z2 = z * z * l2;
    let k = rr.signum() * rr * rr * x2;
    if z.signum() * a2 * z2 > k {
        return (x2 + z2).sqrt() * il2 - rb;
    }
    if y.signum() * a2 * y2 < k {
        return (x2 + y2).sqrt() * il2 - ra;
    }
    ((x2 * a2 * il2).sqrt() + y * rr) * il2 - ra
}

/// An orthonormal frame built by Gram–Schmidt from a first axis and a hint for the second.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub e1: Vector3<f64>,
    pub e2: Vector3<f64>,
    pub e3: Vector3<f64>,
}

impl Frame {
    /// `None` when `first` is null or `second` is (nearly) parallel to it.
    pub fn from_axes(first: Vector3<f64>, second: Vector3<f64>) -> Option<Frame> {
        let e1 = first.try_normalize(1e-12)?;
        let e2 = (second - e1 * e1.dot(&second)).try_normalize(1e-6 * second.norm())?;
        Some(Frame {
            e1,
            e2,
            e3: e1.cross(&e2),
        })
    }

    /// Coordinates of `v` in this frame.
    #[inline]
    pub fn local(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(self.e1.dot(v), self.e2.dot(v), self.e3.dot(v))
    }
}

/// A tapered tube along a polyline: the union of round cones between successive nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    pub points: Vec<Point3<f64>>,
    pub radii: Vec<f64>,
}

impl Tube {
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let mut d = f64::INFINITY;
        for i in 1..self.points.len() {
            d = d.min(round_cone(
                p,
                &self.points[i - 1],
                &self.points[i],
                self.radii[i - 1],
                self.radii[i],
            ));
        }
        d
    }

    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for (p, r) in self.points.iter().zip(&self.radii) {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k] - r);
                hi[k] = hi[k].max(p[k] + r);
            }
        }
        (lo, hi)
    }
}

/// An ellipsoid: semi-axes `semi_axes[i]` along `frame.e{i+1}`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ellipsoid {
    pub center: Point3<f64>,
    pub frame: Frame,
    pub semi_axes: Vector3<f64>,
}

impl Ellipsoid {
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let q = self.frame.local(&(p - self.center));
        let k0 = q.component_div(&self.semi_axes).norm();
        let k1 = q
            .component_div(&self.semi_axes.component_mul(&self.semi_axes))
            .norm();
        if k1 <= f64::MIN_POSITIVE {
            return -self.semi_axes.min();
        }
        k0 * (k0 - 1.0) / k1
    }
}

/// An elliptic plate: semi-axes `semi_axes` along `frame.e1`, `frame.e2`, thickness along
/// `frame.e3` (the plate normal), centred on `center`.
#[derive(Debug, Clone, PartialEq)]
pub struct Disc {
    pub center: Point3<f64>,
    pub frame: Frame,
    pub semi_axes: [f64; 2],
    pub thickness: f64,
}

impl Disc {
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let q = self.frame.local(&(p - self.center));
        let (a, b) = (self.semi_axes[0], self.semi_axes[1]);
        let k0 = ((q.x / a).powi(2) + (q.y / b).powi(2)).sqrt();
        let k1 = ((q.x / (a * a)).powi(2) + (q.y / (b * b)).powi(2)).sqrt();
        let in_plane = if k1 <= f64::MIN_POSITIVE {
            -a.min(b)
        } else {
            k0 * (k0 - 1.0) / k1
        };
        let across = q.z.abs() - 0.5 * self.thickness;
        let outside = (in_plane.max(0.0).powi(2) + across.max(0.0).powi(2)).sqrt();
        outside + in_plane.max(across).min(0.0)
    }

    /// The unit normal of the plate.
    pub fn normal(&self) -> Vector3<f64> {
        self.frame.e3
    }
}

/// One primitive of a bone.
#[derive(Debug, Clone, PartialEq)]
pub enum Primitive {
    Tube(Tube),
    Ellipsoid(Ellipsoid),
    Disc(Disc),
}

impl Primitive {
    #[inline]
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        match self {
            Primitive::Tube(t) => t.distance(p),
            Primitive::Ellipsoid(e) => e.distance(p),
            Primitive::Disc(d) => d.distance(p),
        }
    }

    /// An axis-aligned box that encloses the primitive.
    pub fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let sphere =
            |c: &Point3<f64>, r: f64| (c - Vector3::from_element(r), c + Vector3::from_element(r));
        match self {
            Primitive::Tube(t) => t.bounds(),
            Primitive::Ellipsoid(e) => sphere(&e.center, e.semi_axes.max()),
            Primitive::Disc(d) => sphere(
                &d.center,
                d.semi_axes[0].max(d.semi_axes[1]).max(0.5 * d.thickness),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    #[test]
    fn round_cone_matches_capsule_and_cone_geometry() {
        let (a, b) = (p(0., 0., 0.), p(0., 0., 4.));
        // Equal radii: a capsule of radius 1.
        assert!((round_cone(&p(2., 0., 2.), &a, &b, 1., 1.) - 1.).abs() < 1e-12);
        assert!((round_cone(&p(0., 0., -3.), &a, &b, 1., 1.) - 2.).abs() < 1e-12);
        assert!((round_cone(&p(0., 0., 2.), &a, &b, 1., 1.) + 1.).abs() < 1e-12);
        // Tapered: beyond the small end the distance is to the small sphere.
        assert!((round_cone(&p(0., 0., 6.), &a, &b, 1., 0.5) - 1.5).abs() < 1e-12);
        // On the side the surface lies on the tangent line of the two spheres: the point
        // halfway along, offset radially by the exact side radius, is on the surface.
        let s = (0.5f64 / 4.0).asin(); // half-angle of the tangent cone
        let ta = p(s.cos(), 0., s.sin());
        assert!(round_cone(&ta, &a, &b, 1., 0.5).abs() < 1e-12);
    }

    #[test]
    fn ellipsoid_and_disc_signs_and_surface() {
        let frame = Frame::from_axes(Vector3::x(), Vector3::y()).unwrap();
        let e = Ellipsoid {
            center: p(1., 2., 3.),
            frame,
            semi_axes: Vector3::new(3., 2., 1.),
        };
        assert!(e.distance(&p(4., 2., 3.)).abs() < 1e-12);
        assert!(e.distance(&p(1., 2., 4.)).abs() < 1e-12);
        assert!(e.distance(&p(1., 2., 3.)) < 0.0);
        assert!((e.distance(&p(1., 2., 5.)) - 1.0).abs() < 0.05);
        let d = Disc {
            center: p(0., 0., 0.),
            frame,
            semi_axes: [1.5, 0.7],
            thickness: 0.3,
        };
        assert!(d.distance(&p(0., 0., 0.15)).abs() < 1e-12);
        assert!(d.distance(&p(1.5, 0., 0.)).abs() < 1e-12);
        assert!((d.distance(&p(0., 0., 1.15)) - 1.0).abs() < 1e-12);
        assert!((d.distance(&p(0., 0., 0.)) + 0.15).abs() < 1e-12);
    }

    #[test]
    fn smooth_min_is_below_both_and_hard_outside_blend() {
        assert_eq!(smooth_min(1.0, 3.0, 0.5), 1.0);
        assert!((smooth_min(1.0, 1.0, 0.4) - (1.0 - 0.1)).abs() < 1e-12);
        assert_eq!(smooth_min(-1.0, 2.0, 0.0), -1.0);
    }

    #[test]
    fn frame_rejects_parallel_axes() {
        assert!(Frame::from_axes(Vector3::x(), Vector3::x() * 2.0).is_none());
        let f = Frame::from_axes(Vector3::new(0., 0., 2.), Vector3::new(1., 0., 1.)).unwrap();
        assert!((f.e2 - Vector3::x()).norm() < 1e-12);
        assert!((f.e3 - Vector3::y()).norm() < 1e-12);
    }
}
