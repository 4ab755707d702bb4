//! Sparse Cholesky LLᵀ of a symmetric positive-definite matrix given by its lower triangle
//! (faer 0.24 low-level API): the fill-reducing ordering and symbolic factorisation are
//! computed once per pattern; every numeric factorisation and solve reuses them and a scratch
//! buffer sized once, so neither allocates. `fem::variant` picks supernodal or simplicial.
//!
//! Ordering: AMD on the node graph (one vertex per 3×3 block), expanded to the three DOFs of
//! each node, so a node's DOFs stay adjacent in the factor and the ordering works on a graph
//! nine times smaller than the DOF pattern.
//!
//! Precision: the factor is double precision, or single on request (`FactorPrecision`): a
//! Newton iteration whose residual is evaluated in double precision needs its tangent only
//! approximately, and a single-precision factor moves half the bytes through the dense
//! kernels at twice their width (docs/fem.md, "A single-precision tangent").

use std::sync::Arc;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::LltError;
use faer::perm::PermRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::assembly::SparsePattern;
use super::error::FemError;
use super::variant;
use super::vector_state::DenseKernels;

fn faer_error(stage: &str, e: impl std::fmt::Debug) -> FemError {
    FemError::Factorisation {
        message: format!("{stage}: {e:?}"),
    }
}

/// AMD ordering of the node graph of a 3×3-block pattern, expanded to DOFs: (forward, inverse).
fn node_amd(pattern: &SparsePattern) -> Result<(Vec<usize>, Vec<usize>), FemError> {
    let dof = pattern.symbolic();
    let n = dof.nrows() / 3;
    // Column 3B lists rows 3B..3B+2 then 3A..3A+2 for each neighbour A > B, A increasing.
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(dof.row_idx().len() / 9 + n);
    col_ptr.push(0usize);
    for b in 0..n {
        let rows = &dof.row_idx()[dof.col_ptr()[3 * b]..dof.col_ptr()[3 * b + 1]];
        row_idx.extend(rows.iter().step_by(3).map(|r| r / 3));
        col_ptr.push(row_idx.len());
    }
    let nodes = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    let (fwd, inv) = amd_ordering(nodes.as_ref())?;
    let expand = |p: &[usize]| -> Vec<usize> {
        p.iter()
            .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
            .collect()
    };
    Ok((expand(&fwd), expand(&inv)))
}

/// AMD ordering of a symmetric matrix given by its lower pattern: (forward, inverse), the
/// inverse giving each row's position in the ordered matrix.
pub(crate) fn amd_ordering(
    pattern: SymbolicSparseColMatRef<'_, usize>,
) -> Result<(Vec<usize>, Vec<usize>), FemError> {
    let n = pattern.nrows();
    let (mut fwd, mut inv) = (vec![0usize; n], vec![0usize; n]);
    let mut mem = MemBuffer::new(amd::order_scratch::<usize>(n, pattern.row_idx().len()));
    amd::order(
        &mut fwd,
        &mut inv,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| faer_error("ordering", e))?;
    Ok((fwd, inv))
}

/// The precision of a numeric factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FactorPrecision {
    /// Factor and solves in double precision.
    #[default]
    Double,
    /// The matrix rounded to single precision, factorised and solved so (right-hand side and
    /// solution rounded too): a solve's relative error grows with the matrix's condition
    /// number times 6e-8. For a Newton tangent, whose residual stays double. A matrix whose
    /// single-precision factorisation meets a non-positive pivot is factorised in double
    /// precision instead.
    Single,
}

/// The single-precision factor and the buffers that convert to and from it.
struct SingleFactor {
    l_values: Vec<f32>,
    matrix: Vec<f32>,
    rhs: Vec<f32>,
    scratch: MemBuffer,
}

