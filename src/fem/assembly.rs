//! Sparse assembly of the warped tangent K' = Σ R K_e Rᵀ (lower triangle, faer CSC), with the
//! pattern and every element's value slots computed once per mesh; each assembly re-scatters
//! values into the same buffer without allocation.
//!
//! Layout: DOF 3v+i is axis i of node v. Column 3B+j holds the diagonal-block rows 3B+j..3B+2
//! first, then the 3×3 blocks of the neighbours A > B in increasing A. An element pair (a, b)
//! therefore only needs the rank of the larger node among the smaller node's neighbours: entry
//! (3A+i, 3B+j) sits at col_ptr[3B+j] + (3−j) + 3·rank + i, and a diagonal-block entry
//! (3B+i, 3B+j), i ≥ j, at col_ptr[3B+j] + (i−j). The diagonal of DOF d is at col_ptr[d].
//! (This is what faer's `try_new_from_indices` + argsort would give, without its per-assembly
//! allocation of a new matrix.)

use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use nalgebra::{Matrix3, Point3, Vector3};

use super::bending::{BendingHinge, HingeVectors, TriangleBending};
use super::dashpot::{Dashpot, check_dashpots};
use super::element::CorotElement;
use super::error::FemError;
use super::fixed::FixedDofs;
use super::model::FemModel;
use super::state::{CorotationalState, ElementStates, check_positions};

/// The symbolic lower-triangular pattern of a model's tangent matrix and the value slots of
/// every element. Built once per mesh.
#[derive(Debug, Clone)]
pub struct SparsePattern {
    symbolic: SymbolicSparseColMat<usize>,
    tet_ranks: Vec<u32>,
    membrane_ranks: Vec<u32>,
    /// Per triangle of the bending (`Bending::triangles`), where its blocks go.
    bending: Vec<BendingLayout>,
}

/// The nodes a triangle's bending hinges span (at most six: its own three and the node
/// across each hinge), where each hinge's nodes [p, q, a, b] sit among them, and the rank of
/// each pair (u, v), v < u in `nodes` order, of the lower blocks.
#[derive(Debug, Clone)]
struct BendingLayout {
    nodes: [u32; 6],
    len: usize,
    slots: [[u8; 4]; 3],
    ranks: [u32; 15],
}

impl BendingLayout {
    /// The layout of `share`, its hinges' nodes from `hinges`; no ranks yet.
    fn new(share: &TriangleBending, hinges: &[BendingHinge]) -> Self {
        let mut layout = BendingLayout {
            nodes: [0; 6],
            len: 0,
            slots: [[0; 4]; 3],
            ranks: [0; 15],
        };
        for (k, h) in share.hinges.iter().enumerate() {
            let Some(h) = h else {
                continue;
            };
            for (a, &v) in hinges[*h as usize].nodes.iter().enumerate() {
                let slot = match layout.nodes[..layout.len].iter().position(|&u| u == v) {
                    Some(slot) => slot,
                    None => {
                        layout.nodes[layout.len] = v;
                        layout.len += 1;
                        layout.len - 1
                    }
                };
                layout.slots[k][a] = slot as u8;
            }
        }
        layout
    }

    /// The node pairs (u, v), v < u in `nodes` order, in the order of `ranks`.
    fn pairs(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (0..self.len).flat_map(move |u| (0..u).map(move |v| (self.nodes[u], self.nodes[v])))
    }
}

/// Local node pairs a < b of an N-node element, in a fixed order.
fn pairs<const N: usize>() -> impl Iterator<Item = (usize, usize)> {
    (0..N).flat_map(|a| (a + 1..N).map(move |b| (a, b)))
}

/// The node pairs (in `pairs` order) of every cell.
fn node_pairs<'a, const N: usize>(
    cells: impl Iterator<Item = &'a [u32; N]>,
) -> impl Iterator<Item = (u32, u32)> {
    cells.flat_map(|c| pairs::<N>().map(move |(a, b)| (c[a], c[b])))
}

