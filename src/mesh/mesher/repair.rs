//! Makes every region's boundary a 2-manifold by relabelling lattice tets.
//!
//! Criterion (per vertex `v` and region `r`): on the link sphere of `v` (the faces of its star
//! opposite `v`), the `r` triangles and the other triangles must each form one edge-connected
//! piece, and around every edge `vw` the ring of tets may switch between `r` and not-`r` at
//! most twice. Then the `r` part of the link is a disk and `r`'s boundary is a manifold
//! surface at `v` (no pinched vertex, no edge shared by four boundary faces).
//!
//! A defect is fixed locally and deterministically: a pinched edge ring is filled with `r` when
//! `r` has the majority there (or is a thin region), else carved to the dominant other label;
//! a split `r` keeps its largest piece (thin regions fill the star instead); a split
//! complement is filled with `r`. Sweeps in node order repeat until nothing changes.
//!
//! Groups (unions of regions, e.g. the regions of one bone, or all regions: the whole domain)
//! get the same criterion with `inside` = "label in the group", so that two regions of a
//! group touching along an edge or at a vertex only do not leave the union's boundary
//! non-manifold. A group defect is always fixed by adding to the group (the ring, the star or
//! the smaller complement pieces take the group's most frequent label there), never by
//! carving it, so thin structures are not cut.

use super::lattice::{Lattice, NodeTets};

/// Largest star handled (BCC interior stars have 24 tets).
const MAX_STAR: usize = 32;

/// What the repair did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RepairOutcome {
    pub relabelled: usize,
    pub sweeps: usize,
    /// (vertex, region) pairs still non-manifold after the last sweep (0 on success).
    pub defects_left: usize,
    /// Outside tets of small enclosed voids given a label (`cavity`).
    pub cavities_filled: usize,
    /// Tets taken from a group of regions that shared a node with another group
    /// (`MesherParams::apart_groups`, `separate`).
    pub separated: usize,
    /// Nodes still shared by two apart groups after the last round (0 on success).
    pub shared_nodes_left: usize,
}

impl RepairOutcome {
    /// Adds a later repair of the same labels: its counts summed, its defects the ones left.
    pub fn absorb(&mut self, later: RepairOutcome) {
        self.relabelled += later.relabelled;
        self.sweeps += later.sweeps;
        self.cavities_filled += later.cavities_filled;
        self.defects_left = later.defects_left;
    }
}

enum Defect {
    None,
    /// Ring around edge `v`–`w` switches more than twice.
    Edge(u32),
    SplitRegion,
    SplitComplement,
}

/// Fixed-size union-find over star positions.
struct Components {
    parent: [u8; MAX_STAR],
}

impl Components {
    fn new(n: usize) -> Self {
        let mut parent = [0u8; MAX_STAR];
        for (i, p) in parent.iter_mut().enumerate().take(n) {
            *p = i as u8;
        }
        Self { parent }
    }
    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] as usize != i {
            i = self.parent[i] as usize;
        }
        i
    }
    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        self.parent[ra.max(rb)] = ra.min(rb) as u8;
    }
}

/// The star of one vertex with its link adjacency.
struct Star<'a> {
    v: u32,
    tets: &'a [u32],
    corners: [[u32; 4]; MAX_STAR],
    /// Pairs of star positions sharing a face that contains `v`.
    adjacent: [(u8, u8); MAX_STAR * 3],
    n_adjacent: usize,
}

impl<'a> Star<'a> {
    fn new(v: u32, tets: &'a [u32], all: &[[u32; 4]]) -> Self {
        let mut star = Star {
            v,
            tets,
            corners: [[0; 4]; MAX_STAR],
            adjacent: [(0, 0); MAX_STAR * 3],
            n_adjacent: 0,
        };
        for (i, &t) in tets.iter().enumerate() {
            star.corners[i] = all[t as usize];
        }
        for i in 0..tets.len() {
            for j in i + 1..tets.len() {
                let shared = star.corners[i]
                    .iter()
                    .filter(|n| star.corners[j].contains(n))
                    .count();
                if shared == 3 && star.n_adjacent < star.adjacent.len() {
                    star.adjacent[star.n_adjacent] = (i as u8, j as u8);
                    star.n_adjacent += 1;
                }
            }
        }
        star
    }

    fn pairs(&self) -> &[(u8, u8)] {
        &self.adjacent[..self.n_adjacent]
    }

