//! Groups of regions kept apart: no lattice node may carry tets of two such groups.
//!
//! Why: two structures that the domain keeps apart (ossicles, which meet only through the
//! joint between them) can still come within a lattice cell of each other, and the centroid
//! rule then gives them a node, an edge or a face in common. Such a contact joins them where
//! the anatomy has none: a mechanical model bonds the two bones there, and a bone sharing a
//! node with another cannot be one rigid body. Whether it happens depends on where the
//! lattice falls, not on the anatomy. So wherever two groups meet at a node, the group with
//! fewer tets around it gives them up, to the most common region around the node that
//! belongs to no group (the joint between the two, where there is one) or else to the
//! outside; the repair runs again afterwards (`mesh_domain`), and the two alternate until no
//! node is shared.

use std::collections::BTreeMap;

use super::lattice::NodeTets;

/// The group of each label (indexed by label; none for a label of no group).
fn group_table(groups: &[Vec<u16>]) -> Vec<Option<usize>> {
    let size = groups
        .iter()
        .flatten()
        .max()
        .map_or(0, |&l| usize::from(l) + 1);
    let mut table = vec![None; size];
    for (g, labels) in groups.iter().enumerate() {
        for &l in labels {
            table[usize::from(l)] = Some(g);
        }
    }
    table
}

/// One pass over the nodes in order; returns the number of tets relabelled (0: no node
/// carries tets of two groups).
pub fn separate(adj: &NodeTets, n_nodes: usize, labels: &mut [u16], groups: &[Vec<u16>]) -> usize {
    let table = group_table(groups);
    let group_of = |label: u16| table.get(usize::from(label)).copied().flatten();
    let mut relabelled = 0;
    let mut counts = vec![0usize; groups.len()];
    for v in 0..n_nodes {
        let tets = adj.of(v);
        counts.iter_mut().for_each(|c| *c = 0);
        for &t in tets {
            if let Some(g) = group_of(labels[t as usize]) {
                counts[g] += 1;
            }
        }
        if counts.iter().filter(|&&c| c > 0).count() < 2 {
            continue;
        }
        // the group with most tets here keeps them (the first such group on a tie)
        let keep = counts
            .iter()
            .enumerate()
            .fold(0, |best, (g, &c)| if c > counts[best] { g } else { best });
        let mut others: BTreeMap<u16, usize> = BTreeMap::new();
        for &t in tets {
            let label = labels[t as usize];
            if label != 0 && group_of(label).is_none() {
                *others.entry(label).or_default() += 1;
            }
        }
        // the most common region of no group (the smallest label on a tie), else outside
        let to = others
            .iter()
            .fold(None, |best: Option<(u16, usize)>, (&l, &c)| match best {
                Some((_, bc)) if bc >= c => best,
                _ => Some((l, c)),
            })
            .map_or(0, |(l, _)| l);
        for &t in tets {
            let t = t as usize;
            if group_of(labels[t]).is_some_and(|g| g != keep) {
                labels[t] = to;
                relabelled += 1;
            }
        }
    }
    relabelled
}

/// The nodes that carry tets of two or more groups.
pub fn shared_nodes(adj: &NodeTets, n_nodes: usize, labels: &[u16], groups: &[Vec<u16>]) -> usize {
    let table = group_table(groups);
    let group_of = |label: u16| table.get(usize::from(label)).copied().flatten();
    (0..n_nodes)
        .filter(|&v| {
            let mut first = None;
            adj.of(v)
                .iter()
                .any(|&t| match group_of(labels[t as usize]) {
                    Some(g) if first.is_some_and(|f| f != g) => true,
                    Some(g) => {
                        first = Some(g);
                        false
                    }
                    None => false,
                })
        })
        .count()
}
