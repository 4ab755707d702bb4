//! Cavities below the lattice's resolution, found by face connectivity: outside (label 0)
//! tets that the outside cannot reach from the lattice's shell, in pieces of at most a star's
//! worth of tets. Such a void is no feature of the domain (it is smaller than one lattice
//! cell) but a by-product of labelling and repair, and it gives the whole mesh's boundary an
//! inner component. Each takes the most frequent label across its faces (ties: the
//! smallest). Larger voids are kept: they may be real.
//!
//! Small pieces of a region are not merged: in the default anatomy the manubrium's tip is
//! such a piece (joined to the handle only through the tensor tympani tendon at 0.35 mm).

use super::lattice::{Lattice, NodeTets};
use crate::mesh::tet::TET_FACES;

/// Largest enclosed void filled [tets]: one BCC star has 24 tets.
const MAX_CAVITY_TETS: usize = 32;

/// The tets sharing a face with tet `t`.
fn face_neighbours<'a>(
    t: usize,
    tets: &'a [[u32; 4]],
    adj: &'a NodeTets,
) -> impl Iterator<Item = usize> + 'a {
    TET_FACES.iter().filter_map(move |f| {
        let face = f.map(|k| tets[t][k]);
        adj.of(face[0] as usize)
            .iter()
            .map(|&o| o as usize)
            .find(|&o| {
                o != t
                    && adj.of(face[1] as usize).contains(&(o as u32))
                    && adj.of(face[2] as usize).contains(&(o as u32))
            })
    })
}

/// A face-connected piece of the outside and the most frequent label across its faces.
struct Piece {
    tets: Vec<usize>,
    neighbour: u16,
}

/// Every face-connected piece of the outside, in order of its first tet.
fn outside_pieces(tets: &[[u32; 4]], adj: &NodeTets, labels: &[u16]) -> Vec<Piece> {
    let mut seen = vec![false; tets.len()];
    let mut out = Vec::new();
    let mut around: Vec<u16> = Vec::new();
    for seed in 0..tets.len() {
        if seen[seed] || labels[seed] != 0 {
            continue;
        }
        seen[seed] = true;
        let mut piece = vec![seed];
        around.clear();
        let mut k = 0;
        while k < piece.len() {
            for o in face_neighbours(piece[k], tets, adj) {
                if labels[o] != 0 {
                    around.push(labels[o]);
                } else if !seen[o] {
                    seen[o] = true;
                    piece.push(o);
                }
            }
            k += 1;
        }
        around.sort_unstable();
        let mut best = (0usize, 0u16);
        for run in around.chunk_by(|a, b| a == b) {
            if run.len() > best.0 {
                best = (run.len(), run[0]);
            }
        }
        out.push(Piece {
            tets: piece,
            neighbour: best.1,
        });
    }
    out
}

/// Fills the small cavities; returns the number of tets relabelled.
pub fn fill_cavities(lattice: &Lattice, adj: &NodeTets, labels: &mut [u16]) -> usize {
    let mut changed = 0;
    for p in outside_pieces(&lattice.tets, adj, labels) {
        let open = p.tets.iter().any(|&t| {
            lattice.tets[t]
                .iter()
                .any(|&v| lattice.on_shell[v as usize])
        });
        if !open && p.tets.len() <= MAX_CAVITY_TETS {
            for &t in &p.tets {
                labels[t] = p.neighbour;
            }
            changed += p.tets.len();
        }
    }
    changed
}
