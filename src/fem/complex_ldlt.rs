//! Supernodal LDLᵀ of a complex symmetric matrix (A = Aᵀ, not Hermitian), without pivoting:
//! P A Pᵀ = L D Lᵀ with L unit lower triangular and D diagonal, both complex, and no conjugate
//! anywhere. faer factorises Hermitian matrices only (its LDLᴴ and LLᴴ conjugate), so the
//! numeric factorisation is written here over faer's symbolic analysis (AMD ordering,
//! elimination tree, supernodes) and its dense kernels, in the left-looking scheme of faer's own
//! supernodal LDLᵀ: each supernode gathers its columns of A, subtracts the updates of the
//! supernodes below it in the tree whose rows reach it, factorises its dense diagonal block and
//! scales the block under it.
//!
//! Why not pivot: the harmonic matrices K(1 + iωβ) + iω(αM + C) − ω²M have complex pivots, which
//! vanish only where real and imaginary parts both do; damping keeps the imaginary part away
//! from zero at every frequency a sweep factorises. A pivot that is zero or not finite means
//! no such factorisation exists (`ComplexLdlt::factorise` gives `None`), and the caller falls
//! back to a pivoting LU. Against the real symmetric form of A (twice the unknowns, Bunch-Kaufman pivoting) this
//! stores half the values and does about a third of the work (docs/fem.md,
//! "Complex symmetric factorisation").

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_unit_lower_triangular_in_place, solve_unit_upper_triangular_in_place,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::cholesky::{
    SymbolicCholeskyRaw, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::{Accum, MatMut, MatRef, Par, Side, c64};

use super::error::FemError;
use super::variant;
use super::vector_state::DenseKernels;

/// Diagonal blocks up to this size are factorised column by column; larger ones are split in
/// two halves whose coupling is one matrix product.
const UNBLOCKED: usize = 32;

/// The symbolic analysis of one pattern: ordering, supernodes, where each entry of A goes.
#[derive(Debug)]
pub(super) struct ComplexLdlt {
    /// The ordering: row i of P A Pᵀ is row `forward[i]` of A.
    forward: Vec<usize>,
    /// First column of each supernode, and one past the last (`n_supernodes + 1` entries).
    begin: Vec<usize>,
    /// Rows below each supernode's diagonal block, ascending: `rows[row_ptr[s]..row_ptr[s + 1]]`.
    row_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// Start of each supernode's values (column-major, its rows then `rows`) in L.
    value_ptr: Vec<usize>,
    /// The supernodes whose rows reach supernode s: `updaters[updater_ptr[s]..updater_ptr[s + 1]]`.
    updater_ptr: Vec<usize>,
    updaters: Vec<usize>,
    /// For each entry of A's full pattern: its slot in L's values, if it lies in the lower
    /// triangle of P A Pᵀ (its mirror carries it otherwise).
    slots: Vec<Option<usize>>,
    /// Sizes of the largest update block (rows x columns) and of the largest scaled block of
    /// an updating supernode (its columns x the columns it updates).
    largest_update: usize,
    largest_scaled: usize,
}

/// A numeric factorisation.
pub(super) struct ComplexLdltFactor<'a> {
    symbolic: &'a ComplexLdlt,
    values: Vec<c64>,
}

