//! Analytic test shapes as closed, outward-oriented `TriMesh`es: an icosphere, a subdivided
//! axis-aligned box and a torus. They give surface-distance, sampling and registration tests
//! an exact geometric truth (sphere 4πr², 4/3·πr³; box; torus 4π²Rr, 2π²Rr²).

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};

use super::TriMesh;

/// An icosahedron subdivided `subdivisions` times (each step splits every triangle into four),
/// with every vertex projected onto the sphere of `radius` about `centre`:
/// 12 + 10·(4^s − 1) vertices and 20·4^s triangles.
pub fn icosphere(centre: Point3<f64>, radius: f64, subdivisions: u32) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut dirs: Vec<Vector3<f64>> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&[x, y, z]| Vector3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, dirs: &mut Vec<Vector3<f64>>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = (dirs[a as usize] + dirs[b as usize]).normalize();
                dirs.push(m);
                (dirs.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for &[a, b, c] in &triangles {
            let ab = midpoint(a, b, &mut dirs);
            let bc = midpoint(b, c, &mut dirs);
            let ca = midpoint(c, a, &mut dirs);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    TriMesh {
        vertices: dirs.iter().map(|d| centre + d * radius).collect(),
        triangles,
    }
}

/// The axis-aligned box `[min, max]` with each face split into `divisions` × `divisions`
/// quads (two triangles each); shared edge and corner vertices are merged, so the surface is
/// closed. `divisions` of 0 is treated as 1.
pub fn box_mesh(min: Point3<f64>, max: Point3<f64>, divisions: usize) -> TriMesh {
    let n = divisions.max(1);
    let mut index: HashMap<[usize; 3], u32> = HashMap::new();
    let mut mesh = TriMesh::default();
    // (fixed axis, fixed at max?, u axis, v axis) with u × v = outward normal.
    let faces = [
        (0, true, 1, 2),
        (0, false, 2, 1),
        (1, true, 2, 0),
        (1, false, 0, 2),
        (2, true, 0, 1),
        (2, false, 1, 0),
    ];
    for &(axis, at_max, u, v) in &faces {
        let mut vertex = |i: usize, j: usize| -> u32 {
            let mut lattice = [0usize; 3];
            lattice[axis] = if at_max { n } else { 0 };
            lattice[u] = i;
            lattice[v] = j;
            *index.entry(lattice).or_insert_with(|| {
                let coord = |k: usize| min[k] + (max[k] - min[k]) * lattice[k] as f64 / n as f64;
                mesh.vertices
                    .push(Point3::new(coord(0), coord(1), coord(2)));
                (mesh.vertices.len() - 1) as u32
            })
        };
        let mut quads = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                quads.push([
                    vertex(i, j),
                    vertex(i + 1, j),
                    vertex(i + 1, j + 1),
                    vertex(i, j + 1),
                ]);
            }
        }
        for [a, b, c, d] in quads {
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
    mesh
}

/// A torus about the z axis through the origin: major radius `major` (centre of the tube),
/// minor radius `minor` (tube), `nu` segments around the axis and `nv` around the tube
/// (each at least 3), 2·nu·nv triangles.
pub fn torus(major: f64, minor: f64, nu: usize, nv: usize) -> TriMesh {
    let (nu, nv) = (nu.max(3), nv.max(3));
    let mut vertices = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let u = std::f64::consts::TAU * i as f64 / nu as f64;
        for j in 0..nv {
            let v = std::f64::consts::TAU * j as f64 / nv as f64;
            let ring = major + minor * v.cos();
            vertices.push(Point3::new(ring * u.cos(), ring * u.sin(), minor * v.sin()));
        }
    }
    let id = |i: usize, j: usize| ((i % nu) * nv + (j % nv)) as u32;
    let mut triangles = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            // ∂/∂u × ∂/∂v points out of the tube, so (u, v) order is counter-clockwise.
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh {
        vertices,
        triangles,
    }
}