    /// Components of the positions where `inside(i) == class`, with the largest one's root.
    fn components(&self, inside: &[bool], class: bool) -> (Components, usize, usize) {
        let n = self.tets.len();
        let mut uf = Components::new(n);
        for &(i, j) in self.pairs() {
            let (i, j) = (i as usize, j as usize);
            if inside[i] == class && inside[j] == class {
                uf.union(i, j);
            }
        }
        let mut size = [0usize; MAX_STAR];
        for i in (0..n).filter(|&i| inside[i] == class) {
            let root = uf.find(i);
            size[root] += 1;
        }
        let count = size[..n].iter().filter(|&&s| s > 0).count();
        // Largest component; ties go to the lowest root.
        let largest = (0..n).fold(0, |best, i| if size[i] > size[best] { i } else { best });
        (uf, count, largest)
    }

    fn defect(&self, inside: &[bool]) -> Defect {
        let n = self.tets.len();
        // Edge rings: neighbours w of v in ascending order of first appearance.
        for i in 0..n {
            for &w in &self.corners[i] {
                if w == self.v || (0..i).any(|k| self.corners[k].contains(&w)) {
                    continue;
                }
                let switches = self
                    .pairs()
                    .iter()
                    .filter(|&&(a, b)| {
                        let (a, b) = (a as usize, b as usize);
                        inside[a] != inside[b]
                            && self.corners[a].contains(&w)
                            && self.corners[b].contains(&w)
                    })
                    .count();
                if switches > 2 {
                    return Defect::Edge(w);
                }
            }
        }
        if self.components(inside, true).1 > 1 {
            return Defect::SplitRegion;
        }
        if self.components(inside, false).1 > 1 {
            return Defect::SplitComplement;
        }
        Defect::None
    }
}

/// The most frequent label other than `r` among `tets` (ties: the smallest label).
fn dominant_other(tets: impl Iterator<Item = u32>, labels: &[u16], r: u16) -> u16 {
    let mut seen: [(u16, u32); MAX_STAR] = [(0, 0); MAX_STAR];
    let mut n = 0;
    for t in tets {
        let l = labels[t as usize];
        if l == r {
            continue;
        }
        match seen[..n].iter_mut().find(|(x, _)| *x == l) {
            Some(e) => e.1 += 1,
            None if n < MAX_STAR => {
                seen[n] = (l, 1);
                n += 1;
            }
            None => {}
        }
    }
    seen[..n]
        .iter()
        .fold(None, |best: Option<(u16, u32)>, &(l, c)| match best {
            Some((bl, bc)) if bc > c || (bc == c && bl < l) => Some((bl, bc)),
            _ => Some((l, c)),
        })
        .map_or(0, |(l, _)| l)
}

/// Fixes one defect of region `r` at the star; returns the number of tets relabelled.
fn fix(
    star: &Star,
    inside: &[bool],
    defect: Defect,
    r: u16,
    thin: bool,
    labels: &mut [u16],
) -> usize {
    let n = star.tets.len();
    let set = |positions: &mut dyn Iterator<Item = usize>, label: u16, labels: &mut [u16]| {
        relabel(star, positions, label, labels)
    };
    match defect {
        Defect::None => 0,
        Defect::Edge(w) => {
            let ring = || (0..n).filter(move |&i| star.corners[i].contains(&w));
            let in_r = ring().filter(|&i| inside[i]).count();
            if thin || 2 * in_r >= ring().count() {
                set(&mut ring().filter(|&i| !inside[i]), r, labels)
            } else {
                let other = dominant_other(ring().map(|i| star.tets[i]), labels, r);
                set(&mut ring().filter(|&i| inside[i]), other, labels)
            }
        }
        Defect::SplitRegion if thin => set(&mut (0..n).filter(|&i| !inside[i]), r, labels),
        Defect::SplitRegion => {
            let (mut uf, _, largest) = star.components(inside, true);
            let other = dominant_other(star.tets.iter().copied(), labels, r);
            set(
                &mut (0..n).filter(|&i| inside[i] && uf.find(i) != largest),
                other,
                labels,
            )
        }
        Defect::SplitComplement => {
            let (mut uf, _, largest) = star.components(inside, false);
            set(
                &mut (0..n).filter(|&i| !inside[i] && uf.find(i) != largest),
                r,
                labels,
            )
        }
    }
}

/// The most frequent label of `group` among `tets` (ties: the smallest label).
fn dominant_in(tets: impl Iterator<Item = u32>, labels: &[u16], group: &[u16]) -> Option<u16> {
    let mut counts = [0u32; MAX_STAR];
    for t in tets {
        if let Some(k) = group.iter().position(|&g| g == labels[t as usize])
            && k < MAX_STAR
        {
            counts[k] += 1;
        }
    }
    (0..group.len().min(MAX_STAR))
        .filter(|&k| counts[k] > 0)
        .min_by_key(|&k| (std::cmp::Reverse(counts[k]), group[k]))
        .map(|k| group[k])
}