impl ComplexLdlt {
    /// Analyses the full (both triangles, sorted rows) square pattern `pattern`.
    pub(super) fn analyse(pattern: SymbolicSparseColMatRef<'_, usize>) -> Result<Self, FemError> {
        let n = pattern.ncols();
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            variant::supernodal_cholesky_params(),
        )
        .map_err(|e| FemError::Factorisation {
            message: format!("symbolic analysis of the complex symmetric matrix: {e:?}"),
        })?;
        let SymbolicCholeskyRaw::Supernodal(supernodal) = symbolic.raw() else {
            return Err(FemError::Factorisation {
                message: "symbolic analysis of the complex symmetric matrix: not supernodal".into(),
            });
        };
        let forward: Vec<usize> = match symbolic.perm() {
            Some(p) => p.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        let mut inverse = vec![0usize; n];
        for (i, &f) in forward.iter().enumerate() {
            inverse[f] = i;
        }
        let ns = supernodal.n_supernodes();
        let mut begin = supernodal.supernode_begin().to_vec();
        begin.push(n);
        let mut row_ptr = Vec::with_capacity(ns + 1);
        let mut rows = Vec::new();
        let mut value_ptr = Vec::with_capacity(ns + 1);
        row_ptr.push(0);
        value_ptr.push(0);
        for s in 0..ns {
            let start = supernodal.col_ptr_for_row_idx()[s];
            let count = supernodal.nnz_per_super()[s];
            rows.extend_from_slice(&supernodal.row_idx()[start..start + count]);
            row_ptr.push(rows.len());
            let width = begin[s + 1] - begin[s];
            value_ptr.push(value_ptr[s] + width * (width + count));
        }
        let mut supernode_of = vec![0usize; n];
        for s in 0..ns {
            supernode_of[begin[s]..begin[s + 1]].fill(s);
        }
        // updaters: supernode d updates every supernode one of its rows falls in
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        let (mut largest_update, mut largest_scaled) = (0, 0);
        for d in 0..ns {
            let d_rows = &rows[row_ptr[d]..row_ptr[d + 1]];
            let mut k = 0;
            while k < d_rows.len() {
                let s = supernode_of[d_rows[k]];
                let mid = d_rows[k..].partition_point(|&r| r < begin[s + 1]);
                largest_update = largest_update.max((d_rows.len() - k) * mid);
                largest_scaled = largest_scaled.max((begin[d + 1] - begin[d]) * mid);
                pairs.push((s, d));
                k += mid;
            }
        }
        pairs.sort_unstable();
        let mut updater_ptr = vec![0usize; ns + 1];
        for &(s, _) in &pairs {
            updater_ptr[s + 1] += 1;
        }
        for s in 0..ns {
            updater_ptr[s + 1] += updater_ptr[s];
        }
        let updaters = pairs.iter().map(|&(_, d)| d).collect();
        let mut slots = Vec::with_capacity(pattern.row_idx().len());
        for c in 0..n {
            for &r in &pattern.row_idx()[pattern.col_ptr()[c]..pattern.col_ptr()[c + 1]] {
                let (i, j) = (inverse[r], inverse[c]);
                if i < j {
                    slots.push(None);
                    continue;
                }
                let s = supernode_of[j];
                let height = begin[s + 1] - begin[s] + row_ptr[s + 1] - row_ptr[s];
                let local_row = if i < begin[s + 1] {
                    i - begin[s]
                } else {
                    let below = &rows[row_ptr[s]..row_ptr[s + 1]];
                    match below.binary_search(&i) {
                        Ok(k) => begin[s + 1] - begin[s] + k,
                        Err(_) => {
                            return Err(FemError::Factorisation {
                                message: "complex symmetric pattern: an entry outside the \
                                          symbolic factor"
                                    .into(),
                            });
                        }
                    }
                };
                slots.push(Some(value_ptr[s] + (j - begin[s]) * height + local_row));
            }
        }
        Ok(ComplexLdlt {
            forward,
            begin,
            row_ptr,
            rows,
            value_ptr,
            updater_ptr,
            updaters,
            slots,
            largest_update,
            largest_scaled,
        })
    }

    /// Number of unknowns.
    pub(super) fn unknowns(&self) -> usize {
        self.forward.len()
    }

    /// Number of stored values of L and D (complex).
    #[cfg(test)]
    pub(super) fn factor_len(&self) -> usize {
        self.value_ptr[self.value_ptr.len() - 1]
    }

    fn supernodes(&self) -> usize {
        self.begin.len() - 1
    }

    /// The number of columns of supernode `s`, and its rows below the diagonal block.
    fn shape(&self, s: usize) -> (usize, &[usize]) {
        (
            self.begin[s + 1] - self.begin[s],
            &self.rows[self.row_ptr[s]..self.row_ptr[s + 1]],
        )
    }

