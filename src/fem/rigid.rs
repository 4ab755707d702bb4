//! Rigid bodies: groups of nodes that move as one body, for a reduced model in which each
//! body has six degrees of freedom (a translation t and a small rotation θ about its centre c)
//! instead of three per node (docs/fem.md, "Rigid bodies").
//!
//! A node v of a body moves by u_v = t + θ × (x_v − c): the linear map T from the reduced
//! unknowns to the full DOFs (`Reduction`) turns the full system into Tᵀ K T, Tᵀ M T, Tᵀ C T
//! and Tᵀ f. A tetrahedron whose four nodes lie on one body carries no strain under that
//! motion (its rest stiffness annihilates infinitesimal rigid motions), so the reduced model
//! leaves it out of the assembly (`FemModel::without_rigid_tets`) and keeps its mass.
//! Elements that join a body to anything else (joints, ligaments, the eardrum on the
//! manubrium) stay elastic.

use faer::sparse::SymbolicSparseColMatRef;
use nalgebra::Point3;

use super::error::FemError;
use super::fixed::FixedDofs;

/// Which nodes form rigid bodies, and each body's centre.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidBodies {
    /// Body of each node (`NONE` for a node of no body).
    body_of: Vec<u32>,
    /// The centroid of each body's nodes at rest (mm): the point its rotation turns about.
    centres: Vec<Point3<f64>>,
}

const NONE: u32 = u32::MAX;

impl RigidBodies {
    /// The bodies given by `body_of` (one entry per node of `rest`: the body's index, or
    /// `None`); the bodies are numbered 0..k without gaps.
    pub fn new(rest: &[Point3<f64>], body_of: &[Option<u32>]) -> Result<Self, FemError> {
        if body_of.len() != rest.len() {
            return Err(FemError::LengthMismatch {
                what: "rigid body of each node",
                expected: rest.len(),
                found: body_of.len(),
            });
        }
        let count = body_of.iter().flatten().map(|&b| b as usize + 1).max();
        let count = count.unwrap_or(0);
        let mut sums = vec![(nalgebra::Vector3::zeros(), 0usize); count];
        for (p, b) in rest.iter().zip(body_of) {
            if let Some(b) = b {
                let s = &mut sums[*b as usize];
                s.0 += p.coords;
                s.1 += 1;
            }
        }
        let mut centres = Vec::with_capacity(count);
        for (b, (sum, n)) in sums.into_iter().enumerate() {
            if n == 0 {
                return Err(FemError::InvalidParameter {
                    what: "rigid body without nodes (bodies are numbered without gaps)",
                    value: b as f64,
                    expected: "every body index below the largest one used",
                });
            }
            centres.push(Point3::from(sum / n as f64));
        }
        Ok(RigidBodies {
            body_of: body_of.iter().map(|b| b.unwrap_or(NONE)).collect(),
            centres,
        })
    }

    /// Number of bodies.
    pub fn count(&self) -> usize {
        self.centres.len()
    }

    /// The centre of body `b` at rest (mm).
    pub(crate) fn centre(&self, b: usize) -> Point3<f64> {
        self.centres[b]
    }

    /// Number of nodes the bodies were given for.
    pub fn node_count(&self) -> usize {
        self.body_of.len()
    }

    /// The body of `node`, if any.
    pub fn body_of(&self, node: usize) -> Option<usize> {
        self.body_of
            .get(node)
            .filter(|&&b| b != NONE)
            .map(|&b| b as usize)
    }

    /// Whether the four nodes of a tetrahedron all lie on one body.
    pub(crate) fn holds(&self, cell: &[u32; 4]) -> bool {
        let b = self.body_of(cell[0] as usize);
        b.is_some() && cell[1..].iter().all(|&v| self.body_of(v as usize) == b)
    }
}

/// The linear map T from reduced unknowns to full DOFs (module docs), sparse by rows: a free
/// DOF of no body is one unknown of its own, a DOF of a body node a combination of its body's
/// six, a fixed DOF nothing. Bodies' unknowns follow the nodes' (t_x, t_y, t_z, θ_x, θ_y, θ_z).
#[derive(Debug, Clone)]
pub(crate) struct Reduction {
    /// Row d's entries are `entries[start[d]..start[d + 1]]`.
    start: Vec<usize>,
    entries: Vec<(usize, f64)>,
    unknowns: usize,
}

