//! The eardrum's bending in the SOFA scene: SOFA's FastTriangularBendingSprings (Volino &
//! Magnenat-Thalmann 2006, "Simple linear bending stiffness in particle systems") with a
//! ConstantForceField that cancels its force at the rest shape.
//!
//! FastTriangularBendingSprings puts one spring on every edge shared by exactly two triangles
//! of its topology: wings A, B, edge C–D, weights α (A: |N_B|/(|N_A| + |N_B|), B: |N_A|/(…),
//! C: −|N_D|/(|N_C| + |N_D|), D: −|N_C|/(…), N_X the doubled area of the triangle X makes with
//! the two nodes it is not paired with), stiffness λ = ⅔ (h_A + h_B)/(h_A² h_B²) · |CD| · S (h
//! the wings' distances to the edge line, S the component's `bendingStiffness`), and force
//! f_j = −λ α_j R with R = Σ α_k x_k (FastTriangularBendingSprings.inl in sofa-framework/sofa,
//! v23.06–v24.12). R vanishes only on a flat hinge, so on the curved eardrum the springs push
//! at rest; the ConstantForceField adds back −f at the rest positions, which leaves the linear
//! stiffness K = λ αα^T ⊗ I about the rest shape (exact for small rotations: the springs are
//! linear in x, not corotational).
//!
//! On a flat hinge R·n̂ = −δθ h_A h_B/(h_A + h_B), so Volino's normal stiffness is
//! ⅔ S |e|/(h_A + h_B) per rad² against the discrete shell's D|e|²/(A₁ + A₂) = 2D|e|/(h_A + h_B):
//! S = 3D gives the discrete-shell hinge exactly (tested below). otoatlas's own bending
//! (`fem::bending`, since 2026-11-27) couples the three hinges of each triangle so that it is
//! consistent on irregular meshes; SOFA has no such component, so the scene keeps the hinges
//! alone. On the default atlas the hinges alone gave a transfer function at most 0.21 dB and
//! 0.7° from the coupled bending's and a static asymmetry 1.1 % larger (docs/mechanics.md,
//! "The eardrum: a curved shell").
//!
//! One component has one S, the eardrum several rigidities (pars tensa, pars flaccida), so the
//! scene stacks layers: with the distinct rigidities D₁ < D₂ < … of the triangles, layer k acts
//! on the triangles with D ≥ D_k at S = 3(D_k − D_{k−1}). A triangle's layers sum to 3D; a
//! hinge between two rigidities gets the smaller (otoatlas: their mean).

use nalgebra::{Point3, Vector3};

use crate::fem::bending::interior_edges;

/// SOFA's `bendingStiffness` per unit flexural rigidity that reproduces the discrete-shell
/// hinge (module doc).
pub(super) const STIFFNESS_PER_RIGIDITY: f64 = 3.0;

/// FastTriangularBendingSprings' default `minDistValidity` [mm]: no spring on a shorter edge
/// or wing-to-wing distance.
const MIN_DIST_VALIDITY: f64 = 1e-6;

/// One FastTriangularBendingSprings component: the membrane triangles of its topology (indices
/// into the mesh's triangles) and its `bendingStiffness` S (µN·mm).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BendingLayer {
    pub triangles: Vec<usize>,
    pub stiffness: f64,
}

/// The stacked layers for triangle rigidities `rigidity` (µN·mm, 0 = no bending).
pub(super) fn layers(rigidity: &[f64]) -> Vec<BendingLayer> {
    let mut levels: Vec<f64> = rigidity.iter().copied().filter(|&d| d > 0.0).collect();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let mut below = 0.0;
    levels
        .into_iter()
        .map(|d| {
            let layer = BendingLayer {
                triangles: (0..rigidity.len()).filter(|&t| rigidity[t] >= d).collect(),
                stiffness: STIFFNESS_PER_RIGIDITY * (d - below),
            };
            below = d;
            layer
        })
        .collect()
}

/// One Volino spring: nodes [A, B, C, D], weights α and stiffness λ (µN/mm).
struct Spring {
    nodes: [u32; 4],
    alpha: [f64; 4],
    lambda: f64,
}

/// The springs FastTriangularBendingSprings builds on `triangles` at rest positions `x` with
/// `bendingStiffness` `s`.
fn springs(x: &[Point3<f64>], triangles: &[[u32; 3]], s: f64) -> Vec<Spring> {
    interior_edges(triangles)
        .into_iter()
        .filter_map(|((c, d), [(_, a), (_, b)])| spring([a, b, c, d], x, s))
        .collect()
}

fn spring(nodes: [u32; 4], x: &[Point3<f64>], s: f64) -> Option<Spring> {
    let [a, b, c, d] = nodes.map(|v| x[v as usize]);
    let eps2 = MIN_DIST_VALIDITY * MIN_DIST_VALIDITY;
    if (b - a).norm_squared() <= eps2 || (d - c).norm_squared() <= eps2 {
        return None;
    }
    let na = (a - c).cross(&(a - d)).norm();
    let nb = (b - d).cross(&(b - c)).norm();
    let nc = (c - b).cross(&(c - a)).norm();
    let nd = (d - a).cross(&(d - b)).norm();
    let alpha = [
        nb / (na + nb),
        na / (na + nb),
        -nd / (nc + nd),
        -nc / (nc + nd),
    ];
    let edge = (c - d).normalize();
    let off_edge = |v: Vector3<f64>| (v - edge * v.dot(&edge)).norm();
    let (ha, hb) = (off_edge(c - a), off_edge(c - b));
    let lambda = 2.0 / 3.0 * (ha + hb) / (ha * ha * hb * hb) * (c - d).norm() * s;
    lambda.is_finite().then_some(Spring {
        nodes,
        alpha,
        lambda,
    })
}

