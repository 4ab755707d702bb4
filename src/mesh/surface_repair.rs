//! A closed surface from another tool made fit for inside tests: corners at the same place
//! welded, triangles turned to agree with their neighbours, each piece turned outward, specks
//! dropped, small holes closed. Segmentation exports carry such defects (islands of a few
//! voxels, a triangle soup, a hand edit that flipped faces), and a signed distance read from
//! pseudonormals is wrong near every one of them, silently. What was changed is returned, so
//! that the caller can say it; what cannot be mended (a large opening, a surface that cannot
//! be oriented) is refused with its figures.
//!
//! Orientation: triangles joined by an edge that only they share are oriented alike by a
//! breadth-first walk; each patch so joined keeps the orientation most of its triangles had
//! (a few flipped faces are the exception, not the rule), and a piece enclosing a negative
//! volume is turned whole (the inward-facing export). Pieces are told apart by shared
//! vertices, so that a specimen's part touching the rest at one corner is kept.

use std::collections::HashMap;

use nalgebra::Point3;

use super::TriMesh;
use super::topology::UnionFind;

/// What counts as a speck, and how large a hole may be closed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepairOptions {
    /// A piece enclosing less than this share of the largest piece's volume is dropped.
    pub speck_share: f64,
    /// Holes at most this far around are closed by a fan; larger openings are refused (mm).
    /// The default, 2 mm, closes a few missing triangles of a segmentation's mesh and refuses
    /// a cut that opens an ossicle (about 1.5 mm thick).
    pub max_hole_perimeter_mm: f64,
}

impl Default for RepairOptions {
    fn default() -> Self {
        RepairOptions {
            speck_share: 0.01,
            max_hole_perimeter_mm: 2.0,
        }
    }
}

/// What the repair changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceRepair {
    /// Vertices merged into another at the same coordinates.
    pub welded_vertices: usize,
    /// Triangles dropped for using one vertex twice (after welding).
    pub degenerate_triangles: usize,
    /// Triangles turned to agree with their neighbours.
    pub turned_triangles: usize,
    /// Pieces turned whole because they enclosed a negative volume, with that volume (mm³).
    pub turned_pieces: Vec<f64>,
    /// Pieces dropped as specks, with their volume (mm³), and the largest piece's.
    pub dropped_pieces: Vec<f64>,
    pub largest_piece_mm3: f64,
    /// Holes closed, by their number of edges.
    pub closed_holes: Vec<usize>,
}

impl SurfaceRepair {
    /// True when nothing was changed.
    pub fn is_empty(&self) -> bool {
        self.welded_vertices == 0
            && self.degenerate_triangles == 0
            && self.turned_triangles == 0
            && self.turned_pieces.is_empty()
            && self.dropped_pieces.is_empty()
            && self.closed_holes.is_empty()
    }

    /// One sentence per change, for a log or a note.
    pub fn describe(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.welded_vertices > 0 {
            out.push(format!(
                "{} vertices at the same place as another welded",
                self.welded_vertices
            ));
        }
        if self.degenerate_triangles > 0 {
            out.push(format!(
                "{} triangles with a repeated corner dropped",
                self.degenerate_triangles
            ));
        }
        if self.turned_triangles > 0 {
            out.push(format!(
                "{} triangles turned to agree with their neighbours",
                self.turned_triangles
            ));
        }
        if !self.turned_pieces.is_empty() {
            let volumes: Vec<String> = self
                .turned_pieces
                .iter()
                .map(|v| format!("{v:.3}"))
                .collect();
            out.push(format!(
                "triangles facing inward (enclosed volume {} mm³) turned outward",
                volumes.join(", ")
            ));
        }
        if !self.dropped_pieces.is_empty() {
            let volumes: Vec<String> = self
                .dropped_pieces
                .iter()
                .map(|v| format!("{:.4}", v.abs()))
                .collect();
            out.push(format!(
                "{} separate piece(s) of {} mm³ dropped as specks (the largest piece encloses {:.2} mm³)",
                self.dropped_pieces.len(),
                volumes.join(", "),
                self.largest_piece_mm3
            ));
        }
        if !self.closed_holes.is_empty() {
            let edges: Vec<String> = self.closed_holes.iter().map(|n| n.to_string()).collect();
            out.push(format!(
                "{} hole(s) closed (bounded by {} edges)",
                self.closed_holes.len(),
                edges.join(", ")
            ));
        }
        out
    }
}

