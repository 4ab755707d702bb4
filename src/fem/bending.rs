//! Bending of the membrane (the eardrum's shell): an energy quadratic in the dihedral angles
//! of its interior edges, one hinge per edge, whose stiffness matrix couples the three hinges
//! of each triangle so that it is consistent on irregular meshes.
//!
//! The hinge (Grinspun, Hirani, Desbrun & Schröder 2003, "Discrete shells"): the signed
//! dihedral angle θ of the two triangles of an edge, θ̃ = θ − θ₀ its change from rest; it is
//! invariant under rigid motions, so the energy is too.
//!
//! The energy (a rotation-free "basic shell triangle", after Oñate & Zárate 2000, Int J Numer
//! Meth Eng 47:557): for each triangle T, in its rest plane, the quadratic w(x, y) through its
//! own three vertices (height 0) and the three nodes across its edges (heights h_k) has a
//! constant curvature H = (w_xx, w_yy, w_xy) = B h, B from the six points' rest positions; a
//! change θ̃_k of edge k's angle lifts node k by h_k = θ̃_k / (∂θ_k/∂x_k · n_T) to first order,
//! so H = G θ̃ with G = B diag(1/(∂θ_k/∂x_k · n_T)), and the plate energy of T is
//! ½ A_T Hᵀ C H = ½ θ̃ᵀ (A_T Gᵀ C G) θ̃, C = D [[1, ν, 0], [ν, 1, 0], [0, 0, 2(1 − ν)]], D the
//! flexural rigidity. The quadratic is exact for a quadratic surface on any mesh, which is what
//! the discrete-shell hinge alone (a stiffness D|e|²/(A₁ + A₂) per edge, no coupling) lacks:
//! on an irregular mesh of a clamped plate its deflection converges towards a value about 6 %
//! above Kirchhoff's, this energy's to Kirchhoff's (`tests/mechanics_analytic.rs`). An edge
//! with no triangle across (the eardrum's rim) has no hinge: its node is a ghost, the mirror of
//! T's opposite vertex, whose angle is left free (eliminated from T's 3×3 matrix by its Schur
//! complement), so the rim carries no bending moment, as the hinges alone had it.
//!
//! Stored as each hinge's own stiffness K_ee (its diagonal) and the couplings K_ef of hinge
//! pairs sharing a triangle: E = ½ Σ_e K_ee θ̃_e² + Σ_(e,f) K_ef θ̃_e θ̃_f. Moments m = K θ̃,
//! forces f = −Σ_e m_e ∇θ_e; tangent Σ_(e,f) K_ef ∇θ_e ∇θ_fᵀ (Gauss–Newton: the terms
//! m_e ∇²θ_e are left out, so it is exact at rest and positive semi-definite everywhere).
//!
//! Gradient of θ (Wardetzky et al. 2007, "Discrete quadratic curvature energies"): with p, q
//! the edge, a and b the opposite nodes, h_a, h_b their distances to the edge line, n̂₁, n̂₂ the
//! triangles' unit normals (n̂₁ of (p, q, a), n̂₂ of (q, p, b)) and s = (x − p)·e/|e|² the
//! projection parameters of a and b: ∂θ/∂a = −n̂₁/h_a, ∂θ/∂b = −n̂₂/h_b,
//! ∂θ/∂p = −(1 − s_a)∂θ/∂a − (1 − s_b)∂θ/∂b, ∂θ/∂q = −s_a ∂θ/∂a − s_b ∂θ/∂b.

use std::collections::HashMap;

use nalgebra::{Matrix3, Point3, SMatrix, Vector2, Vector3};

use super::membrane::MembraneElement;

/// One vector per hinge node [p, q, a, b].
pub(crate) type HingeVectors = [Vector3<f64>; 4];