/// Fixes one defect of a group's union at the star by adding to the group; returns the
/// number of tets relabelled.
fn fix_group(
    star: &Star,
    inside: &[bool],
    defect: Defect,
    group: &[u16],
    labels: &mut [u16],
) -> usize {
    let n = star.tets.len();
    let fill: Vec<usize> = match defect {
        Defect::None => return 0,
        Defect::Edge(w) => (0..n)
            .filter(|&i| star.corners[i].contains(&w) && !inside[i])
            .collect(),
        Defect::SplitRegion => (0..n).filter(|&i| !inside[i]).collect(),
        Defect::SplitComplement => {
            let (mut uf, _, largest) = star.components(inside, false);
            (0..n)
                .filter(|&i| !inside[i] && uf.find(i) != largest)
                .collect()
        }
    };
    let from =
        |positions: &[usize]| dominant_in(positions.iter().map(|&i| star.tets[i]), labels, group);
    // the label the neighbourhood of the filled tets has most (else the star's)
    let near: Vec<usize> = (0..n)
        .filter(|&i| {
            inside[i]
                && fill.iter().any(|&f| {
                    star.corners[f]
                        .iter()
                        .filter(|c| star.corners[i].contains(c))
                        .count()
                        == 3
                })
        })
        .collect();
    let Some(label) = from(&near).or_else(|| from(&(0..n).collect::<Vec<_>>())) else {
        return 0;
    };
    relabel(star, &mut fill.into_iter(), label, labels)
}

/// Gives the star's tets at `positions` the label `label`; returns how many changed.
fn relabel(
    star: &Star,
    positions: &mut dyn Iterator<Item = usize>,
    label: u16,
    labels: &mut [u16],
) -> usize {
    let mut changed = 0;
    for i in positions {
        let t = star.tets[i] as usize;
        if labels[t] != label {
            labels[t] = label;
            changed += 1;
        }
    }
    changed
}

/// One sweep over all nodes; returns (tets relabelled, defects seen).
fn sweep(
    lattice: &Lattice,
    adj: &NodeTets,
    labels: &mut [u16],
    thin: &[u16],
    groups: &[Vec<u16>],
    apply: bool,
) -> (usize, usize) {
    let (mut changed, mut defects) = (0, 0);
    let mut inside = [false; MAX_STAR];
    for v in 0..lattice.nodes.len() {
        let tets = adj.of(v);
        if lattice.on_shell[v] || tets.len() > MAX_STAR {
            continue;
        }
        let first = labels[tets[0] as usize];
        if tets.iter().all(|&t| labels[t as usize] == first) {
            continue;
        }
        let star = Star::new(v as u32, tets, &lattice.tets);
        // Regions present, ascending, re-read after every fix.
        let mut r = 0u16;
        while let Some(next) = tets
            .iter()
            .map(|&t| labels[t as usize])
            .filter(|&l| l > r)
            .min()
        {
            r = next;
            for _ in 0..4 {
                for (i, &t) in tets.iter().enumerate() {
                    inside[i] = labels[t as usize] == r;
                }
                let defect = star.defect(&inside[..tets.len()]);
                if matches!(defect, Defect::None) {
                    break;
                }
                defects += 1;
                if !apply {
                    break;
                }
                changed += fix(
                    &star,
                    &inside[..tets.len()],
                    defect,
                    r,
                    thin.contains(&r),
                    labels,
                );
            }
        }
        for group in groups {
            for _ in 0..4 {
                for (i, &t) in tets.iter().enumerate() {
                    inside[i] = group.contains(&labels[t as usize]);
                }
                let defect = star.defect(&inside[..tets.len()]);
                if matches!(defect, Defect::None) {
                    break;
                }
                defects += 1;
                if !apply {
                    break;
                }
                changed += fix_group(&star, &inside[..tets.len()], defect, group, labels);
            }
        }
    }
    (changed, defects)
}

/// Relabels tets until every region and every group is manifold at every vertex, or
/// `max_sweeps` is reached.
pub fn make_manifold(
    lattice: &Lattice,
    adj: &NodeTets,
    labels: &mut [u16],
    thin: &[u16],
    groups: &[Vec<u16>],
    max_sweeps: usize,
) -> RepairOutcome {
    let mut out = RepairOutcome::default();
    while out.sweeps < max_sweeps {
        out.sweeps += 1;
        let (changed, _) = sweep(lattice, adj, labels, thin, groups, true);
        out.relabelled += changed;
        if changed == 0 {
            break;
        }
    }
    out.defects_left = sweep(lattice, adj, labels, thin, groups, false).1;
    out
}
