//! Cavities below the lattice's resolution, found by face connectivity: outside (label 0)
//! tets that the outside cannot reach from the lattice's shell, in pieces of at most a star's
//! worth of tets. Such a void is no feature of the domain (it is smaller than one lattice
//! cell) but a by-product of labelling and repair, and it gives the whole mesh's boundary an
//! inner component. Each takes the most frequent label across its faces (ties: the
//! smallest). Larger voids are kept: they may be real.
//!
//! Small pieces of a region are not merged: in the default anatomy, at 0.34-0.35 mm edges,
//! the manubrium's tip is such a piece (joined to the handle only through the tensor tympani
//! tendon), which is why the default atlas is meshed at 0.33 mm.

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

/// Fills the small cavities; returns the number of tets relabelled.
///
/// A cavity touches labelled tets, so only outside tets with a node on a labelled tet start a
/// search; each search stops once its piece exceeds [`MAX_CAVITY_TETS`] or reaches the shell,
/// and marks what it saw as open, so every tet is searched a bounded number of times.
pub fn fill_cavities(lattice: &Lattice, adj: &NodeTets, labels: &mut [u16]) -> usize {
    let tets = &lattice.tets;
    let mut near_material = vec![false; lattice.nodes.len()];
    for (t, tet) in tets.iter().enumerate() {
        if labels[t] != 0 {
            for &v in tet {
                near_material[v as usize] = true;
            }
        }
    }
    // 0: unseen, 1: open (part of a large or shell-reaching piece), 2: in the current piece
    let mut state = vec![0u8; tets.len()];
    let mut piece: Vec<usize> = Vec::with_capacity(MAX_CAVITY_TETS + 1);
    let mut around: Vec<u16> = Vec::new();
    let mut filled = 0;
    for seed in 0..tets.len() {
        if labels[seed] != 0
            || state[seed] != 0
            || !tets[seed].iter().any(|&v| near_material[v as usize])
        {
            continue;
        }
        piece.clear();
        around.clear();
        piece.push(seed);
        state[seed] = 2;
        let mut open = false;
        let mut k = 0;
        while k < piece.len() && !open {
            let t = piece[k];
            open = tets[t].iter().any(|&v| lattice.on_shell[v as usize]);
            for o in face_neighbours(t, tets, adj) {
                if labels[o] != 0 {
                    around.push(labels[o]);
                } else if state[o] == 1 {
                    open = true;
                } else if state[o] == 0 {
                    state[o] = 2;
                    piece.push(o);
                }
            }
            open |= piece.len() > MAX_CAVITY_TETS;
            k += 1;
        }
        if open {
            for &t in &piece {
                state[t] = 1;
            }
            continue;
        }
        around.sort_unstable();
        let mut best = (0usize, 0u16);
        for run in around.chunk_by(|a, b| a == b) {
            if run.len() > best.0 {
                best = (run.len(), run[0]);
            }
        }
        for &t in &piece {
            labels[t] = best.1;
            state[t] = 1;
        }
        filled += piece.len();
    }
    filled
}