impl SparsePattern {
    /// Builds the pattern of `model`: every node's diagonal block, plus one 3×3 block per pair
    /// of nodes sharing an element.
    pub fn new(model: &FemModel) -> Self {
        let n = model.node_count();
        let mut edges = Vec::new();
        let tet_pairs = || node_pairs(model.tets.iter().map(|e| &e.nodes));
        let membrane_pairs = || node_pairs(model.membranes.iter().map(|e| &e.nodes));
        let hinges = &model.bending.hinges;
        let mut bending: Vec<BendingLayout> = model
            .bending
            .triangles
            .iter()
            .map(|t| BendingLayout::new(t, hinges))
            .collect();
        edges.extend(
            tet_pairs()
                .chain(membrane_pairs())
                .chain(bending.iter().flat_map(BendingLayout::pairs))
                .map(|(p, q)| (p.min(q), p.max(q))),
        );
        edges.sort_unstable();
        edges.dedup();
        // Neighbours A > B of node B are edges[first[B]..first[B+1]] (sorted by A).
        let mut first = vec![0usize; n + 1];
        for &(lo, _) in &edges {
            first[lo as usize + 1] += 1;
        }
        for v in 0..n {
            first[v + 1] += first[v];
        }
        let mut col_ptr = Vec::with_capacity(3 * n + 1);
        let mut row_idx = Vec::with_capacity(6 * n + 9 * edges.len());
        col_ptr.push(0usize);
        for b in 0..n {
            for j in 0..3 {
                row_idx.extend(3 * b + j..3 * b + 3);
                for &(_, a) in &edges[first[b]..first[b + 1]] {
                    row_idx.extend(3 * a as usize..3 * a as usize + 3);
                }
                col_ptr.push(row_idx.len());
            }
        }
        let symbolic = SymbolicSparseColMat::new_checked(3 * n, 3 * n, col_ptr, None, row_idx);
        let rank = |p: u32, q: u32| -> u32 {
            let (lo, hi) = (p.min(q), p.max(q));
            let list = &edges[first[lo as usize]..first[lo as usize + 1]];
            // The edge was inserted above, so the search always succeeds.
            list.partition_point(|&(_, a)| a < hi) as u32
        };
        let ranks = |cell_pairs: &mut dyn Iterator<Item = (u32, u32)>| -> Vec<u32> {
            cell_pairs.map(|(p, q)| rank(p, q)).collect()
        };
        let tet_ranks = ranks(&mut tet_pairs());
        let membrane_ranks = ranks(&mut membrane_pairs());
        for layout in &mut bending {
            let pair_ranks: Vec<u32> = layout.pairs().map(|(p, q)| rank(p, q)).collect();
            layout.ranks[..pair_ranks.len()].copy_from_slice(&pair_ranks);
        }
        SparsePattern {
            symbolic,
            tet_ranks,
            membrane_ranks,
            bending,
        }
    }

    /// Number of DOFs (rows = columns).
    pub fn dof_count(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Number of stored (lower-triangle) entries.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// The symbolic pattern (lower triangle including the diagonal).
    pub fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.symbolic.as_ref()
    }

    /// A zeroed value buffer for this pattern.
    pub fn zero_values(&self) -> Vec<f64> {
        vec![0.0; self.nnz()]
    }

    /// A faer view of the lower-triangular matrix with `values` (length `nnz()`).
    pub fn matrix<'a>(&'a self, values: &'a [f64]) -> SparseColMatRef<'a, usize, f64> {
        SparseColMatRef::new(self.symbolic.as_ref(), values)
    }

