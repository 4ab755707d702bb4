//! Construction of the closest-point BVH: binned surface-area heuristic (Wald, "On fast
//! construction of SAH-based bounding volume hierarchies", IEEE RT 2007) with 16 bins and
//! leaves of at most 4 triangles; below depth 40 median splits take over, which bounds the
//! depth by 40 + log₂(n) < the query stack. Subtrees of at least `PARALLEL_BUILD` triangles
//! build their halves in parallel (rayon) and are spliced into one node list in which the
//! children of an interior node are adjacent.

use rayon::prelude::*;

use super::Node;
use crate::mesh::TriMesh;

const LEAF_SIZE: usize = 4;
const BINS: usize = 16;
const MEDIAN_DEPTH: usize = 40;
/// Subtrees with at least this many triangles build their halves in parallel.
const PARALLEL_BUILD: usize = 4096;

fn half_area(lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
    let (x, y, z) = (hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    x * y + y * z + z * x
}

fn empty_box() -> Aabb {
    ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3])
}

fn grow(b: &mut Aabb, lo: &[f64; 3], hi: &[f64; 3]) {
    for k in 0..3 {
        b.0[k] = b.0[k].min(lo[k]);
        b.1[k] = b.1[k].max(hi[k]);
    }
}

/// A triangle while the tree is built: its box, centroid and input index, moved with the
/// partitions so that every pass reads memory in order.
#[derive(Debug, Clone, Copy)]
struct Item {
    lo: [f64; 3],
    hi: [f64; 3],
    centroid: [f64; 3],
    id: u32,
}

type Aabb = ([f64; 3], [f64; 3]);

/// Fills a node for `items` (triangle slots from `first`) and splits them in place: the node
/// as a leaf, and where the left part ends if it should be split.
fn node_and_split(items: &mut [Item], first: usize, depth: usize) -> (Node, Option<usize>) {
    let mut bounds = empty_box();
    let mut cbounds = empty_box();
    for it in items.iter() {
        grow(&mut bounds, &it.lo, &it.hi);
        grow(&mut cbounds, &it.centroid, &it.centroid);
    }
    let leaf = Node {
        lo: bounds.0,
        hi: bounds.1,
        first: first as u32,
        count: items.len() as u32,
    };
    if items.len() <= LEAF_SIZE {
        return (leaf, None);
    }
    let split = if depth < MEDIAN_DEPTH {
        sah_split(items, &cbounds)
    } else {
        None
    }
    .or_else(|| median_split(items, &cbounds)); // None: all centroids coincide, one leaf
    (leaf, split)
}

/// Builds the subtree of `items` sequentially into `nodes[index]` and after.
fn build_into(nodes: &mut Vec<Node>, index: usize, items: &mut [Item], first: usize, depth: usize) {
    let (leaf, split) = node_and_split(items, first, depth);
    nodes[index] = leaf;
    let Some(mid) = split else {
        return;
    };
    let left = nodes.len();
    nodes.push(leaf);
    nodes.push(leaf);
    nodes[index].first = left as u32;
    nodes[index].count = 0;
    let (l, r) = items.split_at_mut(mid);
    build_into(nodes, left, l, first, depth + 1);
    build_into(nodes, left + 1, r, first + mid, depth + 1);
}

