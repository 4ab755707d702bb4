//! Assigns each lattice tet a region: the domain's label at the tet's centroid, except that a
//! region declared thin wins the tet when it owns any of five sample points (the centroid and
//! the four points halfway from it to the corners). That keeps structures thinner than two
//! lattice cells (ligaments, stapes crura) from breaking up; the mesher's documentation gives
//! the resulting minimum feature sizes.
//!
//! Shortcut: labels and signed distances are first sampled at the lattice nodes. A node whose
//! distance to every region boundary exceeds the longest lattice edge `h` has a ball of radius
//! `h` of one label around it (signed distances are 1-Lipschitz and sign-correct by the
//! `LabelledDomain` contract, so they never overestimate), and that ball holds every incident
//! tet; such tets take the node's label without further queries. Only tets near an interface
//! are sampled, which gives the same labels at a fraction of the queries.

use nalgebra::Point3;
use rayon::prelude::*;

use super::lattice::Lattice;
use crate::mesh::LabelledDomain;

/// Per node: its label, and whether a ball of radius `h` around it has that label throughout.
fn node_labels<D: LabelledDomain + ?Sized>(domain: &D, lattice: &Lattice) -> Vec<(u16, bool)> {
    let clearance = lattice.spacing;
    lattice
        .nodes
        .par_iter()
        .zip(lattice.on_shell.par_iter())
        .map(|(p, &shell)| {
            if shell {
                return (0, false);
            }
            let label = domain.label(p);
            let clear = if label == 0 {
                (1..=domain.region_count()).all(|r| domain.signed_distance(r, p) > clearance)
            } else {
                domain.signed_distance(label, p) < -clearance
            };
            (label, clear)
        })
        .collect()
}

/// One label per lattice tet; tets touching the lattice's outer shell are always 0.
pub fn label_tets<D: LabelledDomain + ?Sized>(
    domain: &D,
    lattice: &Lattice,
    thin: &[u16],
) -> Vec<u16> {
    let nodes = node_labels(domain, lattice);
    lattice
        .tets
        .par_iter()
        .map(|t| {
            if t.iter().any(|&v| lattice.on_shell[v as usize]) {
                return 0;
            }
            if let Some(&v) = t.iter().find(|&&v| nodes[v as usize].1) {
                return nodes[v as usize].0;
            }
            let p = t.map(|v| lattice.nodes[v as usize].coords);
            let centroid = (p[0] + p[1] + p[2] + p[3]) / 4.0;
            let at_centre = domain.label(&Point3::from(centroid));
            if thin.is_empty() || thin.contains(&at_centre) {
                return at_centre;
            }
            p.iter()
                .map(|corner| domain.label(&Point3::from((centroid + corner) / 2.0)))
                .find(|l| thin.contains(l))
                .unwrap_or(at_centre)
        })
        .collect()
}