/// One bending hinge: nodes [p, q, a, b] (edge p–q, a opposite in the first triangle, b in
/// the second), its own stiffness K_ee (µN·mm per rad²) and rest angle θ₀ (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BendingHinge {
    pub nodes: [u32; 4],
    pub stiffness: f64,
    pub rest_angle: f64,
}

/// The coupling K_ef (µN·mm per rad²) of two hinges e < f of one triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HingeCoupling {
    pub hinges: [u32; 2],
    pub stiffness: f64,
}

/// One triangle's share of the bending: the hinges of its edges k = (nodes[k], nodes[k + 1])
/// where it has one, and its 3×3 stiffness k_t between their angles (zero for an edge without
/// hinge). K is the sum of the triangles' shares; the tangent is assembled from them
/// (`fem::assembly`), one block per pair of the at most six nodes a triangle's hinges span,
/// fewer blocks than from the hinges and couplings of K.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TriangleBending {
    pub hinges: [Option<u32>; 3],
    pub stiffness: Matrix3<f64>,
}

/// The membrane's bending: its hinges and their couplings (the energy and the moments), and
/// the same stiffness as each triangle's share (the tangent).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Bending {
    pub hinges: Vec<BendingHinge>,
    pub couplings: Vec<HingeCoupling>,
    pub triangles: Vec<TriangleBending>,
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

/// The bending of `triangles` (module doc), with the flexural rigidity and Poisson's ratio
/// `plate(t)` = (D µN·mm, ν) of triangle t and the rest positions `rest`: a hinge on every
/// interior edge next to a triangle with D > 0, their stiffnesses and couplings. Hinges are
/// sorted by edge.
pub(crate) fn bending(
    triangles: &[MembraneElement],
    plate: impl Fn(usize) -> (f64, f64),
    rest: &[Point3<f64>],
) -> Bending {
    // each triangle's edge k (nodes[k], nodes[k + 1]): its hinge, the node across it and the
    // angle's gradient at that node, at rest
    let mut across: Vec<[Option<Across>; 3]> = vec![[None; 3]; triangles.len()];
    let mut hinges = Vec::new();
    for ((p, q), sides) in interior_edges(triangles.iter().map(|t| &t.nodes)) {
        let [(t1, a), (t2, b)] = sides;
        if plate(t1).0 <= 0.0 && plate(t2).0 <= 0.0 {
            continue;
        }
        let nodes = [p, q, a, b];
        let Some((rest_angle, grad)) = angle_and_gradient(&nodes, rest) else {
            continue;
        };
        let index = hinges.len() as u32;
        for (t, own, node, gradient) in [(t1, a, b, grad[3]), (t2, b, a, grad[2])] {
            if let Some(k) = (0..3).find(|&k| triangles[t].nodes[(k + 2) % 3] == own) {
                across[t][k] = Some(Across {
                    hinge: index,
                    node,
                    gradient,
                });
            }
        }
        hinges.push(BendingHinge {
            nodes,
            stiffness: 0.0,
            rest_angle,
        });
    }
    let mut couplings: HashMap<(u32, u32), f64> = HashMap::new();
    let mut shares = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let (d, nu) = plate(t);
        if d <= 0.0 {
            continue;
        }
        let k_t = triangle_stiffness(tri, &across[t], rest, d, nu)
            .unwrap_or_else(|| hinge_share(tri, &across[t], rest, d));
        let own = across[t].map(|a| a.map(|a| a.hinge));
        if own.iter().any(Option::is_some) {
            shares.push(TriangleBending {
                hinges: own,
                stiffness: k_t,
            });
        }
        for (k, slot) in across[t].iter().enumerate() {
            let Some(Across { hinge: e, .. }) = *slot else {
                continue;
            };
            hinges[e as usize].stiffness += k_t[(k, k)];
            for (l, other) in across[t].iter().enumerate().skip(k + 1) {
                if let Some(Across { hinge: f, .. }) = *other {
                    *couplings.entry((e.min(f), e.max(f))).or_default() += k_t[(k, l)];
                }
            }
        }
    }
    let mut couplings: Vec<HingeCoupling> = couplings
        .into_iter()
        .map(|((e, f), stiffness)| HingeCoupling {
            hinges: [e, f],
            stiffness,
        })
        .collect();
    couplings.sort_unstable_by_key(|c| c.hinges);
    Bending {
        hinges,
        couplings,
        triangles: shares,
    }
}

