//! Isosurfaces of sampled scalar fields and label maps, in world coordinates: marching
//! tetrahedra over each grid cube cut into the six tetrahedra of the Kuhn decomposition along
//! its main diagonal. The cut is the same in every cube, so neighbouring cubes share faces and
//! the surface is closed and manifold with no ambiguous cases (unlike the original marching
//! cubes table). Vertices on shared grid edges are merged; triangles face outwards (from values
//! above the level to values below).
//!
//! Reference: Doi & Koide, "An efficient method of triangulating equi-valued surfaces by using
//! tetrahedral cells", IEICE Trans. E74(1) (1991) 214-224.

use std::collections::HashMap;

use nalgebra::{Matrix3, Point3, Vector3};

use super::TriMesh;

/// The 6 tetrahedra of a cube (corner c = x + 2y + 4z), all around the diagonal 0-7.
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 3, 2, 7],
    [0, 2, 6, 7],
    [0, 6, 4, 7],
    [0, 4, 5, 7],
    [0, 5, 1, 7],
];

/// A regular grid of samples: `values[i + nx (j + ny k)]` at `origin + axes · (i, j, k)`.
pub struct SampledField<'a> {
    pub dims: [usize; 3],
    pub values: &'a [f32],
    pub origin: Vector3<f64>,
    /// Columns: world offsets of one step along i, j, k (direction · spacing).
    pub axes: Matrix3<f64>,
}

/// The surface where the field crosses `level`; the inside is where values exceed it.
pub fn isosurface(field: &SampledField, level: f32) -> TriMesh {
    let [nx, ny, nz] = field.dims;
    let mut mesh = TriMesh::default();
    if nx < 2 || ny < 2 || nz < 2 {
        return mesh;
    }
    let node = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    let world = |n: usize| {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        Point3::from(field.origin + field.axes * Vector3::new(i as f64, j as f64, k as f64))
    };
    let mut edge_vertex: HashMap<(usize, usize), u32> = HashMap::new();
    let mut vertex_on = |a: usize, b: usize, mesh: &mut TriMesh| -> u32 {
        let key = (a.min(b), a.max(b));
        *edge_vertex.entry(key).or_insert_with(|| {
            let (va, vb) = (field.values[key.0], field.values[key.1]);
            let t = ((level - va) / (vb - va)) as f64;
            let p = world(key.0) + (world(key.1) - world(key.0)) * t.clamp(0.0, 1.0);
            mesh.vertices.push(p);
            (mesh.vertices.len() - 1) as u32
        })
    };
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let corner = |c: usize| node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                let inside = |n: usize| field.values[n] > level;
                let all: Vec<bool> = (0..8).map(|c| inside(corner(c))).collect();
                if all.iter().all(|&b| b) || all.iter().all(|&b| !b) {
                    continue;
                }
                for tet in KUHN {
                    let v = tet.map(corner);
                    let (ins, outs): (Vec<usize>, Vec<usize>) = v.iter().partition(|&&n| inside(n));
                    let tris: Vec<[u32; 3]> = match (ins.len(), outs.len()) {
                        (1, 3) | (3, 1) => {
                            let (lone, others) = if ins.len() == 1 {
                                (ins[0], &outs)
                            } else {
                                (outs[0], &ins)
                            };
                            vec![[
                                vertex_on(lone, others[0], &mut mesh),
                                vertex_on(lone, others[1], &mut mesh),
                                vertex_on(lone, others[2], &mut mesh),
                            ]]
                        }
                        (2, 2) => {
                            let a = vertex_on(ins[0], outs[0], &mut mesh);
                            let b = vertex_on(ins[0], outs[1], &mut mesh);
                            let c = vertex_on(ins[1], outs[1], &mut mesh);
                            let d = vertex_on(ins[1], outs[0], &mut mesh);
                            vec![[a, b, c], [a, c, d]]
                        }
                        _ => Vec::new(),
                    };
                    let inner = world(ins.first().copied().unwrap_or(v[0]));
                    for mut t in tris {
                        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                            continue;
                        }
                        let [a, b, c] = t.map(|x| mesh.vertices[x as usize]);
                        let normal = (b - a).cross(&(c - a));
                        let centroid = Point3::from((a.coords + b.coords + c.coords) / 3.0);
                        // outward: away from the inside corner of this tetrahedron
                        if normal.dot(&(centroid - inner)) < 0.0 {
                            t.swap(1, 2);
                        }
                        mesh.triangles.push(t);
                    }
                }
            }
        }
    }
    mesh
}

