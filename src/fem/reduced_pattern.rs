//! The lower pattern of a reduced matrix Tᵀ A T (`rigid::Reduction`, A symmetric over the full
//! DOFs) and where each product of A's lower entries with T's rows falls in it, built once per
//! model: every reduction of new values of A is then one pass over the products. The static
//! solver with rigid bodies reduces its tangent this way at every factorisation
//! (`rigid_statics`), the harmonic solver its stiffness once (`harmonic`).

use faer::sparse::{SparseColMat, SymbolicSparseColMat, SymbolicSparseColMatRef};

use super::rigid::Reduction;

/// The lower pattern of Tᵀ A T (the whole diagonal included) and the plan of its products.
#[derive(Debug, Clone)]
pub(crate) struct ReducedLower {
    pattern: SymbolicSparseColMat<usize>,
    /// For each product in the order `Reduction::lower_products` visits them: its slot in the
    /// values and how many times it counts (0 where its mirror is the lower entry, 2 where both
    /// are).
    plan: Vec<(usize, f64)>,
}

/// How many times the product at reduced (p, q) counts in the lower triangle: an entry on A's
/// diagonal visits both (p, q) and (q, p); an entry off it stands for itself and its mirror.
fn multiplicity(p: usize, q: usize, diagonal_entry: bool) -> f64 {
    match (diagonal_entry, p.cmp(&q)) {
        (true, std::cmp::Ordering::Less) => 0.0,
        (true, _) => 1.0,
        (false, std::cmp::Ordering::Equal) => 2.0,
        (false, _) => 1.0,
    }
}