impl Reduction {
    /// The reduction of a model of `n` nodes at rest positions `rest`, with `fixed` DOFs and
    /// `bodies` (no node of a body may have a fixed DOF: the body would be held by it alone).
    pub(crate) fn new(
        rest: &[Point3<f64>],
        fixed: &FixedDofs,
        bodies: &RigidBodies,
    ) -> Result<Self, FemError> {
        let n = rest.len();
        for (what, expected, found) in [
            ("fixed DOF mask", 3 * n, fixed.len()),
            ("rigid body of each node", n, bodies.node_count()),
        ] {
            if expected != found {
                return Err(FemError::LengthMismatch {
                    what,
                    expected,
                    found,
                });
            }
        }
        if let Some(v) = (0..n).find(|&v| bodies.body_of(v).is_some() && fixed.is_fixed(3 * v)) {
            return Err(FemError::BadNodeReference {
                what: "a fixed DOF on a rigid body's node (fix the body's nodes all or none)",
                node: v as u32,
                n_nodes: n,
            });
        }
        let mut own = vec![usize::MAX; 3 * n];
        let mut unknowns = 0;
        for (d, slot) in own.iter_mut().enumerate() {
            if bodies.body_of(d / 3).is_none() && !fixed.is_fixed(d) {
                *slot = unknowns;
                unknowns += 1;
            }
        }
        let first_body = unknowns;
        unknowns += 6 * bodies.count();
        let mut start = Vec::with_capacity(3 * n + 1);
        let mut entries = Vec::with_capacity(3 * n);
        for (d, &own) in own.iter().enumerate() {
            start.push(entries.len());
            match bodies.body_of(d / 3) {
                None if own != usize::MAX => entries.push((own, 1.0)),
                None => {}
                Some(b) => {
                    // u = t + θ × r, row `axis`: t_axis, then θ_j r_k − θ_k r_j (`set_arms`)
                    let (base, axis) = (first_body + 6 * b, d % 3);
                    let (j, k) = ((axis + 1) % 3, (axis + 2) % 3);
                    entries.extend([(base + axis, 1.0), (base + 3 + j, 0.0), (base + 3 + k, 0.0)]);
                }
            }
        }
        start.push(entries.len());
        let mut reduction = Reduction {
            start,
            entries,
            unknowns,
        };
        reduction.set_arms(bodies, |v, b| rest[v] - bodies.centres[b]);
        Ok(reduction)
    }

    /// Sets the rows of the bodies' nodes for arms `arm(node, body)` = x_v − (c + t), the
    /// node's offset from its body's centre where the body now is (its rest offset at rest).
    pub(crate) fn set_arms(
        &mut self,
        bodies: &RigidBodies,
        arm: impl Fn(usize, usize) -> nalgebra::Vector3<f64>,
    ) {
        for v in 0..bodies.node_count() {
            let Some(b) = bodies.body_of(v) else {
                continue;
            };
            let r = arm(v, b);
            for axis in 0..3 {
                let (j, k) = ((axis + 1) % 3, (axis + 2) % 3);
                let s = self.start[3 * v + axis];
                self.entries[s + 1].1 = r[k];
                self.entries[s + 2].1 = -r[j];
            }
        }
    }

    /// Number of reduced unknowns.
    pub(crate) fn unknowns(&self) -> usize {
        self.unknowns
    }

    /// The entries (reduced unknown, coefficient) of full DOF `d`'s row of T.
    pub(crate) fn row(&self, d: usize) -> &[(usize, f64)] {
        &self.entries[self.start[d]..self.start[d + 1]]
    }

    /// Number of full DOFs.
    pub(crate) fn dof_count(&self) -> usize {
        self.start.len() - 1
    }

    /// Tᵀ f: the reduced load of full DOF values `f`.
    pub(crate) fn restrict(&self, f: impl Fn(usize) -> f64) -> Vec<f64> {
        let mut out = vec![0.0; self.unknowns];
        self.restrict_into(f, &mut out);
        out
    }