/// The surface of the voxels whose label is in `labels` (one closed surface around their
/// union), at the half-way level of the 0/1 indicator, padded so it closes at the image edge.
pub fn label_surface(
    dims: [usize; 3],
    label_map: &[u16],
    labels: &[u16],
    origin: Vector3<f64>,
    axes: Matrix3<f64>,
) -> TriMesh {
    let [nx, ny, nz] = dims;
    let padded = [nx + 2, ny + 2, nz + 2];
    let mut values = vec![0f32; padded.iter().product()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if labels.contains(&label_map[i + nx * (j + ny * k)]) {
                    values[(i + 1) + padded[0] * ((j + 1) + padded[1] * (k + 1))] = 1.0;
                }
            }
        }
    }
    let field = SampledField {
        dims: padded,
        values: &values,
        origin: origin - axes * Vector3::new(1.0, 1.0, 1.0),
        axes,
    };
    isosurface(&field, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn edge_use(mesh: &TriMesh) -> HashMap<(u32, u32), usize> {
        let mut uses = HashMap::new();
        for t in &mesh.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        uses
    }

    #[test]
    fn sphere_is_closed_outward_with_the_right_area_and_volume() {
        let n = 48;
        let h = 0.1;
        let r = 1.7;
        let c = (n as f64 - 1.0) * h / 2.0;
        let values: Vec<f32> = (0..n * n * n)
            .map(|idx| {
                let (i, j, k) = (idx % n, (idx / n) % n, idx / (n * n));
                let p = Vector3::new(i as f64, j as f64, k as f64) * h - Vector3::repeat(c);
                (r - p.norm()) as f32 // signed distance, positive inside
            })
            .collect();
        let field = SampledField {
            dims: [n; 3],
            values: &values,
            origin: Vector3::zeros(),
            axes: Matrix3::identity() * h,
        };
        let mesh = isosurface(&field, 0.0);
        assert!(
            edge_use(&mesh).values().all(|&u| u == 2),
            "closed and manifold"
        );
        let volume = mesh.signed_volume();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((volume - exact).abs() < 0.01 * exact, "{volume} vs {exact}");
        let area = mesh.area();
        let exact_area = 4.0 * std::f64::consts::PI * r * r;
        assert!(
            (area - exact_area).abs() < 0.02 * exact_area,
            "{area} vs {exact_area}"
        );
    }

    #[test]
    fn label_surface_of_a_voxel_block_encloses_its_voxels() {
        // a 4x3x2 block of label 5 inside an 8x8x8 map, 0.5 mm voxels: the half-way surface of
        // the indicator bounds a volume between the block's voxel-centre hull and its voxels
        let dims = [8, 8, 8];
        let mut map = vec![0u16; 512];
        for k in 2..4 {
            for j in 2..5 {
                for i in 1..5 {
                    map[i + 8 * (j + 8 * k)] = 5;
                }
            }
        }
        map[0] = 7; // another label, not selected, touching the border
        let mesh = label_surface(
            dims,
            &map,
            &[5],
            Vector3::new(10.0, 0.0, 0.0),
            Matrix3::identity() * 0.5,
        );
        assert!(edge_use(&mesh).values().all(|&u| u == 2));
        let v = mesh.signed_volume();
        let voxels = 24.0 * 0.125;
        assert!(v > 0.0 && v < voxels, "{v}");
        let xs: Vec<f64> = mesh.vertices.iter().map(|p| p.x).collect();
        let (lo, hi) = xs
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
        assert!(
            (lo - 10.25).abs() < 1e-9 && (hi - 12.25).abs() < 1e-9,
            "{lo} {hi}"
        );
        let both = label_surface(
            dims,
            &map,
            &[5, 7],
            Vector3::zeros(),
            Matrix3::identity() * 0.5,
        );
        assert!(both.signed_volume() > v);
    }
}