/// Why a surface cannot be made closed and oriented.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RepairError {
    #[error("no triangles (after dropping those with a repeated corner)")]
    Empty,
    #[error(
        "an opening {perimeter_mm:.2} mm around (bounded by {edges} edges) at ({x:.2}, {y:.2}, {z:.2}) mm; expected a closed surface (holes up to {max:.1} mm around are closed)",
        x = at[0], y = at[1], z = at[2]
    )]
    Opening {
        edges: usize,
        perimeter_mm: f64,
        at: [f64; 3],
        max: f64,
    },
    #[error(
        "cannot be oriented: {conflicts} edges join triangles that no choice of sides makes agree"
    )]
    NotOrientable { conflicts: usize },
}

/// The repaired surface and what was changed; `mesh` itself is left as it is.
pub fn repair_closed_surface(
    mesh: &TriMesh,
    options: RepairOptions,
) -> Result<(TriMesh, SurfaceRepair), RepairError> {
    let mut report = SurfaceRepair::default();
    let mut surface = welded(mesh, &mut report);
    if surface.triangles.is_empty() {
        return Err(RepairError::Empty);
    }
    orient_patches(&mut surface, &mut report)?;
    let pieces = pieces(&surface);
    let volumes: Vec<f64> = pieces
        .iter()
        .map(|piece| piece.iter().map(|&t| surface.origin_tetra_volume(t)).sum())
        .collect();
    let largest = volumes.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    report.largest_piece_mm3 = largest;
    let mut keep = vec![true; surface.triangles.len()];
    for (piece, v) in pieces.iter().zip(&volumes) {
        if v.abs() < options.speck_share * largest {
            piece.iter().for_each(|&t| keep[t] = false);
            report.dropped_pieces.push(v.abs());
        } else if *v < 0.0 {
            piece.iter().for_each(|&t| surface.triangles[t].swap(1, 2));
            report.turned_pieces.push(*v);
        }
    }
    let mut surface = surface.kept(&keep);
    close_holes(&mut surface, options.max_hole_perimeter_mm, &mut report)?;
    if report.is_empty() {
        // as it came, vertex order too
        return Ok((mesh.clone(), report));
    }
    Ok((surface, report))
}

/// `mesh` with corners at bit-identical coordinates merged and triangles that then repeat a
/// corner dropped.
fn welded(mesh: &TriMesh, report: &mut SurfaceRepair) -> TriMesh {
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let map: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|p| {
            let key = [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits());
            *index.entry(key).or_insert_with(|| {
                vertices.push(*p);
                (vertices.len() - 1) as u32
            })
        })
        .collect();
    report.welded_vertices = mesh.vertices.len() - vertices.len();
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| map[v as usize]);
        if a == b || b == c || a == c {
            report.degenerate_triangles += 1;
        } else {
            triangles.push([a, b, c]);
        }
    }
    TriMesh::compacted(&triangles, &vertices)
}

/// The triangles using each undirected edge, with whether they run it from its lower vertex.
fn edge_uses(mesh: &TriMesh) -> HashMap<(u32, u32), Vec<(usize, bool)>> {
    let mut edges: HashMap<(u32, u32), Vec<(usize, bool)>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            edges
                .entry((a.min(b), a.max(b)))
                .or_default()
                .push((t, a < b));
        }
    }
    edges
}

/// Orients each patch of triangles joined by two-triangle edges alike, keeping the
/// orientation most of its triangles had.
fn orient_patches(mesh: &mut TriMesh, report: &mut SurfaceRepair) -> Result<(), RepairError> {
    let edges = edge_uses(mesh);
    let n = mesh.triangles.len();
    let mut neighbours: Vec<Vec<(usize, bool)>> = vec![Vec::new(); n];
    for uses in edges.values() {
        if let [(s, fs), (t, ft)] = uses.as_slice() {
            // agreeing triangles run a shared edge in opposite directions
            let same_direction = fs == ft;
            neighbours[*s].push((*t, same_direction));
            neighbours[*t].push((*s, same_direction));
        }
    }
    let mut flip: Vec<Option<bool>> = vec![None; n];
    let mut conflicts = 0usize;
    for seed in 0..n {
        if flip[seed].is_some() {
            continue;
        }
        flip[seed] = Some(false);
        let mut patch = vec![seed];
        let mut next = 0;
        while next < patch.len() {
            let s = patch[next];
            next += 1;
            let fs = flip[s].unwrap_or(false);
            for &(t, same_direction) in &neighbours[s] {
                let wanted = fs ^ same_direction;
                match flip[t] {
                    None => {
                        flip[t] = Some(wanted);
                        patch.push(t);
                    }
                    Some(f) if f != wanted => conflicts += 1,
                    Some(_) => {}
                }
            }
        }
        let flipped = patch.iter().filter(|&&t| flip[t] == Some(true)).count();
        if 2 * flipped > patch.len() {
            patch.iter().for_each(|&t| flip[t] = flip[t].map(|f| !f));
        }
    }
    if conflicts > 0 {
        // each conflicting edge is seen from both of its triangles
        return Err(RepairError::NotOrientable {
            conflicts: conflicts.div_ceil(2),
        });
    }
    for (tri, f) in mesh.triangles.iter_mut().zip(&flip) {
        if *f == Some(true) {
            tri.swap(1, 2);
            report.turned_triangles += 1;
        }
    }
    Ok(())
}

