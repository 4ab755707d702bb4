//! Point dashpots that act along one direction: force −c (n·v) n on a node moving at v, so
//! motion across n is not damped. The cochlear fluid loads the stapes footplate this way: it
//! resists the piston motion along the footplate normal, not the footplate's sliding or
//! rocking in its own plane. In a matrix the dashpot is the 3×3 node block c n nᵀ.

use nalgebra::{Matrix3, Vector3};

use super::error::FemError;

/// A dashpot of `coefficient` (g/s) on `node`, acting along the unit vector `direction`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dashpot {
    pub node: u32,
    pub coefficient: f64,
    pub direction: Vector3<f64>,
}

impl Dashpot {
    /// Its damping block c n nᵀ (g/s).
    pub fn block(&self) -> Matrix3<f64> {
        self.direction * self.direction.transpose() * self.coefficient
    }
}

/// `Ok` when every dashpot refers to one of `node_count` nodes, has a finite coefficient ≥ 0
/// and a unit direction.
pub(crate) fn check_dashpots(dashpots: &[Dashpot], node_count: usize) -> Result<(), FemError> {
    for d in dashpots {
        if d.node as usize >= node_count {
            return Err(FemError::BadNodeReference {
                what: "dashpot",
                node: d.node,
                n_nodes: node_count,
            });
        }
        if !(d.coefficient.is_finite() && d.coefficient >= 0.0) {
            return Err(FemError::InvalidParameter {
                what: "dashpot coefficient (g/s)",
                value: d.coefficient,
                expected: "finite and >= 0",
            });
        }
        let length = d.direction.norm();
        if (length - 1.0).abs().partial_cmp(&1e-9) != Some(std::cmp::Ordering::Less) {
            return Err(FemError::InvalidParameter {
                what: "dashpot direction length",
                value: length,
                expected: "a unit vector",
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_damps_along_the_direction_only() {
        let n = Vector3::new(1.0, 2.0, 2.0) / 3.0;
        let d = Dashpot {
            node: 0,
            coefficient: 5.0,
            direction: n,
        };
        let across = n.cross(&Vector3::x()).normalize();
        assert!((d.block() * n - n * 5.0).norm() < 1e-12);
        assert!((d.block() * across).norm() < 1e-12);
    }

    #[test]
    fn bad_dashpots_are_refused() {
        let good = Dashpot {
            node: 1,
            coefficient: 1.0,
            direction: Vector3::z(),
        };
        assert!(check_dashpots(&[good], 2).is_ok());
        for bad in [
            Dashpot { node: 2, ..good },
            Dashpot {
                coefficient: -1.0,
                ..good
            },
            Dashpot {
                direction: Vector3::new(0.0, 0.0, 2.0),
                ..good
            },
            Dashpot {
                direction: Vector3::new(f64::NAN, 0.0, 1.0),
                ..good
            },
        ] {
            assert!(check_dashpots(&[bad], 2).is_err(), "{bad:?}");
        }
    }
}