impl ReducedLower {
    /// The reduced pattern of A's lower pattern `full` through `reduction`, holding also the
    /// reduced entries `extra` (row, column; either triangle).
    pub(crate) fn new(
        reduction: &Reduction,
        full: SymbolicSparseColMatRef<'_, usize>,
        extra: &[(usize, usize)],
    ) -> Self {
        let m = reduction.unknowns();
        // every product's lower slot, the whole diagonal and the extra entries
        let mut slots: Vec<(usize, usize)> = (0..m).map(|i| (i, i)).collect();
        reduction.lower_products(full, |_, p, _, q, _, diagonal| {
            if multiplicity(p, q, diagonal) > 0.0 {
                slots.push((p.min(q), p.max(q)));
            }
        });
        slots.extend(extra.iter().map(|&(r, c)| (r.min(c), r.max(c))));
        // the products arrive nearly in column order, which the sort is quick on
        slots.sort_unstable();
        slots.dedup();
        let mut col_ptr = vec![0usize; m + 1];
        for &(c, _) in &slots {
            col_ptr[c + 1] += 1;
        }
        for c in 0..m {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx: Vec<usize> = slots.iter().map(|&(_, r)| r).collect();
        let pattern = SymbolicSparseColMat::new_checked(m, m, col_ptr, None, row_idx);
        let mut plan = Vec::new();
        reduction.lower_products(full, |_, p, _, q, _, diagonal| {
            let (c, r) = (p.min(q), p.max(q));
            let rows = &pattern.row_idx()[pattern.col_ptr()[c]..pattern.col_ptr()[c + 1]];
            let slot = pattern.col_ptr()[c] + rows.partition_point(|&x| x < r);
            plan.push((slot, multiplicity(p, q, diagonal)));
        });
        ReducedLower { pattern, plan }
    }

    /// The same matrix with its unknowns renumbered, unknown i becoming `position[i]` (a
    /// fill-reducing order, so that a factorisation takes the pattern as it is): the lower
    /// pattern of the renumbered matrix, and the plan's slots moved with its entries.
    pub(crate) fn permuted(&self, position: &[usize]) -> Self {
        let p = &self.pattern;
        let m = p.ncols();
        // (column, row, old slot) of every entry, renumbered and in the lower triangle
        let mut entries: Vec<(usize, usize, usize)> = Vec::with_capacity(p.row_idx().len());
        for c in 0..m {
            for e in p.col_ptr()[c]..p.col_ptr()[c + 1] {
                let (a, b) = (position[p.row_idx()[e]], position[c]);
                entries.push((a.min(b), a.max(b), e));
            }
        }
        entries.sort_unstable();
        let mut col_ptr = vec![0usize; m + 1];
        let mut moved = vec![0usize; entries.len()];
        for (new, &(c, _, old)) in entries.iter().enumerate() {
            col_ptr[c + 1] += 1;
            moved[old] = new;
        }
        for c in 0..m {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx = entries.iter().map(|&(_, r, _)| r).collect();
        ReducedLower {
            pattern: SymbolicSparseColMat::new_checked(m, m, col_ptr, None, row_idx),
            plan: self
                .plan
                .iter()
                .map(|&(slot, times)| (moved[slot], times))
                .collect(),
        }
    }

    /// The lower pattern.
    pub(crate) fn pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        self.pattern.as_ref()
    }

    /// Number of stored entries of the lower pattern.
    pub(crate) fn len(&self) -> usize {
        self.pattern.row_idx().len()
    }

    /// Tᵀ A T's lower triangle into `out` (one value per entry of the pattern), from the
    /// values `values` of A's lower triangle on the pattern `full` the plan was built for.
    pub(crate) fn reduce(
        &self,
        reduction: &Reduction,
        full: SymbolicSparseColMatRef<'_, usize>,
        values: &[f64],
        out: &mut [f64],
    ) {
        out.fill(0.0);
        let mut next = 0;
        reduction.lower_products(full, |k, _, a, _, b, _| {
            let (slot, times) = self.plan[next];
            next += 1;
            out[slot] += times * a * values[k] * b;
        });
    }

    /// The symmetric matrix with lower triangle `lower` (one value per entry of the pattern),
    /// both triangles stored, rows sorted.
    pub(crate) fn to_full(&self, lower: &[f64]) -> SparseColMat<usize, f64> {
        let p = &self.pattern;
        let m = p.ncols();
        // column j holds the upper rows (lower entries of row j, from columns < j), then its
        // own lower rows
        let mut upper = vec![0usize; m];
        for c in 0..m {
            for &r in &p.row_idx()[p.col_ptr()[c]..p.col_ptr()[c + 1]] {
                if r != c {
                    upper[r] += 1;
                }
            }
        }
        let mut col_ptr = Vec::with_capacity(m + 1);
        col_ptr.push(0);
        for c in 0..m {
            let own = p.col_ptr()[c + 1] - p.col_ptr()[c];
            col_ptr.push(col_ptr[c] + upper[c] + own);
        }
        let total = col_ptr[m];
        let (mut row_idx, mut values) = (vec![0usize; total], vec![0.0; total]);
        let mut next_upper: Vec<usize> = col_ptr[..m].to_vec();
        for c in 0..m {
            let own_start = col_ptr[c] + upper[c];
            for (k, e) in (p.col_ptr()[c]..p.col_ptr()[c + 1]).enumerate() {
                let r = p.row_idx()[e];
                row_idx[own_start + k] = r;
                values[own_start + k] = lower[e];
                if r != c {
                    row_idx[next_upper[r]] = c;
                    values[next_upper[r]] = lower[e];
                    next_upper[r] += 1;
                }
            }
        }
        SparseColMat::new(
            SymbolicSparseColMat::new_checked(m, m, col_ptr, None, row_idx),
            values,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::fixed::FixedDofs;
    use crate::fem::rigid::RigidBodies;
    use nalgebra::{DMatrix, Point3};

    /// Tᵀ A T through the plan, in full, is the dense product, for a symmetric A with entries
    /// on and off the diagonal between free nodes, body nodes and both, a fixed DOF, and an
    /// extra entry the product does not reach.
    #[test]
    fn the_reduced_matrix_is_the_dense_product() {
        let rest: Vec<Point3<f64>> = (0..6)
            .map(|v| Point3::new(v as f64, (v * v) as f64 * 0.3, 1.0 - v as f64 * 0.5))
            .collect();
        let bodies =
            RigidBodies::new(&rest, &[None, Some(0), Some(0), Some(0), None, Some(1)]).unwrap();
        let fixed = FixedDofs::from_dofs(6, &[1]).unwrap();
        let reduction = Reduction::new(&rest, &fixed, &bodies).unwrap();
        let n = 18;
        // a symmetric A coupling nodes 0-1, 1-2 (one body), 2-4, 4-5 and every diagonal block
        let mut a = DMatrix::<f64>::zeros(n, n);
        let pairs = [
            (0, 0),
            (1, 1),
            (2, 2),
            (3, 3),
            (4, 4),
            (5, 5),
            (1, 0),
            (2, 1),
            (4, 2),
            (5, 4),
        ];
        let mut value = 0.37;
        for &(u, v) in &pairs {
            for i in 0..3 {
                for j in 0..3 {
                    value = (value * 7.13f64).fract() + 0.1;
                    let (r, c) = (3 * u + i, 3 * v + j);
                    if r >= c {
                        a[(r, c)] = value;
                        a[(c, r)] = value;
                    }
                }
            }
        }
        let mut col_ptr = vec![0usize];
        let (mut row_idx, mut values) = (Vec::new(), Vec::new());
        for c in 0..n {
            for r in c..n {
                if a[(r, c)] != 0.0 {
                    row_idx.push(r);
                    values.push(a[(r, c)]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        let full = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let m = reduction.unknowns();
        let mut t = DMatrix::<f64>::zeros(n, m);
        for d in 0..n {
            for &(i, c) in reduction.row(d) {
                t[(d, i)] = c;
            }
        }
        let expected = t.transpose() * &a * &t;
        let reduced = ReducedLower::new(&reduction, full.as_ref(), &[(0, m - 1)]);
        let mut lower = vec![f64::NAN; reduced.len()];
        reduced.reduce(&reduction, full.as_ref(), &values, &mut lower);
        let dense = |reduced: &ReducedLower, lower: &[f64]| {
            let matrix = reduced.to_full(lower);
            let s = matrix.symbolic();
            let mut got = DMatrix::<f64>::zeros(m, m);
            for c in 0..m {
                let rows = &s.row_idx()[s.col_ptr()[c]..s.col_ptr()[c + 1]];
                assert!(rows.windows(2).all(|w| w[0] < w[1]), "column {c}: {rows:?}");
                for (k, &r) in rows.iter().enumerate() {
                    got[(r, c)] = matrix.val()[s.col_ptr()[c] + k];
                }
            }
            got
        };
        let got = dense(&reduced, &lower);
        assert!((&got - &expected).abs().max() < 1e-12, "{got}\n{expected}");
        // the extra entry is held, as a zero
        let s = reduced.pattern();
        assert!(s.row_idx()[s.col_ptr()[0]..s.col_ptr()[1]].contains(&(m - 1)));
        assert_eq!(got[(m - 1, 0)], 0.0);
        // renumbered (unknown i at m - 1 - i), the same matrix, its lower pattern sorted
        let position: Vec<usize> = (0..m).rev().collect();
        let permuted = reduced.permuted(&position);
        let mut permuted_lower = vec![f64::NAN; permuted.len()];
        permuted.reduce(&reduction, full.as_ref(), &values, &mut permuted_lower);
        let p = permuted.pattern();
        for c in 0..m {
            let rows = &p.row_idx()[p.col_ptr()[c]..p.col_ptr()[c + 1]];
            assert!(rows.iter().all(|&r| r >= c) && rows.windows(2).all(|w| w[0] < w[1]));
        }
        let renumbered = dense(&permuted, &permuted_lower);
        for (r, c) in (0..m).flat_map(|r| (0..m).map(move |c| (r, c))) {
            assert_eq!(
                renumbered[(position[r], position[c])],
                got[(r, c)],
                "({r}, {c})"
            );
        }
    }
}