/// The triangles of each piece: joined through any shared vertex (a piece touching the rest
/// at one corner, as a tetrahedral mesh's boundary can, is not a speck).
fn pieces(mesh: &TriMesh) -> Vec<Vec<usize>> {
    let mut uf = UnionFind::new(mesh.vertices.len());
    for [a, b, c] in &mesh.triangles {
        uf.union(*a, *b);
        uf.union(*b, *c);
    }
    let mut by_root: HashMap<u32, usize> = HashMap::new();
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let root = uf.find(tri[0]);
        let k = *by_root.entry(root).or_insert_with(|| {
            out.push(Vec::new());
            out.len() - 1
        });
        out[k].push(t);
    }
    out
}

/// Closes each hole up to `max_perimeter_mm` around by a fan about its corners' centroid.
fn close_holes(
    mesh: &mut TriMesh,
    max_perimeter_mm: f64,
    report: &mut SurfaceRepair,
) -> Result<(), RepairError> {
    // border edges as the triangles run them; a hole is walked along them
    let mut outgoing: HashMap<u32, Vec<u32>> = HashMap::new();
    for (&(a, b), uses) in &edge_uses(mesh) {
        if let [(_, from_lower)] = uses.as_slice() {
            let (from, to) = if *from_lower { (a, b) } else { (b, a) };
            outgoing.entry(from).or_default().push(to);
        }
    }
    let mut starts: Vec<u32> = outgoing.keys().copied().collect();
    starts.sort_unstable();
    for start in starts {
        while let Some(first) = outgoing.get_mut(&start).and_then(Vec::pop) {
            let mut border = vec![(start, first)];
            let mut at = first;
            while at != start {
                let Some(to) = outgoing.get_mut(&at).and_then(Vec::pop) else {
                    break;
                };
                border.push((at, to));
                at = to;
            }
            let perimeter_mm: f64 = border
                .iter()
                .map(|&(a, b)| (mesh.vertices[a as usize] - mesh.vertices[b as usize]).norm())
                .sum();
            let centre = Point3::from(
                border
                    .iter()
                    .fold(nalgebra::Vector3::zeros(), |s, &(a, _)| {
                        s + mesh.vertices[a as usize].coords
                    })
                    / border.len() as f64,
            );
            if perimeter_mm > max_perimeter_mm || at != start {
                return Err(RepairError::Opening {
                    edges: border.len(),
                    perimeter_mm,
                    at: [centre.x, centre.y, centre.z],
                    max: max_perimeter_mm,
                });
            }
            let c = mesh.vertices.len() as u32;
            mesh.vertices.push(centre);
            mesh.triangles
                .extend(border.iter().map(|&(a, b)| [b, a, c]));
            report.closed_holes.push(border.len());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes::icosphere;
    use crate::mesh::topology::surface_topology;

    fn ball() -> TriMesh {
        icosphere(Point3::new(1.0, 2.0, 3.0), 2.0, 3)
    }

    /// A clean closed surface comes back as it was, and nothing is reported.
    #[test]
    fn a_clean_surface_is_left_as_it_is() {
        let m = ball();
        let (r, report) = repair_closed_surface(&m, RepairOptions::default()).unwrap();
        assert!(r == m, "the surface was changed");
        assert!(report.is_empty(), "{report:?}");
        assert!(report.describe().is_empty());
    }

    /// Every third triangle flipped: turned back, the surface is the ball again triangle for
    /// triangle; the whole ball inward is turned outward as one piece.
    #[test]
    fn flipped_triangles_and_an_inward_surface_are_turned_back() {
        let m = ball();
        let mut bad = m.clone();
        bad.triangles
            .iter_mut()
            .step_by(3)
            .for_each(|t| t.swap(0, 1));
        assert!(surface_topology(&bad).misoriented_edges > 0);
        let (r, report) = repair_closed_surface(&bad, RepairOptions::default()).unwrap();
        assert_eq!(report.turned_triangles, m.triangles.len().div_ceil(3));
        assert!(surface_topology(&r).is_closed_oriented_manifold());
        assert!((r.signed_volume() - m.signed_volume()).abs() < 1e-9);
        let mut inward = m.clone();
        inward.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        let (r, report) = repair_closed_surface(&inward, RepairOptions::default()).unwrap();
        assert_eq!(report.turned_triangles, 0);
        assert_eq!(report.turned_pieces.len(), 1);
        assert!(report.turned_pieces[0] < 0.0);
        assert!((r.signed_volume() - m.signed_volume()).abs() < 1e-9);
    }

    /// A tiny ball beside the large one is dropped; a second ball of a tenth the volume is a
    /// piece, not a speck, and stays.
    #[test]
    fn specks_are_dropped_and_pieces_kept() {
        let big = ball();
        let speck = icosphere(Point3::new(9.0, 0.0, 0.0), 0.3, 1);
        let small = icosphere(Point3::new(-9.0, 0.0, 0.0), 0.93, 2);
        let m = TriMesh::concatenated(&[&big, &speck, &small]);
        let (r, report) = repair_closed_surface(&m, RepairOptions::default()).unwrap();
        assert_eq!(report.dropped_pieces.len(), 1);
        assert!((report.dropped_pieces[0] - speck.signed_volume()).abs() < 1e-12);
        assert_eq!(
            r.triangles.len(),
            big.triangles.len() + small.triangles.len()
        );
        let v = big.signed_volume() + small.signed_volume();
        assert!((r.signed_volume() - v).abs() < 1e-9);
    }

    /// Two holes punched (one triangle, and the fan of five around a vertex) are closed: the
    /// surface is closed and oriented and encloses within 0.5 % of the ball's volume. An
    /// opening larger than the limit is refused with its size.
    #[test]
    fn small_holes_are_closed_and_large_openings_refused() {
        let m = ball();
        let mut holed = m.clone();
        holed.triangles.remove(10);
        let v0 = holed.triangles[0][0];
        holed.triangles.retain(|t| !t.contains(&v0));
        let (r, report) = repair_closed_surface(&holed, RepairOptions::default()).unwrap();
        let mut holes = report.closed_holes.clone();
        holes.sort_unstable();
        assert_eq!(holes, vec![3, 5]);
        assert!(surface_topology(&r).is_closed_oriented_manifold());
        let rel = (r.signed_volume() - m.signed_volume()).abs() / m.signed_volume();
        assert!(rel < 0.005, "{rel}");
        // a cap of the ball cut away: one opening of many edges
        let mut cut = m.clone();
        cut.triangles
            .retain(|t| t.iter().all(|&v| m.vertices[v as usize].z < 3.0));
        let err = repair_closed_surface(&cut, RepairOptions::default()).unwrap_err();
        let RepairError::Opening { perimeter_mm, .. } = err else {
            panic!("{err:?}");
        };
        // the equator's zigzag, longer than the circle's 12.6 mm
        assert!(perimeter_mm > 12.5, "{perimeter_mm}");
        assert!(
            err.to_string().contains("expected a closed surface"),
            "{err}"
        );
    }

    /// A triangle soup (each triangle its own three corners, as in STL) is welded into the
    /// closed ball.
    #[test]
    fn a_triangle_soup_is_welded() {
        let m = ball();
        let mut soup = TriMesh::default();
        for t in 0..m.triangles.len() {
            let base = soup.vertices.len() as u32;
            soup.vertices.extend(m.corners(t));
            soup.triangles.push([base, base + 1, base + 2]);
        }
        let (r, report) = repair_closed_surface(&soup, RepairOptions::default()).unwrap();
        assert_eq!(r.vertices.len(), m.vertices.len());
        assert_eq!(
            report.welded_vertices,
            soup.vertices.len() - m.vertices.len()
        );
        assert!(surface_topology(&r).is_closed_oriented_manifold());
    }
}
