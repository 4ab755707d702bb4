//! Sparse factorisation of a complex symmetric (not Hermitian) matrix A = A_r + iA_i given by
//! its full pattern, for the harmonic solves: the pattern's ordering and symbolic analysis once,
//! then a numeric factorisation per set of values and solves with it.
//!
//! faer's Cholesky and LDLᴴ assume a Hermitian matrix, and its sparse LU (partial pivoting,
//! COLAMD) bounds the fill by the structure of AᵀA, several times the symmetric fill. So A is
//! factorised in its *real symmetric form*: with x = x_r + ix_i and b = b_r + ib_i,
//!
//! [A_r  −A_i] [x_r]   [ b_r]
//! [−A_i −A_r] [x_i] = [−b_i],
//!
//! symmetric (indefinite) because A_r and A_i are. The two parts of each unknown are
//! interleaved, so each complex entry a + ib is one 2×2 block [[a, −b], [−b, −a]], nonsingular
//! whenever a + ib ≠ 0, and the ordering is AMD on the complex pattern with each unknown's pair
//! kept adjacent (the pair then falls in one supernode). faer's supernodal LBLᵀ, with
//! Bunch-Kaufman pivoting inside each supernode, may choose that 2×2 block as a pivot where a
//! is small: a real part that vanishes at a resonance is harmless. Without the pivoting (the
//! simplicial LDLᵀ) it is not, so where supernodal factorisations are not allowed
//! (`fem::variant`) the matrix goes to faer's simplicial complex LU instead, as before.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    IntranodeLbltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::linalg::lu::{LuRef, NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side, c64};

use super::error::FemError;
use super::variant;

fn faer_error(stage: &str, e: impl std::fmt::Debug) -> FemError {
    FemError::Factorisation {
        message: format!("{stage}: {e:?}"),
    }
}

/// Where one lower entry (row ≥ column) of the complex pattern goes in the real form.
#[derive(Debug, Clone, Copy)]
struct RealSlot {
    /// Position in the complex pattern's values.
    complex: usize,
    /// Position of row 2r in column 2c of the real form; row 2r + 1 follows it.
    even: usize,
    /// Position of row 2r (2c + 1 for a diagonal entry) in column 2c + 1; row 2r + 1 follows
    /// it off the diagonal.
    odd: usize,
    diagonal: bool,
}

/// The analysis of one pattern.
#[derive(Debug)]
enum Analysis {
    /// The real symmetric form (module docs): its lower pattern, its symbolic LBLᵀ, and where
    /// each complex entry goes in it.
    RealForm {
        pattern: SymbolicSparseColMat<usize>,
        symbolic: Box<SymbolicCholesky<usize>>,
        slots: Vec<RealSlot>,
    },
    /// The simplicial complex LU, where supernodal factorisations are not allowed.
    Lu(SymbolicLu<usize>),
}

/// The ordering and symbolic analysis of a complex symmetric matrix's full pattern.
#[derive(Debug)]
pub(super) struct ComplexSymmetric {
    pattern: SymbolicSparseColMat<usize>,
    analysis: Analysis,
}

impl ComplexSymmetric {
    /// Analyses the full (both triangles, sorted rows) square pattern `pattern`.
    pub(super) fn analyse(pattern: SymbolicSparseColMatRef<'_, usize>) -> Result<Self, FemError> {
        let analysis = if variant::supernodal_allowed() {
            let (real, slots) = real_form_pattern(pattern);
            let (forward, inverse) = paired_amd(pattern)?;
            let symbolic = factorize_symbolic_cholesky(
                real.as_ref(),
                Side::Lower,
                SymmetricOrdering::Custom(PermRef::new_checked(&forward, &inverse, forward.len())),
                variant::supernodal_cholesky_params(),
            )
            .map_err(|e| faer_error("symbolic analysis of the real form", e))?;
            Analysis::RealForm {
                pattern: real,
                symbolic: Box::new(symbolic),
                slots,
            }
        } else {
            Analysis::Lu(
                factorize_symbolic_lu(pattern, variant::lu_params())
                    .map_err(|e| faer_error("symbolic LU", e))?,
            )
        };
        Ok(ComplexSymmetric {
            pattern: pattern.to_owned().map_err(|e| faer_error("pattern", e))?,
            analysis,
        })
    }

    /// Number of unknowns.
    pub(super) fn unknowns(&self) -> usize {
        self.pattern.ncols()
    }

