//! The interface between an anatomy (or any labelled shape) and the multi-domain tetrahedral
//! mesher: a labelled implicit description of space, and the volume of each of its regions.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// A labelled implicit domain: regions 1..=`region_count()`, label 0 outside every region.
///
/// Implementors must be cheap to query and thread-safe: the mesher samples them on lattices
/// in parallel.
pub trait LabelledDomain: Sync {
    /// Axis-aligned bounds (min, max corner, mm) enclosing every region.
    fn bounds(&self) -> (Point3<f64>, Point3<f64>);
    /// Number of regions; labels run 1..=region_count.
    fn region_count(&self) -> u16;
    /// The region at `p` (0 = outside all regions).
    fn label(&self, p: &Point3<f64>) -> u16;
    /// Signed distance (mm) from `p` to the boundary of region `region`: negative inside.
    /// It need not be exact, but must have the right sign and be 1-Lipschitz or close to it.
    fn signed_distance(&self, region: u16, p: &Point3<f64>) -> f64;
}

/// Sub-cells per block edge in [`region_volumes`]: a block is `SUBDIVISION` sample spacings
/// wide, and one that a boundary may cross is sampled at all `SUBDIVISION³` sub-cell centres.
const SUBDIVISION: usize = 4;

/// How far (in block half-diagonals) a block's centre must lie from every boundary for the
/// whole block to take the centre's label: 2, room for a signed distance that is only close
/// to 1-Lipschitz.
const CLEARANCE_MARGIN: f64 = 2.0;

/// The volume (mm³) of each region of `domain`, indexed by label (index 0, outside, is 0):
/// the midpoint rule on a lattice of cells `spacing_mm` wide over the domain's bounds.
///
/// Blocks of 4 × 4 × 4 cells whose centre lies, by the signed distances, farther than twice
/// the block's half-diagonal from every region boundary are counted whole with the centre's
/// label, and every other block cell by cell, so the result is the full lattice's at a
/// fraction of its label queries (near 5 % for the anatomy at 0.05 mm). Its error is that of
/// the midpoint rule: under 1 % for the anatomy's regions at 0.05 mm, about 0.3 mm thick and
/// more (a test compares it with the full lattice and with a shape of known volume).
pub fn region_volumes<D: LabelledDomain + ?Sized>(domain: &D, spacing_mm: f64) -> Vec<f64> {
    let regions = usize::from(domain.region_count());
    let (lo, hi) = domain.bounds();
    let block = spacing_mm * SUBDIVISION as f64;
    let blocks = (hi - lo).map(|v| (v / block).ceil().max(1.0) as usize);
    let half_diagonal = 0.5 * block * 3f64.sqrt();
    let cell = spacing_mm.powi(3);
    let counts = (0..blocks.z)
        .into_par_iter()
        .map(|k| {
            let mut counts = vec![0u64; regions + 1];
            for j in 0..blocks.y {
                for i in 0..blocks.x {
                    let corner = lo + Vector3::new(i as f64, j as f64, k as f64) * block;
                    let centre = corner + Vector3::repeat(0.5 * block);
                    let label = domain.label(&centre);
                    let clearance = if label > 0 {
                        -domain.signed_distance(label, &centre)
                    } else {
                        (1..=domain.region_count())
                            .map(|r| domain.signed_distance(r, &centre))
                            .fold(f64::INFINITY, f64::min)
                    };
                    if clearance > CLEARANCE_MARGIN * half_diagonal {
                        if let Some(n) = counts.get_mut(usize::from(label)) {
                            *n += (SUBDIVISION as u64).pow(3);
                        }
                    } else {
                        count_cells(domain, &corner, spacing_mm, &mut counts);
                    }
                }
            }
            counts
        })
        .reduce(
            || vec![0u64; regions + 1],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let mut volumes: Vec<f64> = counts.iter().map(|&n| n as f64 * cell).collect();
    if let Some(outside) = volumes.first_mut() {
        *outside = 0.0;
    }
    volumes
}

/// Adds the label at the centre of each of the `SUBDIVISION³` cells of the block whose lowest
/// corner is `corner` to `counts` (indexed by label; a label beyond them is not counted).
fn count_cells<D: LabelledDomain + ?Sized>(
    domain: &D,
    corner: &Point3<f64>,
    spacing_mm: f64,
    counts: &mut [u64],
) {
    for n in 0..SUBDIVISION.pow(3) {
        let (a, b, c) = (
            n % SUBDIVISION,
            n / SUBDIVISION % SUBDIVISION,
            n / (SUBDIVISION * SUBDIVISION),
        );
        let offset = Vector3::new(a as f64, b as f64, c as f64).add_scalar(0.5) * spacing_mm;
        if let Some(count) = counts.get_mut(usize::from(domain.label(&(corner + offset)))) {
            *count += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::mesher::tests::CoreShell;

    #[test]
    fn a_ball_in_a_shell_has_its_analytic_volumes() {
        let v = region_volumes(&CoreShell, 0.02);
        let ball = 4.0 / 3.0 * std::f64::consts::PI;
        let shell = 7.0 * ball;
        assert_eq!(v.len(), 3);
        assert_eq!(v[0], 0.0);
        assert!((v[1] / ball - 1.0).abs() < 0.002, "{} vs {ball}", v[1]);
        assert!((v[2] / shell - 1.0).abs() < 0.002, "{} vs {shell}", v[2]);
    }

    #[test]
    fn skipping_blocks_far_from_every_boundary_changes_nothing() {
        // the full lattice of the same cells, every cell labelled
        let h = 0.05;
        let (lo, hi) = CoreShell.bounds();
        let n = (hi - lo).map(|v| (v / (h * SUBDIVISION as f64)).ceil() as usize * SUBDIVISION);
        let mut counts = [0u64; 3];
        for k in 0..n.z {
            for j in 0..n.y {
                for i in 0..n.x {
                    let p = lo + Vector3::new(i as f64, j as f64, k as f64).add_scalar(0.5) * h;
                    counts[usize::from(CoreShell.label(&p))] += 1;
                }
            }
        }
        let v = region_volumes(&CoreShell, h);
        for l in 1..3 {
            assert!(
                (v[l] - counts[l] as f64 * h.powi(3)).abs() < 1e-12,
                "label {l}"
            );
        }
    }
}