    /// [`Reduction::restrict`] into `out` (one entry per unknown, overwritten).
    pub(crate) fn restrict_into(&self, f: impl Fn(usize) -> f64, out: &mut [f64]) {
        out.fill(0.0);
        for d in 0..self.dof_count() {
            let fd = f(d);
            for &(i, c) in self.row(d) {
                out[i] += c * fd;
            }
        }
    }

    /// Visits the products behind Tᵀ A T of a symmetric A given by its lower triangle
    /// `lower` (over the full DOFs), in one fixed order: `visit(position of the entry in
    /// `lower`, reduced row p, its coefficient, reduced column q, its coefficient, whether the
    /// entry is on A's diagonal)`; the entry's mirror (off the diagonal) adds to (q, p).
    pub(crate) fn lower_products(
        &self,
        lower: SymbolicSparseColMatRef<'_, usize>,
        mut visit: impl FnMut(usize, usize, f64, usize, f64, bool),
    ) {
        for col in 0..lower.ncols() {
            let tc = self.row(col);
            for k in lower.col_ptr()[col]..lower.col_ptr()[col + 1] {
                let row = lower.row_idx()[k];
                for &(p, a) in self.row(row) {
                    for &(q, b) in tc {
                        visit(k, p, a, q, b, row == col);
                    }
                }
            }
        }
    }

    /// T q at full DOF `d`.
    pub(crate) fn expand_at<T>(&self, q: &[T], d: usize) -> T
    where
        T: Copy + std::ops::Mul<f64, Output = T> + std::iter::Sum<T>,
    {
        self.row(d).iter().map(|&(i, c)| q[i] * c).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn a_body_moves_rigidly_and_free_nodes_alone() {
        let rest = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(2.0, 0.0, 0.0),
            Point3::new(0.0, 3.0, 0.0),
            Point3::new(5.0, 5.0, 5.0),
        ];
        let bodies = RigidBodies::new(&rest, &[Some(0), Some(0), Some(0), None]).unwrap();
        assert_eq!(bodies.count(), 1);
        let fixed = FixedDofs::from_nodes(4, &[]).unwrap();
        let t = Reduction::new(&rest, &fixed, &bodies).unwrap();
        assert_eq!(t.unknowns(), 3 + 6);
        // the free node's three unknowns first, then the body's
        let (tx, theta) = (
            Vector3::new(0.1, -0.2, 0.3),
            Vector3::new(0.01, 0.02, -0.03),
        );
        let mut q = vec![7.0, 8.0, 9.0];
        q.extend(tx.iter().chain(theta.iter()));
        let centre = Point3::new(2.0 / 3.0, 1.0, 0.0);
        for (v, p) in rest.iter().enumerate().take(3) {
            let want = tx + theta.cross(&(p - centre));
            for a in 0..3 {
                assert!((t.expand_at(&q, 3 * v + a) - want[a]).abs() < 1e-14);
            }
        }
        assert_eq!([9, 10, 11].map(|d| t.expand_at(&q, d)), [7.0, 8.0, 9.0]);
        // Tᵀ of a force at a body node: the force and its moment about the centre
        let f = Vector3::new(1.0, 2.0, 3.0);
        let reduced = t.restrict(|d| if d / 3 == 1 { f[d % 3] } else { 0.0 });
        let moment = (rest[1] - centre).cross(&f);
        let want = [0.0, 0.0, 0.0, f.x, f.y, f.z, moment.x, moment.y, moment.z];
        for (a, b) in reduced.iter().zip(want) {
            assert!((a - b).abs() < 1e-14, "{reduced:?}");
        }
    }

    #[test]
    fn a_fixed_node_on_a_body_and_a_gap_in_the_numbering_are_refused() {
        let rest = [Point3::origin(), Point3::new(1.0, 0.0, 0.0)];
        let bodies = RigidBodies::new(&rest, &[Some(0), None]).unwrap();
        let fixed = FixedDofs::from_nodes(2, &[0]).unwrap();
        assert!(Reduction::new(&rest, &fixed, &bodies).is_err());
        assert!(RigidBodies::new(&rest, &[Some(1), None]).is_err());
    }
}
