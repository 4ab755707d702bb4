//! Sparse Cholesky LLᵀ of a symmetric positive-definite matrix given by its lower triangle
//! (faer 0.24 low-level API): the AMD ordering and symbolic factorisation are computed once
//! per pattern; every numeric factorisation and solve reuses them and a scratch buffer sized
//! once, so neither allocates.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::LltError;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::error::FemError;

/// A reusable sparse Cholesky factorisation for one sparsity pattern.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    scratch: MemBuffer,
    par: Par,
    factorised: bool,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("dofs", &self.symbolic.nrows())
            .field("factor_nnz", &self.l_values.len())
            .field("factorised", &self.factorised)
            .finish()
    }
}

impl SparseCholesky {
    /// Symbolic analysis (AMD ordering, elimination tree, supernodes) of a lower-triangular
    /// pattern; done once per mesh. Uses faer's global parallelism setting.
    pub fn analyse(pattern: SymbolicSparseColMatRef<'_, usize>) -> Result<Self, FemError> {
        let symbolic = factorize_symbolic_cholesky(
            pattern,
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_err(|e| FemError::Factorisation {
            message: format!("symbolic analysis: {e:?}"),
        })?;
        let par = faer::get_global_parallelism();
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        Ok(SparseCholesky {
            l_values: vec![0.0; symbolic.len_val()],
            scratch: MemBuffer::new(req),
            symbolic,
            par,
            factorised: false,
        })
    }

    /// Number of stored values of the factor L.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Numeric factorisation of `matrix` (lower triangle, the analysed pattern).
    pub fn factorise(&mut self, matrix: SparseColMatRef<'_, usize, f64>) -> Result<(), FemError> {
        self.factorised = false;
        let result = self.symbolic.factorize_numeric_llt(
            &mut self.l_values,
            matrix,
            Side::Lower,
            Default::default(),
            self.par,
            MemStack::new(&mut self.scratch),
            Default::default(),
        );
        match result {
            Ok(_) => {
                self.factorised = true;
                Ok(())
            }
            Err(LltError::NonPositivePivot { index }) => {
                Err(FemError::NotPositiveDefinite { pivot: index })
            }
        }
    }

    /// Solves A x = rhs in place with the last factorisation (`rhs` has one entry per DOF).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), FemError> {
        if !self.factorised {
            return Err(FemError::Factorisation {
                message: "solve requested without a successful numeric factorisation".into(),
            });
        }
        let n = self.symbolic.nrows();
        if rhs.len() != n {
            return Err(FemError::LengthMismatch {
                what: "right-hand side",
                expected: n,
                found: rhs.len(),
            });
        }
        let llt = LltRef::new(&self.symbolic, &self.l_values);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            self.par,
            MemStack::new(&mut self.scratch),
        );
        Ok(())
    }
}