    /// Assembles A = scale·K'(state) + diag(node_diagonal ⊗ I₃) into `values` (overwritten),
    /// with the fixed DOFs projected out (row and column zero, diagonal 1). `state` holds the
    /// element rotations of the configuration (see `CorotationalState::update`);
    /// `node_diagonal`, if given, has one value per node (e.g. spring stiffness in µN/mm or a
    /// scaled mass). `model` must be the model this pattern was built from.
    pub fn assemble(
        &self,
        model: &FemModel,
        state: &CorotationalState,
        scale: f64,
        node_diagonal: Option<&[f64]>,
        fixed: &FixedDofs,
        values: &mut [f64],
    ) -> Result<(), FemError> {
        let diag_len = node_diagonal.map_or(model.node_count(), <[f64]>::len);
        for (what, expected, found) in [
            ("value buffer", self.nnz(), values.len()),
            ("fixed DOF mask", self.dof_count(), fixed.len()),
            ("model DOFs", self.dof_count(), model.dof_count()),
            ("node diagonal", model.node_count(), diag_len),
            (
                "tetrahedron rank table",
                self.tet_ranks.len(),
                6 * model.tets.len(),
            ),
            (
                "membrane rank table",
                self.membrane_ranks.len(),
                3 * model.membranes.len(),
            ),
            (
                "bending triangle table",
                self.bending.len(),
                model.bending.triangles.len(),
            ),
        ] {
            if expected != found {
                return Err(FemError::LengthMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        state.check_model(model)?;
        values.fill(0.0);
        let col_ptr = self.symbolic.col_ptr();
        let mut sink = Sink {
            col_ptr,
            fixed,
            values,
        };
        scatter(&model.tets, &state.tets, &self.tet_ranks, scale, &mut sink);
        scatter(
            &model.membranes,
            &state.membranes,
            &self.membrane_ranks,
            scale,
            &mut sink,
        );
        let gradients = &state.hinges.gradients;
        for (share, layout) in model.bending.triangles.iter().zip(&self.bending) {
            add_bending(share, layout, gradients, scale, &mut sink);
        }
        if let Some(diag) = node_diagonal {
            for (v, &d) in diag.iter().enumerate() {
                for i in 0..3 {
                    sink.values[col_ptr[3 * v + i]] += d;
                }
            }
        }
        for (dof, &start) in col_ptr[..self.dof_count()].iter().enumerate() {
            if fixed.is_fixed(dof) {
                sink.values[start] = 1.0;
            }
        }
        Ok(())
    }
}

impl SparsePattern {
    /// Adds `scale` times the tensile stress stiffness of the membrane triangles at positions
    /// `x` (state already updated to `x`) to assembled `values` (fixed DOFs stay projected):
    /// the
    /// geometric term K_σ,ab = w·g_aᵀσ⁺g_b·I₃ that the warped tangent lacks, which carries a
    /// tensioned membrane's out-of-plane stiffness (Bonet & Wood, "Nonlinear continuum
    /// mechanics for finite element analysis", initial-stress matrix).
    pub fn add_membrane_stress_stiffness(
        &self,
        model: &FemModel,
        x: &[Point3<f64>],
        state: &CorotationalState,
        scale: f64,
        fixed: &FixedDofs,
        values: &mut [f64],
    ) -> Result<(), FemError> {
        state.check_model(model)?;
        check_positions(model, x)?;
        let mut sink = self.sink(fixed, values)?;
        for ((e, r), ranks) in model
            .membranes
            .iter()
            .zip(&state.membranes.rotations)
            .zip(self.membrane_ranks.chunks_exact(3))
        {
            let f = e.deformation(x);
            let mut pair = 0;
            e.tensile_stress_stiffness(r, &f, |a, b, k| {
                let blk = Matrix3::identity() * (k * scale);
                let (p, q) = (e.nodes[a] as usize, e.nodes[b] as usize);
                if a == b {
                    sink.add_diagonal(p, &blk);
                } else {
                    let rank = ranks[pair] as usize;
                    pair += 1;
                    sink.add_off_diagonal(p.max(q), p.min(q), rank, &blk);
                }
            });
        }
        Ok(())
    }
}

impl SparsePattern {
    /// Adds the blocks c n nᵀ of `dashpots` to assembled `values` (fixed DOFs stay
    /// projected); a caller wanting h·C passes dashpots with their coefficients times h.
    pub fn add_dashpots(
        &self,
        dashpots: &[Dashpot],
        fixed: &FixedDofs,
        values: &mut [f64],
    ) -> Result<(), FemError> {
        check_dashpots(dashpots, self.dof_count() / 3)?;
        let mut sink = self.sink(fixed, values)?;
        for d in dashpots {
            sink.add_diagonal(d.node as usize, &d.block());
        }
        Ok(())
    }
}

/// Destination of the scatter: the values, their column pointers and the fixed DOFs.
impl SparsePattern {
    /// A sink adding blocks to assembled `values` of this pattern, fixed DOFs projected;
    /// checks the lengths of `values` and `fixed`.
    fn sink<'a>(
        &'a self,
        fixed: &'a FixedDofs,
        values: &'a mut [f64],
    ) -> Result<Sink<'a>, FemError> {
        if values.len() != self.nnz() || fixed.len() != self.dof_count() {
            return Err(FemError::LengthMismatch {
                what: "value buffer or fixed DOF mask",
                expected: self.nnz(),
                found: values.len(),
            });
        }
        Ok(Sink {
            col_ptr: self.symbolic.col_ptr(),
            fixed,
            values,
        })
    }
}

struct Sink<'a> {
    col_ptr: &'a [usize],
    fixed: &'a FixedDofs,
    values: &'a mut [f64],
}