/// Builds the subtree of `items` as its own node list (root first); large subtrees build
/// their two halves in parallel and splice them: `[root, left root, right root, left rest,
/// right rest]`, child indices shifted accordingly.
fn build_subtree(items: &mut [Item], first: usize, depth: usize) -> Vec<Node> {
    if items.len() < PARALLEL_BUILD {
        let mut nodes = Vec::with_capacity(items.len() / 2 + 1);
        nodes.push(Node {
            lo: [0.0; 3],
            hi: [0.0; 3],
            first: 0,
            count: 0,
        });
        build_into(&mut nodes, 0, items, first, depth);
        return nodes;
    }
    let (mut root, split) = node_and_split(items, first, depth);
    let Some(mid) = split else {
        return vec![root];
    };
    let (l, r) = items.split_at_mut(mid);
    let (left, right) = rayon::join(
        || build_subtree(l, first, depth + 1),
        || build_subtree(r, first + mid, depth + 1),
    );
    let shift = |node: &Node, by: usize| {
        let mut n = *node;
        if n.count == 0 {
            n.first += by as u32;
        }
        n
    };
    let (left_by, right_by) = (2, left.len() + 1);
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    root.first = 1;
    root.count = 0;
    nodes.push(root);
    nodes.push(shift(&left[0], left_by));
    nodes.push(shift(&right[0], right_by));
    nodes.extend(left[1..].iter().map(|n| shift(n, left_by)));
    nodes.extend(right[1..].iter().map(|n| shift(n, right_by)));
    nodes
}

/// Binned SAH: the best of 3·(BINS−1) candidate planes, binned in one pass over the items;
/// `None` if no plane separates them.
fn sah_split(items: &mut [Item], cb: &Aabb) -> Option<usize> {
    let scale: [f64; 3] = std::array::from_fn(|k| {
        let extent = cb.1[k] - cb.0[k];
        if extent > 0.0 {
            BINS as f64 / extent
        } else {
            0.0
        }
    });
    let bin = |c: f64, k: usize| (((c - cb.0[k]) * scale[k]) as usize).min(BINS - 1);
    let mut counts = [[0usize; BINS]; 3];
    let mut bins = [[empty_box(); BINS]; 3];
    for it in items.iter() {
        for k in 0..3 {
            let b = bin(it.centroid[k], k);
            counts[k][b] += 1;
            grow(&mut bins[k][b], &it.lo, &it.hi);
        }
    }
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins on the left)
    for k in (0..3).filter(|&k| scale[k] > 0.0) {
        let mut right_cost = [0.0; BINS];
        let (mut acc, mut n) = (empty_box(), 0);
        for b in (1..BINS).rev() {
            grow(&mut acc, &bins[k][b].0, &bins[k][b].1);
            n += counts[k][b];
            right_cost[b] = half_area(&acc.0, &acc.1) * n as f64;
        }
        let (mut acc, mut n) = (empty_box(), 0);
        for b in 0..BINS - 1 {
            grow(&mut acc, &bins[k][b].0, &bins[k][b].1);
            n += counts[k][b];
            if n == 0 || n == items.len() {
                continue;
            }
            let cost = half_area(&acc.0, &acc.1) * n as f64 + right_cost[b + 1];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, k, b + 1));
            }
        }
    }
    let (_, k, left_bins) = best?;
    let mut mid = 0;
    for i in 0..items.len() {
        if bin(items[i].centroid[k], k) < left_bins {
            items.swap(i, mid);
            mid += 1;
        }
    }
    Some(mid)
}

/// Halves the items by centroid along the longest centroid extent.
fn median_split(items: &mut [Item], cb: &Aabb) -> Option<usize> {
    let axis = (0..3)
        .max_by(|&a, &b| (cb.1[a] - cb.0[a]).total_cmp(&(cb.1[b] - cb.0[b])))
        .unwrap_or(0);
    if cb.1[axis] - cb.0[axis] <= 0.0 {
        return None;
    }
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]));
    Some(mid)
}

/// The tree over `mesh` (indices valid) and the input triangle index of every leaf slot.
pub(super) fn build(mesh: &TriMesh) -> (Vec<Node>, Vec<u32>) {
    let mut items: Vec<Item> = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| {
            let mut b = empty_box();
            for p in &mesh.corners(t) {
                let q = [p.x, p.y, p.z];
                grow(&mut b, &q, &q);
            }
            let m = mesh.triangle_centroid(t);
            Item {
                lo: b.0,
                hi: b.1,
                centroid: [m.x, m.y, m.z],
                id: t as u32,
            }
        })
        .collect();
    let nodes = build_subtree(&mut items, 0, 0);
    (nodes, items.iter().map(|it| it.id).collect())
}
