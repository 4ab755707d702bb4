//! The interface between an anatomy (or any labelled shape) and the multi-domain tetrahedral
//! mesher: a labelled implicit description of space.

use nalgebra::Point3;

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