impl Sink<'_> {
    /// Adds block `k` (rows of node `hi`, columns of node `lo`, hi > lo) at neighbour `rank`.
    #[inline]
    fn add_off_diagonal(&mut self, hi: usize, lo: usize, rank: usize, k: &Matrix3<f64>) {
        if self.fixed.node_free(hi) && self.fixed.node_free(lo) {
            for j in 0..3 {
                let base = self.col_ptr[3 * lo + j] + (3 - j) + 3 * rank;
                for (v, kij) in self.values[base..base + 3]
                    .iter_mut()
                    .zip(k.column(j).iter())
                {
                    *v += kij;
                }
            }
            return;
        }
        for j in 0..3 {
            if self.fixed.is_fixed(3 * lo + j) {
                continue;
            }
            let base = self.col_ptr[3 * lo + j] + (3 - j) + 3 * rank;
            for i in 0..3 {
                if !self.fixed.is_fixed(3 * hi + i) {
                    self.values[base + i] += k[(i, j)];
                }
            }
        }
    }

    /// Adds the lower triangle of the diagonal block `k` of node `v`.
    #[inline]
    fn add_diagonal(&mut self, v: usize, k: &Matrix3<f64>) {
        for j in 0..3 {
            if self.fixed.is_fixed(3 * v + j) {
                continue;
            }
            let base = self.col_ptr[3 * v + j];
            for i in j..3 {
                if !self.fixed.is_fixed(3 * v + i) {
                    self.values[base + i - j] += k[(i, j)];
                }
            }
        }
    }
}

/// Adds a triangle's bending tangent Gᵀ k_t G (G the gradients of its hinges' angles at the
/// nodes of `layout`; the Gauss–Newton tangent of `fem::bending`), times `scale`.
fn add_bending(
    share: &TriangleBending,
    layout: &BendingLayout,
    gradients: &[HingeVectors],
    scale: f64,
    sink: &mut Sink<'_>,
) {
    let n = layout.len;
    let mut g = [[Vector3::zeros(); 6]; 3];
    for (k, h) in share.hinges.iter().enumerate() {
        if let Some(h) = h {
            for (a, grad) in gradients[*h as usize].iter().enumerate() {
                g[k][layout.slots[k][a] as usize] = *grad;
            }
        }
    }
    // w_k = Σ_l k_kl g_l, so that the block of nodes (u, v) is Σ_k g_k(u) w_k(v)ᵀ
    let k_t = share.stiffness * scale;
    let mut w = [[Vector3::zeros(); 6]; 3];
    for (k, wk) in w.iter_mut().enumerate() {
        for (v, wkv) in wk.iter_mut().enumerate().take(n) {
            *wkv = g[0][v] * k_t[(k, 0)] + g[1][v] * k_t[(k, 1)] + g[2][v] * k_t[(k, 2)];
        }
    }
    let block = |u: usize, v: usize| -> Matrix3<f64> {
        g[0][u] * w[0][v].transpose()
            + g[1][u] * w[1][v].transpose()
            + g[2][u] * w[2][v].transpose()
    };
    let mut pair = 0;
    for u in 0..n {
        let p = layout.nodes[u] as usize;
        sink.add_diagonal(p, &block(u, u));
        for v in 0..u {
            let q = layout.nodes[v] as usize;
            let rank = layout.ranks[pair] as usize;
            pair += 1;
            if p > q {
                sink.add_off_diagonal(p, q, rank, &block(u, v));
            } else {
                sink.add_off_diagonal(q, p, rank, &block(v, u));
            }
        }
    }
}

fn scatter<const N: usize>(
    elements: &[CorotElement<N>],
    states: &ElementStates<N>,
    ranks: &[u32],
    scale: f64,
    sink: &mut Sink<'_>,
) {
    let per = N * (N - 1) / 2;
    for ((e, r), ranks) in elements
        .iter()
        .zip(&states.rotations)
        .zip(ranks.chunks_exact(per))
    {
        let mut pair = 0;
        e.warped_blocks(r, |a, b, blk| {
            let blk = blk * scale;
            let (p, q) = (e.nodes[a] as usize, e.nodes[b] as usize);
            if a == b {
                sink.add_diagonal(p, &blk);
            } else {
                let rank = ranks[pair] as usize;
                pair += 1;
                if p > q {
                    sink.add_off_diagonal(p, q, rank, &blk);
                } else {
                    sink.add_off_diagonal(q, p, rank, &blk.transpose());
                }
            }
        });
    }
}