    /// Factorises the matrix with `values` (one per entry of the analysed pattern); `None`
    /// where a pivot is zero or not finite (no LDLᵀ without pivoting).
    pub(super) fn factorise(
        &self,
        values: &[c64],
    ) -> Result<Option<ComplexLdltFactor<'_>>, FemError> {
        let _clean = DenseKernels::sequential();
        if values.len() != self.slots.len() {
            return Err(FemError::LengthMismatch {
                what: "complex symmetric values",
                expected: self.slots.len(),
                found: values.len(),
            });
        }
        let zero = c64::new(0.0, 0.0);
        let mut l = vec![zero; self.value_ptr[self.supernodes()]];
        for (slot, &v) in self.slots.iter().zip(values) {
            if let Some(slot) = slot {
                l[*slot] += v;
            }
        }
        let n = self.unknowns();
        let mut local = vec![usize::MAX; n];
        let mut product = vec![zero; self.largest_update];
        let mut scaled = vec![zero; self.largest_scaled];
        for s in 0..self.supernodes() {
            let (width, below) = self.shape(s);
            let height = width + below.len();
            let (start, end) = (self.begin[s], self.begin[s + 1]);
            for (k, &r) in below.iter().enumerate() {
                local[r] = width + k;
            }
            let (done, rest) = l.split_at_mut(self.value_ptr[s]);
            let ls = &mut rest[..width * height];
            for &d in &self.updaters[self.updater_ptr[s]..self.updater_ptr[s + 1]] {
                let (d_width, d_below) = self.shape(d);
                let d_height = d_width + d_below.len();
                let ld = MatRef::from_column_major_slice(
                    &done[self.value_ptr[d]..self.value_ptr[d] + d_width * d_height],
                    d_height,
                    d_width,
                );
                let first = d_below.partition_point(|&r| r < start);
                let mid = d_below[first..].partition_point(|&r| r < end);
                let reach = &d_below[first..];
                let m = reach.len();
                // (L_d D_d) restricted to the rows in s, transposed: d_width x mid
                let mut t =
                    MatMut::from_column_major_slice_mut(&mut scaled[..d_width * mid], d_width, mid);
                for jj in 0..mid {
                    for k in 0..d_width {
                        t[(k, jj)] = ld[(d_width + first + jj, k)] * ld[(k, k)];
                    }
                }
                let mut w = MatMut::from_column_major_slice_mut(&mut product[..m * mid], m, mid);
                matmul(
                    w.rb_mut(),
                    Accum::Replace,
                    ld.subrows(d_width + first, m),
                    t.rb(),
                    c64::new(1.0, 0.0),
                    Par::Seq,
                );
                for (jj, &col) in reach[..mid].iter().enumerate() {
                    let col = col - start;
                    let column = &mut ls[col * height..(col + 1) * height];
                    for (ii, &row) in reach.iter().enumerate().skip(jj) {
                        let row = if row < end { row - start } else { local[row] };
                        column[row] -= w[(ii, jj)];
                    }
                }
            }
            let ls = MatMut::from_column_major_slice_mut(ls, height, width);
            let (mut top, mut bottom) = ls.split_at_row_mut(width);
            if !ldlt_in_place(top.rb_mut()) {
                return Ok(None);
            }
            scale_below(top.rb(), bottom.rb_mut());
            for &r in below {
                local[r] = usize::MAX;
            }
        }
        Ok(Some(ComplexLdltFactor {
            symbolic: self,
            values: l,
        }))
    }
}

/// Factorises the symmetric matrix in the lower triangle of `a` in place: D on the diagonal,
/// L's strict lower part under it (the upper triangle is left as it was); false where a pivot
/// is zero or not finite.
fn ldlt_in_place(mut a: MatMut<'_, c64>) -> bool {
    let n = a.nrows();
    if n <= UNBLOCKED {
        for k in 0..n {
            let d = a[(k, k)];
            if !(d.re.is_finite() && d.im.is_finite()) || (d.re == 0.0 && d.im == 0.0) {
                return false;
            }
            let inv = c64::new(1.0, 0.0) / d;
            for j in k + 1..n {
                let ljk = a[(j, k)] * inv;
                for i in j..n {
                    let aik = a[(i, k)];
                    a[(i, j)] -= aik * ljk;
                }
            }
            for i in k + 1..n {
                a[(i, k)] *= inv;
            }
        }
        return true;
    }
    let h = n / 2;
    let (mut a11, _, mut a21, mut a22) = a.rb_mut().split_at_mut(h, h);
    if !ldlt_in_place(a11.rb_mut()) {
        return false;
    }
    let a11 = a11.rb();
    // A21 ← A21 L11⁻ᵀ = L21 D1; the product L21 D1 L21ᵀ taken from it, then L21 = A21 D1⁻¹
    solve_unit_lower_triangular_in_place(a11, a21.rb_mut().transpose_mut(), Par::Seq);
    let mut l21 = a21.rb().to_owned();
    for j in 0..h {
        let inv = c64::new(1.0, 0.0) / a11[(j, j)];
        for i in 0..l21.nrows() {
            l21[(i, j)] *= inv;
        }
    }
    matmul(
        a22.rb_mut(),
        Accum::Add,
        l21.as_ref(),
        a21.rb().transpose(),
        c64::new(-1.0, 0.0),
        Par::Seq,
    );
    a21.copy_from(&l21);
    ldlt_in_place(a22)
}

