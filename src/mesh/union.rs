//! The outer surface of several closed surfaces taken as one solid: what an image shows of
//! parts that touch or overlap, such as the ossicles of a chain, whose joints a CT cannot
//! separate. Scoring a chain as one solid compares this surface, not the faces where one
//! ossicle's label ends and the next begins inside the bone.
//!
//! A triangle of one part is kept when a point just off its centroid, along its outward
//! normal, lies outside every other part. So a face that two parts share with opposite
//! orientations (a contact) is inside the union and dropped from both, a face shared with the
//! same orientation is kept once (from the first part), and a face inside another part is
//! dropped. A triangle that crosses another part's surface is kept or dropped whole, so the
//! result is exact up to one triangle's size along the curves where parts cross, and is an
//! open surface there.

use nalgebra::Point3;
use rayon::prelude::*;

use super::TriMesh;
use super::spatial::{SignedSurface, SpatialError};
use super::topology::surface_topology;

/// Why parts have no outer surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnionError {
    #[error(transparent)]
    Spatial(#[from] SpatialError),
    #[error(
        "{role} part {index}: not a closed, consistently oriented surface; expected one, since its inside decides what it hides of the others"
    )]
    NotClosed { role: &'static str, index: usize },
}

/// How far off a centroid the inside test probes, and how near another part's surface a
/// centroid counts as on it [mm]: far above the rounding of coordinates stored as 32-bit
/// floats (~1e-5 mm at 100 mm from the origin), far below any anatomical size.
const CONTACT_MM: f64 = 1e-3;

/// The outer surface of the solid that `parts` (closed, outward-oriented surfaces) bound
/// together, with only the vertices it uses; `role` names the parts in errors.
pub fn outer_surface(parts: &[&TriMesh], role: &'static str) -> Result<TriMesh, UnionError> {
    // pinched vertices and edges of more than two faces leave inside and outside defined
    let closed = |p: &TriMesh| {
        let t = surface_topology(p);
        t.border_edges == 0 && t.misoriented_edges == 0
    };
    if let Some(index) = parts.iter().position(|p| !closed(p)) {
        return Err(UnionError::NotClosed { role, index });
    }
    let indexed = parts
        .par_iter()
        .map(|p| SignedSurface::new(p, role))
        .collect::<Result<Vec<_>, _>>()?;
    let mut pieces = Vec::with_capacity(parts.len());
    for (i, part) in parts.iter().enumerate() {
        let keep: Vec<bool> = (0..part.triangles.len())
            .into_par_iter()
            .map(|t| {
                let Some(normal) = part.area_normal2(t).try_normalize(0.0) else {
                    return false;
                };
                let centre = part.triangle_centroid(t);
                let probe: Point3<f64> = centre + normal * CONTACT_MM;
                indexed.iter().enumerate().all(|(j, other)| {
                    if j == i || !near_box(other.bounds(), &centre) {
                        return true;
                    }
                    let outside = other.signed_distance(&probe) > 0.0;
                    // on a face of an earlier part with the same outward side: kept there
                    let shared_earlier =
                        j < i && other.signed_distance(&centre).abs() <= CONTACT_MM;
                    outside && !shared_earlier
                })
            })
            .collect();
        let kept: Vec<[u32; 3]> = part
            .triangles
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(t, _)| *t)
            .collect();
        pieces.push(TriMesh::compacted(&kept, &part.vertices));
    }
    Ok(TriMesh::concatenated(&pieces.iter().collect::<Vec<_>>()))
}

/// Whether `p` lies within `CONTACT_MM` of the box (`lo`, `hi`): outside it, `p` and its probe
/// are outside the part the box bounds, and need no closest-point query.
fn near_box((lo, hi): (Point3<f64>, Point3<f64>), p: &Point3<f64>) -> bool {
    (0..3).all(|k| p[k] >= lo[k] - 2.0 * CONTACT_MM && p[k] <= hi[k] + 2.0 * CONTACT_MM)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::{box_mesh, icosphere};

    fn cube(x0: f64, size: f64, divisions: usize) -> TriMesh {
        box_mesh(
            Point3::new(x0, 0.0, 0.0),
            Point3::new(x0 + size, size, size),
            divisions,
        )
    }

    #[test]
    fn two_cubes_sharing_a_face_are_one_box() {
        // [0,1]³ and [1,2]x[0,1]²: the face x = 1 is inside the union, from both sides
        let (a, b) = (cube(0.0, 1.0, 4), cube(1.0, 1.0, 4));
        let union = outer_surface(&[&a, &b], "test").unwrap();
        assert!((union.area() - 10.0).abs() < 1e-9, "{}", union.area());
        assert!((union.signed_volume() - 2.0).abs() < 1e-9);
        assert!(union.vertices.iter().all(|v| v.x >= 0.0 && v.x <= 2.0));
    }

    #[test]
    fn a_part_inside_another_adds_nothing_and_a_copy_counts_once() {
        let big = cube(0.0, 2.0, 4);
        let small = icosphere(Point3::new(1.0, 1.0, 1.0), 0.5, 2);
        let union = outer_surface(&[&big, &small, &big], "test").unwrap();
        assert!((union.area() - 24.0).abs() < 1e-9, "{}", union.area());
        assert_eq!(union.triangles.len(), big.triangles.len());
    }

    #[test]
    fn overlapping_parts_lose_what_the_other_encloses_to_within_a_triangle() {
        // unit cubes overlapping by half: the union is a 1.5 x 1 x 1 box (area 8); triangles
        // across the other cube's faces are kept or dropped whole
        let (a, b) = (cube(0.0, 1.0, 40), cube(0.5, 1.0, 40));
        let union = outer_surface(&[&a, &b], "test").unwrap();
        // one strip of triangles (1/40 wide) on each of the four sides may go either way
        assert!((union.area() - 8.0).abs() <= 4.0 / 40.0, "{}", union.area());
        assert!(union.area() < a.area() + b.area() - 2.0);
    }

    #[test]
    fn an_open_part_is_refused_by_its_index() {
        let mut open = cube(1.0, 1.0, 2);
        open.triangles.pop();
        let err = outer_surface(&[&cube(0.0, 1.0, 1), &open], "reference").unwrap_err();
        assert_eq!(
            err,
            UnionError::NotClosed {
                role: "reference",
                index: 1
            }
        );
    }
}