/// A triangle's 3×3 stiffness above this times D |e_max|²/A (about 0.25 on a regular mesh)
/// means its six points lie near a conic, so that no quadratic through them is well
/// determined (up to 1e13 times on the refined eardrums, whose static solve then failed): it
/// takes the hinges' share instead (`hinge_share`). On the default eardrum 150 of its 2,537
/// triangles do (5.9 %), on one refined to 0.12 mm 315 of 10,142 (3.1 %).
const MAX_PATCH_STIFFNESS: f64 = 2.0;

/// A triangle's share of the discrete-shell hinges of its edges, D|e|²/(A₁ + A₂) each split
/// evenly between the two triangles (a diagonal 3×3; ghost edges zero): the bending of a
/// triangle whose patch admits no well-determined quadratic.
fn hinge_share(
    tri: &MembraneElement,
    across: &[Option<Across>; 3],
    rest: &[Point3<f64>],
    d: f64,
) -> Matrix3<f64> {
    let v = tri.nodes.map(|n| rest[n as usize]);
    let area = 0.5 * (v[1] - v[0]).cross(&(v[2] - v[0])).norm();
    Matrix3::from_fn(|i, j| match &across[i] {
        Some(Across { gradient, .. }) if i == j => {
            let len = (v[(i + 1) % 3] - v[i]).norm();
            // the triangle across: its height over the edge is 1/|∂θ/∂x|
            let across_area = 0.5 * len / gradient.norm();
            0.5 * d * len * len / (area + across_area)
        }
        _ => 0.0,
    })
}

/// The hinge across one edge of a triangle, the hinge's node on the other side and the
/// gradient of its angle at that node, at rest.
#[derive(Debug, Clone, Copy)]
struct Across {
    hinge: u32,
    node: u32,
    gradient: Vector3<f64>,
}

