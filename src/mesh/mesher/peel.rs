//! Peels flat caps before snapping. A kept tet whose four nodes all lie on region boundaries
//! and that touches the outside would, once its nodes reach the interface, lie flat on the
//! surface: it would block snapping (the dihedral guard refuses the moves) and leave the
//! surface a staircase. Such a tet holds almost no volume after snapping, so it is handed to
//! the outside (label 0) instead; isosurface stuffing reaches the same end by cutting.
//! Thin regions are never peeled (their tets are all boundary tets by design).

use nalgebra::Point3;

use super::lattice::NodeTets;
use super::snap::Targets;
use crate::mesh::quality::dihedral_range;
use crate::mesh::tet::{TET_FACES, signed_volume};

/// True when another tet with label 0 shares face `face` of tet `t`.
fn faces_outside(t: usize, face: [u32; 3], adj: &NodeTets, labels: &[u16]) -> bool {
    adj.of(face[0] as usize).iter().any(|&o| {
        o as usize != t
            && labels[o as usize] == 0
            && adj.of(face[1] as usize).contains(&o)
            && adj.of(face[2] as usize).contains(&o)
    })
}

/// Relabels to 0 every kept tet that would be flatter than `min_dihedral_deg` with all its
/// nodes at their targets and that shares a face with the outside; returns how many.
pub fn peel_flat_caps(
    nodes: &[Point3<f64>],
    tets: &[[u32; 4]],
    labels: &mut [u16],
    adj: &NodeTets,
    targets: &Targets,
    min_dihedral_deg: f64,
    thin: &[u16],
) -> usize {
    let mut goal: Vec<Option<Point3<f64>>> = vec![None; nodes.len()];
    let mut on_boundary = vec![false; nodes.len()];
    for (&v, g) in targets.nodes.iter().zip(&targets.goals) {
        on_boundary[v as usize] = true;
        goal[v as usize] = *g;
    }
    let min_angle = min_dihedral_deg.to_radians();
    let mut peeled = 0;
    for (t, tet) in tets.iter().enumerate() {
        let r = labels[t];
        if r == 0 || thin.contains(&r) || !tet.iter().all(|&v| on_boundary[v as usize]) {
            continue;
        }
        let p = tet.map(|v| goal[v as usize].unwrap_or(nodes[v as usize]));
        let flat =
            signed_volume(&p[0], &p[1], &p[2], &p[3]) <= 0.0 || dihedral_range(&p).0 < min_angle;
        if flat
            && TET_FACES
                .iter()
                .any(|f| faces_outside(t, f.map(|i| tet[i]), adj, labels))
        {
            labels[t] = 0;
            peeled += 1;
        }
    }
    peeled
}
