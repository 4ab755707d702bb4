//! Dirichlet (fixed) degrees of freedom. The solvers keep the sparse pattern unchanged and
//! project the system instead: a fixed DOF's row and column are zeroed, its diagonal set to 1
//! and its right-hand side to 0, so its update is exactly zero (SOFA's projective constraint,
//! P A P + (I − P)).

use super::error::FemError;

/// A mask over the 3·n degrees of freedom (x, y, z per node); `true` means fixed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FixedDofs {
    mask: Vec<bool>,
}

impl FixedDofs {
    /// All three DOFs of each listed node fixed, in a model of `node_count` nodes.
    pub fn from_nodes(node_count: usize, nodes: &[u32]) -> Result<Self, FemError> {
        let mut mask = vec![false; 3 * node_count];
        for &n in nodes {
            if n as usize >= node_count {
                return Err(FemError::BadNodeReference {
                    what: "fixed node",
                    node: n,
                    n_nodes: node_count,
                });
            }
            mask[3 * n as usize..3 * n as usize + 3].fill(true);
        }
        Ok(FixedDofs { mask })
    }

    /// The listed DOFs (index 3·node + axis, axis 0 = x, 1 = y, 2 = z) fixed.
    pub fn from_dofs(node_count: usize, dofs: &[u32]) -> Result<Self, FemError> {
        let mut mask = vec![false; 3 * node_count];
        for &d in dofs {
            let slot = mask.get_mut(d as usize).ok_or(FemError::BadNodeReference {
                what: "fixed DOF (3*node+axis)",
                node: d / 3,
                n_nodes: node_count,
            })?;
            *slot = true;
        }
        Ok(FixedDofs { mask })
    }

    /// Whether DOF `dof` is fixed.
    #[inline]
    pub fn is_fixed(&self, dof: usize) -> bool {
        self.mask[dof]
    }

    /// Whether none of node `v`'s three DOFs is fixed.
    #[inline]
    pub fn node_free(&self, v: usize) -> bool {
        self.mask[3 * v..3 * v + 3] == [false; 3]
    }

    /// Number of DOFs covered (3 per node).
    pub fn len(&self) -> usize {
        self.mask.len()
    }

    /// Whether the mask covers no DOF at all (a model without nodes).
    pub fn is_empty(&self) -> bool {
        self.mask.is_empty()
    }

    /// Zeroes the fixed entries of a DOF vector.
    pub fn zero_fixed(&self, v: &mut [f64]) {
        for (x, &f) in v.iter_mut().zip(&self.mask) {
            if f {
                *x = 0.0;
            }
        }
    }
}