/// A latitude-longitude sphere of radius `r` about the origin: `rings` rings between the
/// poles, `segments` around; closed and outward. (Unlike the icosphere, its triangles are
/// anisotropic near the poles, which exercises code on uneven tessellations.)
pub fn uv_sphere(r: f64, rings: u32, segments: u32) -> TriMesh {
    use std::f64::consts::PI;
    let mut m = TriMesh::default();
    m.vertices.push(Point3::new(0., 0., r));
    for i in 1..=rings {
        let theta = PI * i as f64 / (rings + 1) as f64;
        for j in 0..segments {
            let phi = 2.0 * PI * j as f64 / segments as f64;
            m.vertices.push(Point3::new(
                r * theta.sin() * phi.cos(),
                r * theta.sin() * phi.sin(),
                r * theta.cos(),
            ));
        }
    }
    m.vertices.push(Point3::new(0., 0., -r));
    let south = rings * segments + 1;
    let at = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    for j in 0..segments {
        m.triangles.push([0, at(1, j), at(1, j + 1)]);
        m.triangles.push([south, at(rings, j + 1), at(rings, j)]);
    }
    for i in 1..rings {
        for j in 0..segments {
            m.triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            m.triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    /// Every undirected edge is used exactly twice, once in each direction (closed, oriented,
    /// manifold).
    fn assert_closed_oriented(mesh: &TriMesh) {
        let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
        for &[a, b, c] in &mesh.triangles {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                *directed.entry((p, q)).or_default() += 1;
            }
        }
        for (&(p, q), &count) in &directed {
            assert_eq!(count, 1, "directed edge {p}->{q} used {count} times");
            assert_eq!(directed.get(&(q, p)), Some(&1), "edge {p}-{q} has no twin");
        }
    }

    #[test]
    fn icosphere_counts_radius_and_bounds() {
        let c = Point3::new(1.0, -2.0, 0.5);
        let r = 2.5;
        for s in 0..4 {
            let m = icosphere(c, r, s);
            assert_eq!(m.triangles.len(), 20 * 4usize.pow(s));
            assert_eq!(m.vertices.len(), 12 + 10 * (4usize.pow(s) - 1));
            assert_closed_oriented(&m);
            for v in &m.vertices {
                assert!(((v - c).norm() - r).abs() < 1e-12);
            }
            // The polyhedron lies between the sphere and the ball of its inradius (the smallest
            // distance from the centre to a face plane): exact volume and area bounds.
            let inradius = (0..m.triangles.len())
                .map(|t| {
                    let n = m.area_normal2(t).normalize();
                    n.dot(&(m.corners(t)[0] - c))
                })
                .fold(f64::INFINITY, f64::min);
            let vol = m.signed_volume();
            assert!(vol < 4.0 / 3.0 * PI * r.powi(3));
            assert!(vol > 4.0 / 3.0 * PI * inradius.powi(3));
            assert!(m.area() < 4.0 * PI * r * r);
            assert!(m.area() > 4.0 * PI * inradius * inradius);
        }
        let fine = icosphere(c, r, 5);
        assert!((fine.area() / (4.0 * PI * r * r) - 1.0).abs() < 2e-3);
        assert!((fine.signed_volume() / (4.0 / 3.0 * PI * r.powi(3)) - 1.0).abs() < 3e-3);
    }

    #[test]
    fn box_area_and_volume_are_exact() {
        let (lo, hi) = (Point3::new(-1.0, 0.5, 2.0), Point3::new(2.0, 1.5, 4.5));
        let (dx, dy, dz) = (3.0, 1.0, 2.5);
        for n in [1, 2, 5] {
            let m = box_mesh(lo, hi, n);
            assert_closed_oriented(&m);
            assert_eq!(m.triangles.len(), 12 * n * n);
            assert_eq!(m.vertices.len(), 6 * n * n + 2);
            let area = 2.0 * (dx * dy + dy * dz + dz * dx);
            assert!((m.area() - area).abs() < 1e-12);
            assert!((m.signed_volume() - dx * dy * dz).abs() < 1e-12);
        }
    }

    #[test]
    fn torus_area_and_volume_converge() {
        let (big, small) = (3.0, 1.0);
        let area = 4.0 * PI * PI * big * small;
        let volume = 2.0 * PI * PI * big * small * small;
        let coarse = torus(big, small, 32, 16);
        let fine = torus(big, small, 256, 128);
        assert_closed_oriented(&fine);
        assert_eq!(fine.triangles.len(), 2 * 256 * 128);
        let err = |m: &TriMesh| {
            (
                (m.area() / area - 1.0).abs(),
                (m.signed_volume() / volume - 1.0).abs(),
            )
        };
        let (ac, vc) = err(&coarse);
        let (af, vf) = err(&fine);
        assert!(af < 1e-3 && vf < 1e-3, "fine errors {af} {vf}");
        // Second-order convergence: 8x finer gives ≳ 40x smaller error.
        assert!(ac / af > 40.0 && vc / vf > 40.0, "{ac}/{af}, {vc}/{vf}");
        assert!(fine.signed_volume() > 0.0);
    }
}
