//! Assigns each lattice tet a region: the domain's label at the tet's centroid, except that a
//! region declared thin wins the tet when it owns any of five sample points (the centroid and
//! the four points halfway from it to the corners). That keeps structures thinner than two
//! lattice cells (ligaments, stapes crura) from breaking up; the mesher's documentation gives
//! the resulting minimum feature sizes.

use nalgebra::Point3;
use rayon::prelude::*;

use super::lattice::Lattice;
use crate::mesh::LabelledDomain;

/// One label per lattice tet; tets touching the lattice's outer shell are always 0.
pub fn label_tets<D: LabelledDomain + ?Sized>(
    domain: &D,
    lattice: &Lattice,
    thin: &[u16],
) -> Vec<u16> {
    lattice
        .tets
        .par_iter()
        .map(|t| {
            if t.iter().any(|&v| lattice.on_shell[v as usize]) {
                return 0;
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