/// The 3×3 stiffness A_T Gᵀ C G of triangle `tri` on the angles of its edges k = (nodes[k],
/// nodes[k + 1]) (module doc); `across[k]` is edge k's hinge, `None` for a ghost, whose row
/// and column come out zero (eliminated). `None` when the six points admit no
/// well-determined quadratic (`MAX_PATCH_STIFFNESS`) or a hinge's angle does not change as
/// its node across leaves the plane.
fn triangle_stiffness(
    tri: &MembraneElement,
    across: &[Option<Across>; 3],
    rest: &[Point3<f64>],
    d: f64,
    nu: f64,
) -> Option<Matrix3<f64>> {
    let v = tri.nodes.map(|n| rest[n as usize]);
    let normal = (v[1] - v[0]).cross(&(v[2] - v[0]));
    let area = 0.5 * normal.norm();
    if area <= 0.0 {
        return None;
    }
    let n = normal / (2.0 * area);
    let centre = (v[0].coords + v[1].coords + v[2].coords) / 3.0;
    let e1 = (v[1] - v[0]).normalize();
    let e2 = n.cross(&e1);
    let plane = |p: &Vector3<f64>| Vector2::new((p - centre).dot(&e1), (p - centre).dot(&e2));
    let own = v.map(|p| plane(&p.coords));
    let mut points = [Vector2::zeros(); 6];
    points[..3].copy_from_slice(&own);
    // height per unit angle of each edge's node across
    let mut lift = [0.0f64; 3];
    for k in 0..3 {
        match &across[k] {
            Some(Across { node, gradient, .. }) => {
                let slope = gradient.dot(&n);
                if slope.abs() <= f64::MIN_POSITIVE {
                    return None;
                }
                points[3 + k] = plane(&rest[*node as usize].coords);
                lift[k] = 1.0 / slope;
            }
            None => {
                // the mirror of the vertex opposite edge k across it
                let (a, b, c) = (own[k], own[(k + 1) % 3], own[(k + 2) % 3]);
                let t = b - a;
                let foot = a + t * ((c - a).dot(&t) / t.norm_squared());
                points[3 + k] = foot * 2.0 - c;
                lift[k] = 1.0;
            }
        }
    }
    let m = SMatrix::<f64, 6, 6>::from_fn(|i, j| {
        let (x, y) = (points[i].x, points[i].y);
        [1.0, x, y, 0.5 * x * x, 0.5 * y * y, x * y][j]
    });
    let inverse = m.try_inverse()?;
    let g = Matrix3::from_fn(|i, k| inverse[(3 + i, 3 + k)] * lift[k]);
    let c = Matrix3::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 2.0 * (1.0 - nu)) * d;
    let mut k_t = g.transpose() * c * g * area;
    let longest2 = (0..3)
        .map(|k| (v[(k + 1) % 3] - v[k]).norm_squared())
        .fold(0.0, f64::max);
    let bound = MAX_PATCH_STIFFNESS * d * longest2 / area;
    if k_t.abs().max().partial_cmp(&bound) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    for k in 0..3 {
        if across[k].is_none() {
            let pivot = k_t[(k, k)];
            if pivot > 0.0 {
                let (col, row) = (k_t.column(k).into_owned(), k_t.row(k).into_owned());
                k_t -= col * row / pivot;
            }
            k_t.row_mut(k).fill(0.0);
            k_t.column_mut(k).fill(0.0);
        }
    }
    Some(k_t)
}

impl BendingHinge {
    /// The change θ̃ = θ − θ₀ of the angle (the shortest way round) and its gradient at `x`,
    /// or `None` for a collapsed triangle.
    pub fn angle_change(&self, x: &[Point3<f64>]) -> Option<(f64, HingeVectors)> {
        let (angle, grad) = angle_and_gradient(&self.nodes, x)?;
        let mut delta = angle - self.rest_angle;
        if delta > std::f64::consts::PI {
            delta -= 2.0 * std::f64::consts::PI;
        } else if delta < -std::f64::consts::PI {
            delta += 2.0 * std::f64::consts::PI;
        }
        Some((delta, grad))
    }
}