/// Turns the block under a factorised diagonal block, A_below, into L_below = A_below L⁻ᵀ D⁻¹.
fn scale_below(top: MatRef<'_, c64>, mut bottom: MatMut<'_, c64>) {
    solve_unit_lower_triangular_in_place(top, bottom.rb_mut().transpose_mut(), Par::Seq);
    for j in 0..top.ncols() {
        let inv = c64::new(1.0, 0.0) / top[(j, j)];
        for i in 0..bottom.nrows() {
            bottom[(i, j)] *= inv;
        }
    }
}

impl ComplexLdltFactor<'_> {
    /// Solves A x = `rhs` in place; `work` is scratch space.
    pub(super) fn solve_in_place(&self, rhs: &mut [c64], work: &mut Vec<c64>) {
        let _clean = DenseKernels::sequential();
        let sym = self.symbolic;
        let n = sym.unknowns();
        work.clear();
        work.extend(sym.forward.iter().map(|&f| rhs[f]));
        work.resize(2 * n, c64::new(0.0, 0.0));
        let (y, gathered) = work.split_at_mut(n);
        let one = c64::new(1.0, 0.0);
        let block = |s: usize| {
            let (width, below) = sym.shape(s);
            let height = width + below.len();
            let ls = MatRef::from_column_major_slice(
                &self.values[sym.value_ptr[s]..sym.value_ptr[s] + width * height],
                height,
                width,
            );
            ls.split_at_row(width)
        };
        // L z = P b, then D w = z, then Lᵀ v = w, x = Pᵀ v
        for s in 0..sym.supernodes() {
            let (_, below) = sym.shape(s);
            let (top, bottom) = block(s);
            let (start, end) = (sym.begin[s], sym.begin[s + 1]);
            let mut x = MatMut::from_column_major_slice_mut(&mut y[start..end], end - start, 1);
            solve_unit_lower_triangular_in_place(top, x.rb_mut(), Par::Seq);
            let mut update =
                MatMut::from_column_major_slice_mut(&mut gathered[..below.len()], below.len(), 1);
            matmul(
                update.rb_mut(),
                Accum::Replace,
                bottom,
                x.rb(),
                one,
                Par::Seq,
            );
            for (&r, u) in below.iter().zip(gathered.iter()) {
                y[r] -= *u;
            }
        }
        for s in 0..sym.supernodes() {
            let (top, _) = block(s);
            for (j, v) in y[sym.begin[s]..sym.begin[s + 1]].iter_mut().enumerate() {
                *v /= top[(j, j)];
            }
        }
        for s in (0..sym.supernodes()).rev() {
            let (_, below) = sym.shape(s);
            let (top, bottom) = block(s);
            let (start, end) = (sym.begin[s], sym.begin[s + 1]);
            for (&r, g) in below.iter().zip(gathered.iter_mut()) {
                *g = y[r];
            }
            let known = MatRef::from_column_major_slice(&gathered[..below.len()], below.len(), 1);
            let mut x = MatMut::from_column_major_slice_mut(&mut y[start..end], end - start, 1);
            matmul(
                x.rb_mut(),
                Accum::Add,
                bottom.transpose(),
                known,
                -one,
                Par::Seq,
            );
            solve_unit_upper_triangular_in_place(top.transpose(), x, Par::Seq);
        }
        for (&f, &v) in sym.forward.iter().zip(y.iter()) {
            rhs[f] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::complex_symmetric::ComplexSymmetric;
    use faer::sparse::SymbolicSparseColMat;

    /// A complex symmetric matrix in full pattern (sorted rows), from its lower entries.
    fn full(n: usize, lower: &[(usize, usize, c64)]) -> (SymbolicSparseColMat<usize>, Vec<c64>) {
        let mut entries: Vec<(usize, usize, c64)> = Vec::new();
        for &(r, c, v) in lower {
            entries.push((c, r, v));
            if r != c {
                entries.push((r, c, v));
            }
        }
        entries.sort_by_key(|&(c, r, _)| (c, r));
        entries.dedup_by(|b, a| {
            let same = (a.0, a.1) == (b.0, b.1);
            if same {
                a.2 += b.2;
            }
            same
        });
        let mut col_ptr = vec![0usize; n + 1];
        for &(c, _, _) in &entries {
            col_ptr[c + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let rows = entries.iter().map(|e| e.1).collect();
        let values = entries.iter().map(|e| e.2).collect();
        (
            SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows),
            values,
        )
    }

    /// ‖A x − b‖ / ‖b‖ by the full pattern's product.
    fn relative_residual(
        pattern: &SymbolicSparseColMat<usize>,
        values: &[c64],
        x: &[c64],
        b: &[c64],
    ) -> f64 {
        let mut r = b.to_vec();
        for (c, xc) in x.iter().enumerate() {
            for p in pattern.col_ptr()[c]..pattern.col_ptr()[c + 1] {
                r[pattern.row_idx()[p]] -= values[p] * xc;
            }
        }
        let norm = |v: &[c64]| v.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        norm(&r) / norm(b)
    }

    /// A deterministic sequence in [−1, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A 2D grid's 5-point coupling with an indefinite complex diagonal (a damped system
    /// driven above some of its resonances) plus a dense clique of `clique` unknowns (a
    /// supernode wider than the unblocked size).
    fn grid_with_clique(side: usize, clique: usize) -> (usize, Vec<(usize, usize, c64)>) {
        let n = side * side;
        let mut rng = Lcg(7);
        let mut lower = Vec::new();
        for i in 0..side {
            for j in 0..side {
                let v = i * side + j;
                let re = 4.0 + 3.0 * rng.next() - if v.is_multiple_of(3) { 9.0 } else { 0.0 };
                lower.push((v, v, c64::new(re, 0.5 + 0.2 * rng.next())));
                if j + 1 < side {
                    lower.push((
                        v + 1,
                        v,
                        c64::new(-1.0 + 0.1 * rng.next(), 0.05 * rng.next()),
                    ));
                }
                if i + 1 < side {
                    lower.push((v + side, v, c64::new(-1.0, 0.1 * rng.next())));
                }
            }
        }
        let first = n - clique;
        for c in first..n {
            for r in c + 1..n {
                lower.push((r, c, c64::new(0.02 * rng.next(), 0.01 * rng.next())));
            }
        }
        (n, lower)
    }

    #[test]
    fn solves_an_indefinite_complex_symmetric_system_to_rounding() {
        for (side, clique) in [(3, 0), (12, 0), (14, 80)] {
            let (n, lower) = grid_with_clique(side, clique);
            let (pattern, values) = full(n, &lower);
            let ldlt = ComplexLdlt::analyse(pattern.as_ref()).unwrap();
            let widest = ldlt.begin.windows(2).map(|w| w[1] - w[0]).max();
            assert_eq!(widest > Some(UNBLOCKED), clique > UNBLOCKED, "{widest:?}");
            let factor = ldlt.factorise(&values).unwrap().unwrap();
            let mut rng = Lcg(11);
            let b: Vec<c64> = (0..n).map(|_| c64::new(rng.next(), rng.next())).collect();
            let mut x = b.clone();
            factor.solve_in_place(&mut x, &mut Vec::new());
            let residual = relative_residual(&pattern, &values, &x, &b);
            assert!(
                residual < 1e-12,
                "{side}x{side} grid, clique {clique}: {residual:e}"
            );
            // the factor stores each lower entry of L once (not the real form's four)
            assert!(ldlt.factor_len() < n * n, "{}", ldlt.factor_len());
        }
    }

    #[test]
    fn a_zero_pivot_is_an_error_and_the_lu_takes_over() {
        // [[0, 1], [1, 0]] (+ a decoupled unknown): no LDLᵀ without pivoting exists
        let one = c64::new(1.0, 0.0);
        let lower = [
            (0, 0, c64::new(0.0, 0.0)),
            (1, 0, one),
            (1, 1, c64::new(0.0, 0.0)),
            (2, 2, c64::new(2.0, 1.0)),
        ];
        let (pattern, values) = full(3, &lower);
        let ldlt = ComplexLdlt::analyse(pattern.as_ref()).unwrap();
        assert!(matches!(ldlt.factorise(&values), Ok(None)));
        let b = vec![c64::new(1.0, 2.0), c64::new(-3.0, 0.5), c64::new(2.0, 1.0)];
        let solver = ComplexSymmetric::analyse(pattern.as_ref()).unwrap();
        let x = solver
            .with_factor(&values, |solve| {
                let mut x = b.clone();
                solve(&mut x);
                Ok(x)
            })
            .unwrap();
        assert!(relative_residual(&pattern, &values, &x, &b) < 1e-14);
        assert!((x[2] - one).norm() < 1e-14);
    }
}