impl SingleFactor {
    /// A factor of `symbolic`'s pattern with the values `l_values`, and its buffers.
    fn new(l_values: Vec<f32>, symbolic: &SymbolicCholesky<usize>, par: Par) -> Self {
        SingleFactor {
            l_values,
            matrix: Vec::new(),
            rhs: Vec::new(),
            scratch: scratch::<f32>(symbolic, par),
        }
    }
}

/// A reusable sparse Cholesky factorisation for one sparsity pattern. A clone shares the
/// symbolic analysis and has its own numeric factor and scratch.
pub struct SparseCholesky {
    symbolic: Arc<SymbolicCholesky<usize>>,
    l_values: Vec<f64>,
    scratch: MemBuffer,
    /// Allocated at the first single-precision factorisation.
    single: Option<SingleFactor>,
    par: Par,
    /// The precision of the last successful factorisation, if any.
    factorised: Option<FactorPrecision>,
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

/// The scratch of a numeric factorisation and a one-column solve in precision `T`.
fn scratch<T: faer::traits::ComplexField>(
    symbolic: &SymbolicCholesky<usize>,
    par: Par,
) -> MemBuffer {
    MemBuffer::new(StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<T>(par, Default::default()),
        symbolic.solve_in_place_scratch::<T>(1, par),
    ]))
}

impl Clone for SparseCholesky {
    fn clone(&self) -> Self {
        SparseCholesky {
            symbolic: Arc::clone(&self.symbolic),
            l_values: self.l_values.clone(),
            scratch: scratch::<f64>(&self.symbolic, self.par),
            single: self
                .single
                .as_ref()
                .map(|single| SingleFactor::new(single.l_values.clone(), &self.symbolic, self.par)),
            par: self.par,
            factorised: self.factorised,
        }
    }
}

/// A factorisation's outcome as the crate's error.
fn pivot_error<T>(result: Result<T, LltError>) -> Result<(), FemError> {
    match result {
        Ok(_) => Ok(()),
        Err(LltError::NonPositivePivot { index }) => {
            Err(FemError::NotPositiveDefinite { pivot: index })
        }
    }
}

impl SparseCholesky {
    /// Ordering and symbolic analysis (elimination tree, supernodes) of a tangent pattern;
    /// done once per mesh. Uses faer's global parallelism setting at this call.
    pub fn analyse(pattern: &SparsePattern) -> Result<Self, FemError> {
        let (fwd, inv) = node_amd(pattern)?;
        let perm = PermRef::new_checked(&fwd, &inv, fwd.len());
        Self::with_ordering(pattern.symbolic(), SymmetricOrdering::Custom(perm))
    }

    /// As [`SparseCholesky::analyse`] for a lower-triangle pattern (the diagonal included)
    /// already in a fill-reducing order (`amd_ordering`): factorised as it is, so that faer
    /// neither permutes nor sorts the matrix at each factorisation (a reduced tangent, whose
    /// unknowns are not 3 per node, permuted once by `ReducedLower::permuted`).
    pub(crate) fn analyse_in_order(
        pattern: SymbolicSparseColMatRef<'_, usize>,
    ) -> Result<Self, FemError> {
        // without a permutation faer's symbolic analysis reads the upper triangle whatever
        // side it is told (its numeric factorisation takes the lower one as it is)
        let upper = pattern
            .transpose()
            .to_col_major()
            .map_err(|e| faer_error("upper triangle", e))?;
        Self::with_ordering_on(upper.as_ref(), Side::Upper, SymmetricOrdering::Identity)
    }

    fn with_ordering(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        ordering: SymmetricOrdering<'_, usize>,
    ) -> Result<Self, FemError> {
        Self::with_ordering_on(pattern, Side::Lower, ordering)
    }