    /// Factorises the matrix with `values` (one per entry of the analysed full pattern) and
    /// gives `body` the in-place solve with it.
    pub(super) fn with_factor<R>(
        &self,
        values: &[c64],
        body: impl FnOnce(&mut dyn FnMut(&mut [c64])) -> Result<R, FemError>,
    ) -> Result<R, FemError> {
        if values.len() != self.pattern.row_idx().len() {
            return Err(FemError::LengthMismatch {
                what: "complex symmetric values",
                expected: self.pattern.row_idx().len(),
                found: values.len(),
            });
        }
        let par = Par::Seq;
        match &self.analysis {
            Analysis::RealForm {
                pattern,
                symbolic,
                slots,
            } => {
                let mut real = vec![0.0; pattern.row_idx().len()];
                for slot in slots {
                    let z = values[slot.complex];
                    real[slot.even] = z.re;
                    real[slot.even + 1] = -z.im;
                    if slot.diagonal {
                        real[slot.odd] = -z.re;
                    } else {
                        real[slot.odd] = -z.im;
                        real[slot.odd + 1] = -z.re;
                    }
                }
                let n = symbolic.nrows();
                let mut mem = MemBuffer::new(StackReq::any_of(&[
                    symbolic
                        .factorize_numeric_intranode_lblt_scratch::<f64>(par, Default::default()),
                    symbolic.solve_in_place_scratch::<f64>(1, par),
                ]));
                let mut l_values = vec![0.0; symbolic.len_val()];
                let mut subdiag = vec![0.0; n];
                let (mut forward, mut inverse) = (vec![0usize; n], vec![0usize; n]);
                let lblt: IntranodeLbltRef<'_, usize, f64> = symbolic
                    .factorize_numeric_intranode_lblt(
                        &mut l_values,
                        &mut subdiag,
                        &mut forward,
                        &mut inverse,
                        SparseColMatRef::new(pattern.as_ref(), &real),
                        Side::Lower,
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    );
                let mut x = vec![0.0; n];
                body(&mut |rhs: &mut [c64]| {
                    for (i, z) in rhs.iter().enumerate() {
                        x[2 * i] = z.re;
                        x[2 * i + 1] = -z.im;
                    }
                    lblt.solve_in_place_with_conj(
                        Conj::No,
                        MatMut::from_column_major_slice_mut(&mut x, n, 1),
                        par,
                        MemStack::new(&mut mem),
                    );
                    for (i, z) in rhs.iter_mut().enumerate() {
                        *z = c64::new(x[2 * i], x[2 * i + 1]);
                    }
                })
            }
            Analysis::Lu(symbolic) => {
                let mut mem = MemBuffer::new(StackReq::any_of(&[
                    symbolic.factorize_numeric_lu_scratch::<c64>(par, Default::default()),
                    symbolic.solve_in_place_scratch::<c64>(1, par),
                ]));
                let mut numeric = NumericLu::<usize, c64>::new();
                let lu: LuRef<'_, usize, c64> = symbolic
                    .factorize_numeric_lu(
                        &mut numeric,
                        SparseColMatRef::new(self.pattern.as_ref(), values),
                        par,
                        MemStack::new(&mut mem),
                        Default::default(),
                    )
                    .map_err(|e| faer_error("numeric LU", e))?;
                let m = self.unknowns();
                body(&mut |rhs: &mut [c64]| {
                    lu.solve_in_place_with_conj(
                        Conj::No,
                        MatMut::from_column_major_slice_mut(rhs, m, 1),
                        par,
                        MemStack::new(&mut mem),
                    )
                })
            }
        }
    }
}

/// AMD ordering of the complex pattern `s` (full), expanded to the real form's interleaved
/// pairs: (forward, inverse).
fn paired_amd(s: SymbolicSparseColMatRef<'_, usize>) -> Result<(Vec<usize>, Vec<usize>), FemError> {
    let m = s.ncols();
    let (mut forward, mut inverse) = (vec![0usize; m], vec![0usize; m]);
    let mut mem = MemBuffer::new(amd::order_scratch::<usize>(m, s.row_idx().len()));
    amd::order(
        &mut forward,
        &mut inverse,
        s,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| faer_error("ordering", e))?;
    let pairs =
        |p: &[usize]| -> Vec<usize> { p.iter().flat_map(|&v| [2 * v, 2 * v + 1]).collect() };
    Ok((pairs(&forward), pairs(&inverse)))
}

/// The lower pattern of the real form of the full complex pattern `s`, and where each lower
/// complex entry goes in it.
fn real_form_pattern(
    s: SymbolicSparseColMatRef<'_, usize>,
) -> (SymbolicSparseColMat<usize>, Vec<RealSlot>) {
    let m = s.ncols();
    let mut col_ptr = Vec::with_capacity(2 * m + 1);
    let mut row_idx = Vec::with_capacity(2 * s.row_idx().len() + 2 * m);
    let mut slots = Vec::with_capacity(s.row_idx().len() / 2 + m);
    col_ptr.push(0);
    for c in 0..m {
        // column 2c: rows 2r, 2r + 1 of every r ≥ c; column 2c + 1: the same, less the
        // diagonal block's upper entry
        let lower: Vec<usize> = (s.col_ptr()[c]..s.col_ptr()[c + 1])
            .filter(|&p| s.row_idx()[p] >= c)
            .collect();
        let even_start = row_idx.len();
        for &p in &lower {
            let r = s.row_idx()[p];
            row_idx.extend([2 * r, 2 * r + 1]);
        }
        col_ptr.push(row_idx.len());
        for (k, &p) in lower.iter().enumerate() {
            let r = s.row_idx()[p];
            slots.push(RealSlot {
                complex: p,
                even: even_start + 2 * k,
                odd: row_idx.len(),
                diagonal: r == c,
            });
            if r == c {
                row_idx.push(2 * r + 1);
            } else {
                row_idx.extend([2 * r, 2 * r + 1]);
            }
        }
        col_ptr.push(row_idx.len());
    }
    let pattern = SymbolicSparseColMat::new_checked(2 * m, 2 * m, col_ptr, None, row_idx);
    (pattern, slots)
}