impl Bending {
    /// The moments m = K θ̃ (µN·mm) of the angle changes `deltas`, one per hinge, into
    /// `moments`.
    pub fn moments(&self, deltas: &[f64], moments: &mut [f64]) {
        for ((m, h), d) in moments.iter_mut().zip(&self.hinges).zip(deltas) {
            *m = h.stiffness * d;
        }
        for c in &self.couplings {
            let [e, f] = c.hinges.map(|h| h as usize);
            moments[e] += c.stiffness * deltas[f];
            moments[f] += c.stiffness * deltas[e];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::material::MembraneMaterial;
    use crate::fem::membrane::rest_membrane;
    use nalgebra::{Rotation3, Vector3};

    /// The bending energy ½ θ̃ᵀ K θ̃ at `x` (µN·mm).
    fn energy(bending: &Bending, x: &[Point3<f64>]) -> f64 {
        let deltas: Vec<f64> = bending
            .hinges
            .iter()
            .map(|h| h.angle_change(x).map_or(0.0, |(d, _)| d))
            .collect();
        let mut moments = vec![0.0; deltas.len()];
        bending.moments(&deltas, &mut moments);
        0.5 * deltas.iter().zip(&moments).map(|(d, m)| d * m).sum::<f64>()
    }

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

    /// A triangle and the three across its edges, irregular, in the plane z = 0; only the
    /// first triangle bends.
    fn patch() -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
        let rest = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.1, 0.1, 0.0),
            Point3::new(0.3, 0.9, 0.0),
            Point3::new(0.6, -0.8, 0.0),
            Point3::new(1.2, 1.0, 0.0),
            Point3::new(-0.7, 0.5, 0.0),
        ];
        (rest, vec![[0, 1, 2], [1, 0, 3], [2, 1, 4], [0, 2, 5]])
    }

    /// The bending of `cells` with plate(t) = (D, ν) of triangle t.
    fn bending_of(
        rest: &[Point3<f64>],
        cells: &[[u32; 3]],
        plate: impl Fn(usize) -> (f64, f64),
    ) -> Bending {
        let mat = MembraneMaterial {
            youngs_modulus: 2.0e7,
            poisson_ratio: plate(0).1,
            thickness: 0.05,
            bending_thickness: None,
            density: 1e-3,
        };
        let tris: Vec<MembraneElement> = cells
            .iter()
            .enumerate()
            .map(|(e, c)| rest_membrane(e, *c, rest, &mat).unwrap())
            .collect();
        bending(&tris, plate, rest)
    }

    /// The bending of the first triangle alone.
    fn patch_bending(rest: &[Point3<f64>], cells: &[[u32; 3]], d: f64, nu: f64) -> Bending {
        bending_of(rest, cells, |t| (if t == 0 { d } else { 0.0 }, nu))
    }

    /// Lifted by a small quadratic height w = ε(½ a x² + b x y + ½ c y²), the bending
    /// triangle stores the plate's ½ A D [(1 − ν) H:H + ν (tr H)²] of its constant curvature
    /// H = ε (a, c, b) whatever the mesh's irregularity: the quadratic through its six points
    /// is exact. The hinge alone is not (the module doc).
    #[test]
    fn an_irregular_patch_stores_the_plate_energy_of_a_quadratic() {
        let (rest, cells) = patch();
        let (d, nu) = (0.7, 0.3);
        let bending = patch_bending(&rest, &cells, d, nu);
        assert_eq!(bending.hinges.len(), 3);
        assert_eq!(bending.couplings.len(), 3);
        let area = 0.5 * (rest[1] - rest[0]).cross(&(rest[2] - rest[0])).norm();
        let eps = 1e-5;
        for (a, b, c) in [
            (1.0, 0.0, 0.0),
            (0.0, 0.0, 1.0),
            (0.0, 1.0, 0.0),
            (0.7, -0.4, 1.3),
        ] {
            let lifted: Vec<Point3<f64>> = rest
                .iter()
                .map(|p| {
                    let w = eps * (0.5 * a * p.x * p.x + b * p.x * p.y + 0.5 * c * p.y * p.y);
                    Point3::new(p.x, p.y, w)
                })
                .collect();
            let (h11, h22, h12) = (eps * a, eps * c, eps * b);
            let plate = 0.5
                * area
                * d
                * ((1.0 - nu) * (h11 * h11 + h22 * h22 + 2.0 * h12 * h12)
                    + nu * (h11 + h22).powi(2));
            let stored = energy(&bending, &lifted);
            println!("({a}, {b}, {c}): stored / plate = {}", stored / plate);
            assert!((stored / plate - 1.0).abs() < 1e-4, "{}", stored / plate);
        }
    }

    /// The triangles' shares add up to the hinges' own stiffnesses and their couplings: the
    /// tangent assembled from the shares is that of the energy.
    #[test]
    fn the_triangles_shares_add_up_to_the_stiffness() {
        let (rest, cells) = patch();
        let bending = bending_of(&rest, &cells, |_| (0.7, 0.3));
        // each hinge has a share from the middle triangle and from the one across it
        assert_eq!((bending.triangles.len(), bending.couplings.len()), (4, 3));
        let n = bending.hinges.len();
        let mut from_shares = nalgebra::DMatrix::<f64>::zeros(n, n);
        for share in &bending.triangles {
            for (k, e) in share.hinges.iter().enumerate() {
                for (l, f) in share.hinges.iter().enumerate() {
                    if let (Some(e), Some(f)) = (e, f) {
                        from_shares[(*e as usize, *f as usize)] += share.stiffness[(k, l)];
                    }
                }
            }
        }
        let mut stored = nalgebra::DMatrix::<f64>::zeros(n, n);
        for (e, h) in bending.hinges.iter().enumerate() {
            stored[(e, e)] = h.stiffness;
        }
        for c in &bending.couplings {
            let [e, f] = c.hinges.map(|h| h as usize);
            stored[(e, f)] = c.stiffness;
            stored[(f, e)] = c.stiffness;
        }
        assert!(stored.abs().max() > 0.0);
        assert!((&from_shares - &stored).abs().max() <= 1e-12 * stored.abs().max());
    }

    /// An edge with nothing across it is free: its ghost's angle minimises the triangle's
    /// energy, so for any lift the triangle stores no more than with a neighbour at the
    /// ghost's place (the mirror of its opposite vertex) lifted alike, and less where the
    /// curvature is across the free edge.
    #[test]
    fn a_free_edge_is_softer_than_a_neighbour() {
        let (mut rest, mut cells) = patch();
        // the neighbour across edge (2, 0) at the mirror of vertex 1
        let (p, q, o) = (rest[2], rest[0], rest[1]);
        let t = (q - p).normalize();
        let foot = p + t * (o - p).dot(&t);
        rest[5] = foot + (foot - o);
        let (d, nu) = (0.7, 0.3);
        let full = patch_bending(&rest, &cells, d, nu);
        cells.remove(3);
        let free = patch_bending(&rest, &cells, d, nu);
        assert_eq!(free.hinges.len(), 2);
        let eps = 1e-5;
        let across = Vector3::z().cross(&t);
        for direction in [across, t, (t + across).normalize()] {
            let lifted: Vec<Point3<f64>> = rest
                .iter()
                .map(|x| {
                    let s = (x - p).dot(&direction);
                    Point3::new(x.x, x.y, 0.5 * eps * s * s)
                })
                .collect();
            let (e_free, e_full) = (energy(&free, &lifted), energy(&full, &lifted));
            println!("curvature along {direction:?}: free edge {e_free:e}, neighbour {e_full:e}");
            assert!(e_free <= e_full * (1.0 + 1e-9));
            if direction == across {
                assert!(e_free < 0.5 * e_full);
            }
        }
    }

    /// The energy and the forces follow a rigid motion: the angle changes are invariant and
    /// their gradients turn with it; a rigidly moved rest shape is unbent.
    #[test]
    fn rigid_motion_moves_nothing() {
        let (rest, cells) = patch();
        let bending = patch_bending(&rest, &cells, 0.7, 0.3);
        let bent: Vec<Point3<f64>> = rest
            .iter()
            .map(|p| Point3::new(p.x, p.y, 0.05 * p.x * p.x - 0.03 * p.x * p.y))
            .collect();
        let q = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.8);
        let moved: Vec<Point3<f64>> = bent
            .iter()
            .map(|p| q * p + Vector3::new(1.0, 2.0, -3.0))
            .collect();
        let e0 = energy(&bending, &bent);
        assert!(e0 > 0.0);
        assert!((energy(&bending, &moved) - e0).abs() <= 1e-9 * e0);
        for h in &bending.hinges {
            let (d0, g0) = h.angle_change(&bent).unwrap();
            let (d1, g1) = h.angle_change(&moved).unwrap();
            assert!((d0 - d1).abs() < 1e-12);
            for (a, b) in g0.iter().zip(&g1) {
                assert!((q * a - b).norm() <= 1e-9 * (1.0 + a.norm()));
            }
        }
        let turned: Vec<Point3<f64>> = rest.iter().map(|p| q * p).collect();
        assert!(energy(&bending, &turned) < 1e-20);
    }
}
