//! Discrete-shell bending of the membrane: one hinge per interior edge of the membrane
//! triangles (Grinspun, Hirani, Desbrun & Schröder 2003, "Discrete shells"), so that the
//! eardrum resists folding even where it is not tensioned.
//!
//! Energy of a hinge with edge e, adjacent triangle areas A₁, A₂ and dihedral angle θ (rest
//! θ₀): E = ½ k (θ − θ₀)², k = D|e|²/(A₁ + A₂), D = E_m h³/(12(1 − ν²)) the flexural
//! rigidity (µN·mm) averaged over the two triangles. With this k an equilateral mesh bent
//! into a cylinder of radius r stores the plate's ½ D A / r² within 2 % whatever the
//! orientation of its axis (unit test below), which is what fixes the constant.
//!
//! Gradient of θ (Wardetzky et al. 2007, "Discrete quadratic curvature energies"): with p, q
//! the edge, a and b the opposite nodes, h_a, h_b their distances to the edge line, n̂₁, n̂₂ the
//! triangles' unit normals (n̂₁ of (p, q, a), n̂₂ of (q, p, b)) and s = (x − p)·e/|e|² the
//! projection parameters of a and b: ∂θ/∂a = −n̂₁/h_a, ∂θ/∂b = −n̂₂/h_b,
//! ∂θ/∂p = −(1 − s_a)∂θ/∂a − (1 − s_b)∂θ/∂b, ∂θ/∂q = −s_a ∂θ/∂a − s_b ∂θ/∂b.
//! Forces f = −k(θ − θ₀)∇θ; tangent k ∇θ∇θᵀ (Gauss–Newton: the term k(θ − θ₀)∇²θ is left
//! out, so it is exact at rest and positive semi-definite everywhere). The energy is
//! invariant under rigid motions, so a rigidly moved mesh is at rest.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

use super::membrane::MembraneElement;

/// One vector per hinge node [p, q, a, b].
pub(crate) type HingeVectors = [Vector3<f64>; 4];

/// One bending hinge: nodes [p, q, a, b] (edge p–q, a opposite in the first triangle, b in
/// the second), stiffness k (µN·mm per rad²) and rest angle θ₀ (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BendingHinge {
    pub nodes: [u32; 4],
    pub stiffness: f64,
    pub rest_angle: f64,
}

/// Signed dihedral angle (rad) and its gradient at positions `x`; `None` when a triangle
/// has collapsed (no normal).
pub(crate) fn angle_and_gradient(
    nodes: &[u32; 4],
    x: &[Point3<f64>],
) -> Option<(f64, HingeVectors)> {
    let [p, q, a, b] = nodes.map(|v| x[v as usize]);
    let e = q - p;
    let len2 = e.norm_squared();
    let n1 = e.cross(&(a - p));
    let n2 = (b - p).cross(&e);
    let (a1, a2) = (n1.norm(), n2.norm());
    if !(len2 > 0.0 && a1 > 1e-14 * len2 && a2 > 1e-14 * len2) {
        return None;
    }
    let len = len2.sqrt();
    let (u1, u2) = (n1 / a1, n2 / a2);
    let angle = u1.cross(&u2).dot(&e).atan2(u1.dot(&u2) * len);
    // h_a = |n1|/|e|, so −n̂₁/h_a = −n1·|e|/|n1|²
    let ga = -n1 * (len / (a1 * a1));
    let gb = -n2 * (len / (a2 * a2));
    let (sa, sb) = ((a - p).dot(&e) / len2, (b - p).dot(&e) / len2);
    let gp = -ga * (1.0 - sa) - gb * (1.0 - sb);
    let gq = -ga * sa - gb * sb;
    Some((angle, [gp, gq, ga, gb]))
}

/// An interior edge: (lo, hi) and, for each of its two triangles, (triangle index, opposite
/// node).
pub(crate) type InteriorEdge = ((u32, u32), [(usize, u32); 2]);

/// The interior edges of `triangles` (edges shared by exactly two), sorted by edge: the edge
/// (lo, hi) and, for each of its triangles in order, (triangle index, opposite node).
pub(crate) fn interior_edges<'a>(
    triangles: impl IntoIterator<Item = &'a [u32; 3]>,
) -> Vec<InteriorEdge> {
    let mut edges: HashMap<(u32, u32), Vec<(usize, u32)>> = HashMap::new();
    for (t, tri) in triangles.into_iter().enumerate() {
        for k in 0..3 {
            let (p, q, o) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            edges.entry((p.min(q), p.max(q))).or_default().push((t, o));
        }
    }
    let mut interior: Vec<_> = edges
        .into_iter()
        .filter_map(|(edge, sides)| Some((edge, <[(usize, u32); 2]>::try_from(sides).ok()?)))
        .collect();
    interior.sort_unstable_by_key(|(edge, _)| *edge);
    interior
}

/// The hinges of the interior edges of `triangles`, with the flexural rigidity `rigidity(t)`
/// (µN·mm) of triangle t and the rest positions `rest`; an edge whose two triangles have no
/// rigidity gets no hinge. Sorted by edge.
pub(crate) fn hinges(
    triangles: &[MembraneElement],
    rigidity: impl Fn(usize) -> f64,
    rest: &[Point3<f64>],
) -> Vec<BendingHinge> {
    interior_edges(triangles.iter().map(|t| &t.nodes))
        .into_iter()
        .filter_map(|((p, q), [(t1, a), (t2, b)])| {
            let nodes = [p, q, a, b];
            let (rest_angle, _) = angle_and_gradient(&nodes, rest)?;
            let len2 = (rest[q as usize] - rest[p as usize]).norm_squared();
            let d = 0.5 * (rigidity(t1) + rigidity(t2));
            if d <= 0.0 {
                return None;
            }
            Some(BendingHinge {
                nodes,
                stiffness: d * len2 / (triangles[t1].measure_area() + triangles[t2].measure_area()),
                rest_angle,
            })
        })
        .collect()
}