    /// The analysis of the `side` triangle `pattern`; the numeric factorisations take the
    /// lower triangle.
    fn with_ordering_on(
        pattern: SymbolicSparseColMatRef<'_, usize>,
        side: Side,
        ordering: SymmetricOrdering<'_, usize>,
    ) -> Result<Self, FemError> {
        let symbolic =
            factorize_symbolic_cholesky(pattern, side, ordering, variant::cholesky_params())
                .map_err(|e| faer_error("symbolic analysis", e))?;
        let par = faer::get_global_parallelism();
        Ok(SparseCholesky {
            l_values: vec![0.0; symbolic.len_val()],
            scratch: scratch::<f64>(&symbolic, par),
            single: None,
            symbolic: Arc::new(symbolic),
            par,
            factorised: None,
        })
    }

    /// Number of stored values of the factor L.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// The precision of the last successful factorisation (`None` before one, or after a
    /// failed one).
    pub fn precision(&self) -> Option<FactorPrecision> {
        self.factorised
    }

    /// Numeric factorisation of `matrix` (lower triangle, the analysed pattern), in double
    /// precision.
    pub fn factorise(&mut self, matrix: SparseColMatRef<'_, usize, f64>) -> Result<(), FemError> {
        self.factorise_in(matrix, FactorPrecision::Double)
    }

    /// Numeric factorisation of `matrix` in `precision` (a single-precision one that meets a
    /// non-positive pivot is redone in double precision); the solves use it.
    pub fn factorise_in(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
        precision: FactorPrecision,
    ) -> Result<(), FemError> {
        let _clean = DenseKernels::parallel();
        self.factorised = None;
        if precision == FactorPrecision::Single && self.factorise_single(matrix).is_ok() {
            self.factorised = Some(FactorPrecision::Single);
            return Ok(());
        }
        pivot_error(self.symbolic.factorize_numeric_llt(
            &mut self.l_values,
            matrix,
            Side::Lower,
            Default::default(),
            self.par,
            MemStack::new(&mut self.scratch),
            Default::default(),
        ))?;
        self.factorised = Some(FactorPrecision::Double);
        Ok(())
    }

    /// `matrix` rounded to single precision and factorised so.
    fn factorise_single(
        &mut self,
        matrix: SparseColMatRef<'_, usize, f64>,
    ) -> Result<(), FemError> {
        let (symbolic, par) = (&self.symbolic, self.par);
        let single = self
            .single
            .get_or_insert_with(|| SingleFactor::new(vec![0.0; symbolic.len_val()], symbolic, par));
        single.matrix.clear();
        single.matrix.extend(matrix.val().iter().map(|&v| v as f32));
        pivot_error(symbolic.factorize_numeric_llt(
            &mut single.l_values,
            SparseColMatRef::new(matrix.symbolic(), &single.matrix),
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(&mut single.scratch),
            Default::default(),
        ))
    }

    /// Solves A x = rhs in place with the last factorisation (`rhs` has one entry per DOF),
    /// in the precision it was made in.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), FemError> {
        let n = self.symbolic.nrows();
        if rhs.len() != n {
            return Err(FemError::LengthMismatch {
                what: "right-hand side",
                expected: n,
                found: rhs.len(),
            });
        }
        let _clean = DenseKernels::parallel();
        match (self.factorised, &mut self.single) {
            (Some(FactorPrecision::Single), Some(single)) => {
                let SingleFactor {
                    l_values,
                    rhs: rounded,
                    scratch,
                    ..
                } = single;
                rounded.clear();
                rounded.extend(rhs.iter().map(|&v| v as f32));
                LltRef::new(&self.symbolic, l_values).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rounded, n, 1),
                    self.par,
                    MemStack::new(scratch),
                );
                for (r, s) in rhs.iter_mut().zip(rounded.iter()) {
                    *r = f64::from(*s);
                }
            }
            (Some(FactorPrecision::Double), _) => LltRef::new(&self.symbolic, &self.l_values)
                .solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rhs, n, 1),
                    self.par,
                    MemStack::new(&mut self.scratch),
                ),
            // no factorisation yet, or the last one failed (a single-precision factor always
            // has its buffers)
            _ => {
                return Err(FemError::Factorisation {
                    message: "solve requested without a successful numeric factorisation".into(),
                });
            }
        }
        Ok(())
    }
}
