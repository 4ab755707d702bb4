//! Moves the lattice nodes that lie on a region boundary onto the true interface, so region
//! surfaces follow the domain instead of the lattice's staircase.
//!
//! Interface functions: with `φ_r` the signed distance of region `r` and
//! `φ_0 = −min_r φ_r` (outside every region), the interface between regions `a` and `b` is the
//! zero set of `f_ab = (φ_a − φ_b) / 2`. A node whose incident tets carry labels
//! `{a, b}` is projected onto `f_ab = 0` by Newton steps `p ← p − f ∇f / |∇f|²` (central
//! differences); a node where three or more labels meet is projected alternately onto
//! `f_ab = 0` and `f_ac = 0`, which converges to the junction curve.
//!
//! Moves are guarded (Gauss–Seidel, in node order, so deterministic): a node moves the full
//! way, or half, or a quarter, whichever is the longest that keeps every incident kept tet at a
//! dihedral angle ≥ the minimum; otherwise it stays. Later sweeps retry the remaining ones.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::MesherParams;
use super::lattice::NodeTets;
use crate::mesh::LabelledDomain;
use crate::mesh::quality::dihedral_range;
use crate::mesh::tet::signed_volume;

/// Result of snapping.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SnapOutcome {
    /// Nodes on a region boundary (incident tets with two or more labels, 0 included).
    pub boundary_nodes: usize,
    /// Boundary nodes that reached the interface.
    pub snapped: usize,
    /// Boundary nodes moved part of the way only, or not at all.
    pub held_back: usize,
    /// Mean and largest distance (mm) from a boundary node to its interface target after
    /// snapping.
    pub mean_offset: f64,
    pub max_offset: f64,
}

/// `φ_label(p)`: signed distance of a region, or of the outside for label 0.
fn phi<D: LabelledDomain + ?Sized>(domain: &D, label: u16, p: &Point3<f64>) -> f64 {
    if label == 0 {
        -(1..=domain.region_count())
            .map(|r| domain.signed_distance(r, p))
            .fold(f64::INFINITY, f64::min)
    } else {
        domain.signed_distance(label, p)
    }
}

/// One Newton projection onto `f_ab = 0` (a few steps); `None` if the gradient vanishes.
fn project_pair<D: LabelledDomain + ?Sized>(
    domain: &D,
    a: u16,
    b: u16,
    mut p: Point3<f64>,
    h: f64,
) -> Option<Point3<f64>> {
    let f = |q: &Point3<f64>| 0.5 * (phi(domain, a, q) - phi(domain, b, q));
    let delta = 1e-4 * h;
    for _ in 0..8 {
        let value = f(&p);
        if value.abs() < 1e-7 * h {
            break;
        }
        let mut grad = Vector3::zeros();
        for axis in 0..3 {
            let mut e = Vector3::zeros();
            e[axis] = delta;
            grad[axis] = (f(&(p + e)) - f(&(p - e))) / (2.0 * delta);
        }
        let g2 = grad.norm_squared();
        if g2 < 1e-12 {
            return None;
        }
        let step = grad * (value / g2);
        // Distances are (near) 1-Lipschitz: no step needs to exceed a lattice cell.
        p -= if step.norm() > h {
            step * (h / step.norm())
        } else {
            step
        };
    }
    Some(p)
}

/// Interface target of a node whose incident tets carry `labels` (sorted, distinct, ≥ 2).
fn target<D: LabelledDomain + ?Sized>(
    domain: &D,
    labels: &[u16],
    p: Point3<f64>,
    h: f64,
) -> Option<Point3<f64>> {
    let (a, rest) = labels.split_first()?;
    if rest.len() == 1 {
        return project_pair(domain, *a, rest[0], p, h);
    }
    let mut q = p;
    for _ in 0..6 {
        for &b in rest.iter().take(2) {
            q = project_pair(domain, *a, b, q, h)?;
        }
    }
    Some(q)
}