impl BendingHinge {
    /// Nodal forces (µN) and the angle gradient at `x`, or `None` for a collapsed triangle.
    pub fn forces(&self, x: &[Point3<f64>]) -> Option<(HingeVectors, HingeVectors)> {
        let (angle, grad) = angle_and_gradient(&self.nodes, x)?;
        let mut delta = angle - self.rest_angle;
        // the shortest way round
        if delta > std::f64::consts::PI {
            delta -= 2.0 * std::f64::consts::PI;
        } else if delta < -std::f64::consts::PI {
            delta += 2.0 * std::f64::consts::PI;
        }
        Some((grad.map(|g| g * (-self.stiffness * delta)), grad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::material::MembraneMaterial;
    use crate::fem::membrane::rest_membrane;
    use nalgebra::{Rotation3, Vector3};

    fn hinge_points(fold: f64) -> Vec<Point3<f64>> {
        vec![
            Point3::new(0.1, -0.2, 0.05),
            Point3::new(1.3, 0.1, -0.1),
            Point3::new(0.4, 1.0, 0.3 * fold),
            Point3::new(0.9, -0.8, -0.2 * fold),
        ]
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let nodes = [0, 1, 2, 3];
        for fold in [0.0, 1.0, -2.0] {
            let x = hinge_points(fold);
            let (_, grad) = angle_and_gradient(&nodes, &x).unwrap();
            let h = 1e-6;
            for v in 0..4 {
                for i in 0..3 {
                    let mut xp = x.clone();
                    let mut xm = x.clone();
                    xp[v][i] += h;
                    xm[v][i] -= h;
                    let fd = (angle_and_gradient(&nodes, &xp).unwrap().0
                        - angle_and_gradient(&nodes, &xm).unwrap().0)
                        / (2.0 * h);
                    assert!(
                        (fd - grad[v][i]).abs() < 1e-6,
                        "{fold} {v} {i}: {fd} vs {}",
                        grad[v][i]
                    );
                }
            }
        }
    }

    /// An equilateral lattice bent into a cylinder of radius r stores the plate's bending
    /// energy ½ D A / r² (A the area the hinges cover), for any orientation of the axis;
    /// after a rigid motion of the bent sheet the forces are unchanged (none at rest).
    #[test]
    fn equilateral_sheet_bent_into_a_cylinder_stores_plate_energy() {
        let (a, n) = (0.1, 40usize);
        let mut rest = Vec::new();
        for j in 0..n {
            for i in 0..n {
                rest.push(Point3::new(
                    a * (i as f64 + 0.5 * j as f64),
                    a * j as f64 * 3f64.sqrt() / 2.0,
                    0.0,
                ));
            }
        }
        let id = |i: usize, j: usize| (j * n + i) as u32;
        let mut cells = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                cells.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                cells.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let mat = MembraneMaterial {
            youngs_modulus: 2.0e7,
            poisson_ratio: 0.3,
            thickness: 0.05,
            bending_thickness: None,
            density: 1e-3,
        };
        let d = mat.youngs_modulus * 0.08f64.powi(3) / (12.0 * (1.0 - 0.09));
        let tris: Vec<MembraneElement> = cells
            .iter()
            .enumerate()
            .map(|(e, c)| rest_membrane(e, *c, &rest, &mat).unwrap())
            .collect();
        let hinges = hinges(&tris, |_| d, &rest);
        assert!(hinges.iter().all(|h| h.rest_angle.abs() < 1e-12));
        let r = 3.0;
        for axis_angle in [0.0, 0.3, 1.1, 2.0] {
            let (c, s) = (f64::cos(axis_angle), f64::sin(axis_angle));
            let bent: Vec<Point3<f64>> = rest
                .iter()
                .map(|p| {
                    // u along the cylinder's axis, v across it (arc length)
                    let (u, v) = (c * p.x + s * p.y, -s * p.x + c * p.y);
                    let (w, z) = (r * (v / r).sin(), r * (1.0 - (v / r).cos()));
                    Point3::new(c * u - s * w, s * u + c * w, z)
                })
                .collect();
            let (mut energy, mut area) = (0.0, 0.0);
            for h in &hinges {
                let (angle, _) = angle_and_gradient(&h.nodes, &bent).unwrap();
                energy += 0.5 * h.stiffness * (angle - h.rest_angle).powi(2);
                let [p, q, x, y] = h.nodes.map(|v| rest[v as usize]);
                area += ((q - p).cross(&(x - p)).norm() + (y - p).cross(&(q - p)).norm()) / 6.0;
            }
            let plate = 0.5 * d * area / (r * r);
            println!(
                "axis {axis_angle}: hinge energy / plate energy = {}",
                energy / plate
            );
            assert!((energy / plate - 1.0).abs() < 0.03, "{}", energy / plate);
            let q = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.8);
            let moved: Vec<Point3<f64>> = bent
                .iter()
                .map(|p| q * p + Vector3::new(1.0, 2.0, -3.0))
                .collect();
            for h in hinges.iter().step_by(97) {
                let (f0, _) = h.forces(&bent).unwrap();
                let (f1, _) = h.forces(&moved).unwrap();
                for (a, b) in f0.iter().zip(&f1) {
                    assert!((q * a - b).norm() <= 1e-9 * (1.0 + a.norm()));
                }
                let (at_rest, _) = h
                    .forces(&rest.iter().map(|p| q * p).collect::<Vec<_>>())
                    .unwrap();
                assert!(at_rest.iter().all(|f| f.norm() < 1e-9 * h.stiffness));
            }
        }
    }
}
