//! Sparse factorisation of a complex symmetric (not Hermitian) matrix A = A_r + iA_i given by
//! its full pattern, for the harmonic solves: the pattern's ordering and symbolic analysis once,
//! then a numeric factorisation per set of values and solves with it.
//!
//! faer's Cholesky and LDLᴴ assume a Hermitian matrix, and its sparse LU (partial pivoting,
//! COLAMD) bounds the fill by the structure of AᵀA, several times the symmetric fill. So A is
//! factorised by the supernodal complex LDLᵀ of `fem::complex_ldlt` (AMD ordering, no
//! pivoting: a pivot vanishes only where its real and imaginary parts both do). Where that
//! meets a zero pivot, and where supernodal factorisations are not allowed (`fem::variant`),
//! the matrix goes to faer's complex LU instead (simplicial under an address-space limit).

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::lu::{LuRef, NumericLu, SymbolicLu, factorize_symbolic_lu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, c64};

use super::complex_ldlt::ComplexLdlt;
use super::error::FemError;
use super::variant;
use super::vector_state::DenseKernels;

fn faer_error(stage: &str, e: impl std::fmt::Debug) -> FemError {
    FemError::Factorisation {
        message: format!("{stage}: {e:?}"),
    }
}

/// The analysis of one pattern.
#[derive(Debug)]
enum Analysis {
    /// The supernodal complex LDLᵀ.
    Ldlt(Box<ComplexLdlt>),
    /// The complex LU, where supernodal factorisations are not allowed.
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
            Analysis::Ldlt(Box::new(ComplexLdlt::analyse(pattern)?))
        } else {
            Analysis::Lu(symbolic_lu(pattern)?)
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
        match &self.analysis {
            Analysis::Ldlt(ldlt) => match ldlt.factorise(values)? {
                Some(factor) => {
                    let mut work = Vec::with_capacity(ldlt.unknowns());
                    body(&mut |rhs: &mut [c64]| factor.solve_in_place(rhs, &mut work))
                }
                None => {
                    let lu = symbolic_lu(self.pattern.as_ref())?;
                    self.with_lu(&lu, values, body)
                }
            },
            Analysis::Lu(lu) => self.with_lu(lu, values, body),
        }
    }

    /// [`ComplexSymmetric::with_factor`] by the LU of `symbolic`.
    fn with_lu<R>(
        &self,
        symbolic: &SymbolicLu<usize>,
        values: &[c64],
        body: impl FnOnce(&mut dyn FnMut(&mut [c64])) -> Result<R, FemError>,
    ) -> Result<R, FemError> {
        let par = Par::Seq;
        let mut mem = MemBuffer::new(StackReq::any_of(&[
            symbolic.factorize_numeric_lu_scratch::<c64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<c64>(1, par),
        ]));
        let mut numeric = NumericLu::<usize, c64>::new();
        let lu: LuRef<'_, usize, c64> = {
            let _clean = DenseKernels::sequential();
            symbolic
                .factorize_numeric_lu(
                    &mut numeric,
                    SparseColMatRef::new(self.pattern.as_ref(), values),
                    par,
                    MemStack::new(&mut mem),
                    Default::default(),
                )
                .map_err(|e| faer_error("numeric LU", e))?
        };
        let m = self.unknowns();
        body(&mut |rhs: &mut [c64]| {
            let _clean = DenseKernels::sequential();
            lu.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(rhs, m, 1),
                par,
                MemStack::new(&mut mem),
            )
        })
    }
}

/// The symbolic LU of the full pattern `pattern`.
fn symbolic_lu(pattern: SymbolicSparseColMatRef<'_, usize>) -> Result<SymbolicLu<usize>, FemError> {
    factorize_symbolic_lu(pattern, variant::lu_params()).map_err(|e| faer_error("symbolic LU", e))
}