/// Smallest dihedral angle (radians) of the kept tets at `v` if it sat at `at`; negative or
/// zero volume counts as 0.
fn worst_angle_at(
    v: u32,
    at: &Point3<f64>,
    nodes: &[Point3<f64>],
    tets: &[[u32; 4]],
    labels: &[u16],
    incident: &[u32],
    min_edge: f64,
) -> f64 {
    let mut worst = f64::INFINITY;
    for &t in incident.iter().filter(|&&t| labels[t as usize] != 0) {
        let p = tets[t as usize].map(|n| if n == v { *at } else { nodes[n as usize] });
        if signed_volume(&p[0], &p[1], &p[2], &p[3]) <= 0.0 {
            return 0.0;
        }
        // a tiny tet among normal ones is well shaped but fragile: a small difference in its
        // nodes' motion inverts it
        let short = tets[t as usize]
            .iter()
            .filter(|&&n| n != v)
            .any(|&n| (nodes[n as usize] - at).norm() < min_edge);
        if short {
            return 0.0;
        }
        worst = worst.min(dihedral_range(&p).0);
    }
    worst
}

/// No snapped edge gets shorter than this fraction of the lattice spacing.
const MIN_EDGE_FRACTION: f64 = 0.2;

/// Nodes on a region boundary (incident tets with two or more labels, 0 included, at least
/// one non-zero) with their interface targets (`None` where the projection failed).
pub struct Targets {
    pub nodes: Vec<u32>,
    pub goals: Vec<Option<Point3<f64>>>,
}

/// Finds the boundary nodes and projects them onto their interfaces (in parallel; the result
/// does not depend on the thread count).
pub fn interface_targets<D: LabelledDomain + ?Sized>(
    domain: &D,
    nodes: &[Point3<f64>],
    labels: &[u16],
    adj: &NodeTets,
    h: f64,
) -> Targets {
    let boundary: Vec<(u32, Vec<u16>)> = (0..nodes.len())
        .filter_map(|v| {
            let incident = adj.of(v);
            let mut set: Vec<u16> = incident.iter().map(|&t| labels[t as usize]).collect();
            set.sort_unstable();
            set.dedup();
            (set.len() >= 2 && set.iter().any(|&l| l != 0)).then_some((v as u32, set))
        })
        .collect();
    let goals = boundary
        .par_iter()
        .map(|(v, set)| {
            let p = nodes[*v as usize];
            target(domain, set, p, h).filter(|q| (q - p).norm() <= 1.5 * h)
        })
        .collect();
    Targets {
        nodes: boundary.into_iter().map(|(v, _)| v).collect(),
        goals,
    }
}

/// Moves the boundary nodes toward their `targets`, in place, under the dihedral guard.
pub fn snap_to_interfaces(
    nodes: &mut [Point3<f64>],
    tets: &[[u32; 4]],
    labels: &[u16],
    adj: &NodeTets,
    targets: &Targets,
    h: f64,
    params: &MesherParams,
) -> SnapOutcome {
    let (boundary, targets) = (&targets.nodes, &targets.goals);
    let min_angle = params.min_dihedral_deg.to_radians();
    let mut done = vec![false; boundary.len()];
    for _ in 0..params.snap_sweeps {
        let mut moved_any = false;
        for (i, v) in boundary.iter().enumerate() {
            let Some(goal) = targets[i] else { continue };
            if done[i] {
                continue;
            }
            let from = nodes[*v as usize];
            for fraction in [1.0, 0.5, 0.25] {
                let at = from + (goal - from) * fraction;
                let min_edge = MIN_EDGE_FRACTION * h;
                let worst =
                    worst_angle_at(*v, &at, nodes, tets, labels, adj.of(*v as usize), min_edge);
                if worst >= min_angle {
                    nodes[*v as usize] = at;
                    moved_any = true;
                    done[i] = fraction == 1.0;
                    break;
                }
            }
        }
        if !moved_any {
            break;
        }
    }

    let mut out = SnapOutcome {
        boundary_nodes: boundary.len(),
        ..SnapOutcome::default()
    };
    let mut sum = 0.0;
    for (i, v) in boundary.iter().enumerate() {
        let offset = targets[i].map_or(h, |goal| (goal - nodes[*v as usize]).norm());
        if done[i] {
            out.snapped += 1;
        }
        sum += offset;
        out.max_offset = out.max_offset.max(offset);
    }
    out.held_back = out.boundary_nodes - out.snapped;
    out.mean_offset = if boundary.is_empty() {
        0.0
    } else {
        sum / boundary.len() as f64
    };
    out
}