/// Adds the force (µN) FastTriangularBendingSprings on `triangles` with `bendingStiffness`
/// `s`, set up at the rest positions `rest`, exerts at positions `x` to `force`.
pub(super) fn add_spring_force(
    rest: &[Point3<f64>],
    x: &[Point3<f64>],
    triangles: &[[u32; 3]],
    s: f64,
    force: &mut [Vector3<f64>],
) {
    for sp in springs(rest, triangles, s) {
        let r: Vector3<f64> = (0..4)
            .map(|k| x[sp.nodes[k] as usize].coords * sp.alpha[k])
            .sum();
        for k in 0..4 {
            force[sp.nodes[k] as usize] -= r * (sp.lambda * sp.alpha[k]);
        }
    }
}

/// The force that cancels `layers` at the rest positions `x`: per node (µN), zero off the
/// eardrum.
pub(super) fn rest_force_cancellation(
    x: &[Point3<f64>],
    triangles: &[[u32; 3]],
    layers: &[BendingLayer],
) -> Vec<Vector3<f64>> {
    let mut force = vec![Vector3::zeros(); x.len()];
    for layer in layers {
        let tris: Vec<[u32; 3]> = layer.triangles.iter().map(|&t| triangles[t]).collect();
        add_spring_force(x, x, &tris, layer.stiffness, &mut force);
    }
    force.iter_mut().for_each(|f| *f = -*f);
    force
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::bending::angle_and_gradient;

    /// Volino's stiffness K = λ αα^T ⊗ I at S = 3D equals the discrete-shell hinge's
    /// k ∇θ∇θ^T (k = D|e|²/(A₁ + A₂)) in the normal direction on a flat, irregular hinge.
    #[test]
    fn three_times_the_rigidity_gives_the_discrete_shell_hinge() {
        let x = [
            Point3::new(0.0, 0.0, 0.0),  // p (edge)
            Point3::new(1.3, 0.2, 0.0),  // q (edge)
            Point3::new(0.4, 0.9, 0.0),  // a (wing of p, q, a)
            Point3::new(0.9, -0.6, 0.0), // b (wing of q, p, b)
        ];
        let d = 0.37;
        let (_, grad) = angle_and_gradient(&[0, 1, 2, 3], &x).unwrap();
        let e = x[1] - x[0];
        let area = |u: Vector3<f64>| 0.5 * e.cross(&u).norm();
        let k = d * e.norm_squared() / (area(x[2] - x[0]) + area(x[3] - x[0]));
        let sp = spring([2, 3, 0, 1], &x, STIFFNESS_PER_RIGIDITY * d).unwrap();
        // Volino's node order [A, B, C, D] = hinge nodes [a, b, p, q] = indices [2, 3, 0, 1]
        for (j, &hj) in sp.nodes.iter().enumerate() {
            for (m, &hm) in sp.nodes.iter().enumerate() {
                let volino = sp.lambda * sp.alpha[j] * sp.alpha[m];
                let shell = k * grad[hj as usize].z * grad[hm as usize].z;
                assert!(
                    (volino - shell).abs() <= 1e-12 * shell.abs().max(1.0),
                    "K[{j}{m}]: {volino} vs {shell}"
                );
            }
        }
    }

    /// On a bent hinge the springs push at rest, and the cancellation makes the net force zero
    /// there; a small displacement then meets the linear stiffness λ αα^T.
    #[test]
    fn the_cancellation_leaves_a_force_free_rest_shape() {
        let x = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.5, 0.8, 0.15),
            Point3::new(0.4, -0.9, 0.2),
        ];
        let tris = [[0, 1, 2], [1, 0, 3]];
        let layers = vec![BendingLayer {
            triangles: vec![0, 1],
            stiffness: 2.0,
        }];
        let cancel = rest_force_cancellation(&x, &tris, &layers);
        assert!(cancel.iter().map(|f| f.norm()).sum::<f64>() > 1e-3);
        let mut net = cancel.clone();
        add_spring_force(&x, &x, &tris, 2.0, &mut net);
        assert!(net.iter().all(|f| f.norm() < 1e-12));
        // moving the wing 2 by δ along z: f_j = −λ α_j α_2 δ ẑ
        let delta = 1e-3;
        let mut moved = x.clone();
        moved[2].z += delta;
        let mut f = cancel;
        add_spring_force(&x, &moved, &tris, 2.0, &mut f);
        let sp = spring([2, 3, 0, 1], &x, 2.0).unwrap();
        for (j, &node) in sp.nodes.iter().enumerate() {
            let want = -sp.lambda * sp.alpha[j] * sp.alpha[0] * delta;
            assert!((f[node as usize].z - want).abs() < 1e-12, "node {node}");
        }
    }

    #[test]
    fn layers_stack_to_each_triangles_rigidity() {
        let rigidity = [2.0, 5.0, 0.0, 5.0, 2.0];
        let layers = layers(&rigidity);
        assert_eq!(layers.len(), 2);
        for (t, &d) in rigidity.iter().enumerate() {
            let s: f64 = layers
                .iter()
                .filter(|l| l.triangles.contains(&t))
                .map(|l| l.stiffness)
                .sum();
            assert!(
                (s - STIFFNESS_PER_RIGIDITY * d).abs() < 1e-12,
                "triangle {t}"
            );
        }
    }
}
