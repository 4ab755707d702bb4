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
//!
//! Only triangles near another part need that part's signed distance, whose query is slow far
//! from a surface. A triangle whose centroid has no point of part j within `reach` (its part's
//! longest edge plus twice the contact distance, a cheap bounded query) is on the same side of
//! j as its edge-neighbours that are also that far: the segment between their probes cannot
//! reach j. So each connected patch of such triangles takes one signed query, and the patch's
//! triangles share its answer (the same result as querying each, far faster: most of a bone's
//! surface is far from the others).

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
        let probes: Vec<Option<(Point3<f64>, Point3<f64>)>> = (0..part.triangles.len())
            .into_par_iter()
            .map(|t| {
                let normal = part.area_normal2(t).try_normalize(0.0)?;
                let centre = part.triangle_centroid(t);
                Some((centre, centre + normal * CONTACT_MM))
            })
            .collect();
        let reach = longest_edge(part) + 2.0 * CONTACT_MM;
        let mut keep: Vec<bool> = probes.iter().map(Option::is_some).collect();
        for (j, other) in indexed.iter().enumerate().filter(|(j, _)| *j != i) {
            let beside = |t: usize| -> Side {
                let Some((centre, probe)) = probes[t].filter(|_| keep[t]) else {
                    // degenerate, or dropped already by an earlier part: nothing to ask
                    return Side::Hidden;
                };
                if !near_box(other.bounds(), &centre, reach) {
                    return Side::Outside;
                }
                if !other.bvh.any_within(&centre, reach) {
                    return Side::Far;
                }
                let outside = other.signed_distance(&probe) > 0.0;
                // on a face of an earlier part with the same outward side: kept there
                let shared_earlier = j < i && other.signed_distance(&centre).abs() <= CONTACT_MM;
                if outside && !shared_earlier {
                    Side::Outside
                } else {
                    Side::Hidden
                }
            };
            let mut sides: Vec<Side> = (0..part.triangles.len())
                .into_par_iter()
                .map(beside)
                .collect();
            resolve_far_patches(part, &mut sides, |t| {
                probes[t].is_some_and(|(_, probe)| other.signed_distance(&probe) > 0.0)
            });
            for (k, side) in keep.iter_mut().zip(&sides) {
                *k &= *side == Side::Outside;
            }
        }
        pieces.push(part.kept(&keep));
    }
    Ok(TriMesh::concatenated(&pieces.iter().collect::<Vec<_>>()))
}

/// Where a triangle of one part lies with respect to another part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    /// Outside it (kept, as far as that part decides).
    Outside,
    /// Inside it, or on a face an earlier part keeps (dropped).
    Hidden,
    /// Too far from it to have been asked: decided by its patch.
    Far,
}

/// Decides every `Side::Far` triangle of `part`: each patch of edge-connected far triangles
/// is outside or hidden as a whole, as `outside(t)` says for its first triangle.
fn resolve_far_patches(part: &TriMesh, sides: &mut [Side], outside: impl Fn(usize) -> bool) {
    if !sides.contains(&Side::Far) {
        return;
    }
    let mut edges: Vec<(u32, u32, usize)> = part
        .triangles
        .iter()
        .enumerate()
        .filter(|(t, _)| sides[*t] == Side::Far)
        .flat_map(|(t, [a, b, c])| {
            [(*a, *b), (*b, *c), (*c, *a)].map(|(p, q)| (p.min(q), p.max(q), t))
        })
        .collect();
    edges.sort_unstable();
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); sides.len()];
    for run in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        for x in run {
            neighbours[x.2].extend(run.iter().filter(|y| y.2 != x.2).map(|y| y.2));
        }
    }
    let mut stack = Vec::new();
    for seed in 0..sides.len() {
        if sides[seed] != Side::Far {
            continue;
        }
        let side = if outside(seed) {
            Side::Outside
        } else {
            Side::Hidden
        };
        sides[seed] = side;
        stack.push(seed);
        while let Some(t) = stack.pop() {
            for &n in &neighbours[t] {
                if sides[n] == Side::Far {
                    sides[n] = side;
                    stack.push(n);
                }
            }
        }
    }
}

/// The longest edge of `mesh`'s triangles (mm).
fn longest_edge(mesh: &TriMesh) -> f64 {
    (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            (b - a).norm().max((c - b).norm()).max((a - c).norm())
        })
        .fold(0.0, f64::max)
}

/// Whether `p` lies within `margin` of the box (`lo`, `hi`): outside it (a margin of at least
/// twice `CONTACT_MM`), `p` and its probe are outside the part the box bounds, and need no
/// closest-point query.
fn near_box((lo, hi): (Point3<f64>, Point3<f64>), p: &Point3<f64>, margin: f64) -> bool {
    (0..3).all(|k| p[k] >= lo[k] - margin && p[k] <= hi[k] + margin)
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

    /// Every triangle asked about every other part, the way the patches stand in for.
    fn outer_surface_one_by_one(parts: &[&TriMesh]) -> TriMesh {
        let indexed: Vec<SignedSurface> = parts
            .iter()
            .map(|p| SignedSurface::new(p, "test").unwrap())
            .collect();
        let pieces: Vec<TriMesh> = parts
            .iter()
            .enumerate()
            .map(|(i, part)| {
                let kept: Vec<[u32; 3]> = (0..part.triangles.len())
                    .filter(|&t| {
                        let Some(normal) = part.area_normal2(t).try_normalize(0.0) else {
                            return false;
                        };
                        let centre = part.triangle_centroid(t);
                        let probe = centre + normal * CONTACT_MM;
                        indexed.iter().enumerate().all(|(j, other)| {
                            j == i
                                || (other.signed_distance(&probe) > 0.0
                                    && !(j < i
                                        && other.signed_distance(&centre).abs() <= CONTACT_MM))
                        })
                    })
                    .map(|t| part.triangles[t])
                    .collect();
                TriMesh::compacted(&kept, &part.vertices)
            })
            .collect();
        TriMesh::concatenated(&pieces.iter().collect::<Vec<_>>())
    }

    /// Spheres and boxes crossing each other, one sphere inside another (at least 0.5 from
    /// its surface, so one far patch) and one apart: the patches give the triangles that
    /// asking each triangle gives.
    #[test]
    fn far_patches_decide_as_every_triangle_asked_would() {
        let parts = [
            icosphere(Point3::new(0.0, 0.0, 0.0), 1.0, 3),
            icosphere(Point3::new(1.2, 0.3, 0.0), 0.8, 3),
            cube(0.5, 1.0, 12),
            icosphere(Point3::new(-0.2, 0.1, 0.0), 0.3, 2),
            icosphere(Point3::new(6.0, 0.0, 0.0), 0.5, 2),
            cube(0.4, 1.0, 12),
        ];
        let refs: Vec<&TriMesh> = parts.iter().collect();
        let fast = outer_surface(&refs, "test").unwrap();
        let slow = outer_surface_one_by_one(&refs);
        assert_eq!(fast.triangles.len(), slow.triangles.len());
        assert_eq!(fast, slow);
        // the inner sphere is dropped whole, the lone sphere kept whole
        let near =
            |c: Point3<f64>, r: f64| fast.vertices.iter().filter(|v| (*v - c).norm() < r).count();
        assert_eq!(near(Point3::new(-0.2, 0.1, 0.0), 0.31), 0);
        assert_eq!(
            near(Point3::new(6.0, 0.0, 0.0), 0.51),
            parts[4].vertices.len()
        );
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
