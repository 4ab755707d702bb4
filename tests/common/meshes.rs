//! Structured meshes for the FEM tests and benchmark: a box cut into cubes, each cube into the
//! 6 tetrahedra of the Kuhn (Freudenthal) decomposition along its main diagonal, which is
//! conforming across cubes; and a rectangle cut into squares of 2 triangles each.

use nalgebra::Point3;

/// A box [0, size] meshed by cells[0]×cells[1]×cells[2] cubes of 6 tetrahedra.
pub struct BoxMesh {
    pub nodes: Vec<Point3<f64>>,
    pub tets: Vec<[u32; 4]>,
    pub cells: [usize; 3],
    pub size: [f64; 3],
}

impl BoxMesh {
    pub fn new(size: [f64; 3], cells: [usize; 3]) -> Self {
        let [nx, ny, nz] = cells;
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    nodes.push(Point3::new(
                        size[0] * i as f64 / nx as f64,
                        size[1] * j as f64 / ny as f64,
                        size[2] * k as f64 / nz as f64,
                    ));
                }
            }
        }
        let mut mesh = BoxMesh {
            nodes,
            tets: Vec::with_capacity(6 * nx * ny * nz),
            cells,
            size,
        };
        // Kuhn simplices: 0 → e_p0 → e_p0 + e_p1 → (1,1,1) for each axis permutation p.
        const PERMS: [[usize; 3]; 6] = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    for p in PERMS {
                        let mut c = [i, j, k];
                        let mut tet = [mesh.node(c[0], c[1], c[2]); 4];
                        for (s, axis) in p.iter().enumerate() {
                            c[*axis] += 1;
                            tet[s + 1] = mesh.node(c[0], c[1], c[2]);
                        }
                        mesh.tets.push(tet);
                    }
                }
            }
        }
        mesh
    }

    /// Index of grid node (i, j, k).
    pub fn node(&self, i: usize, j: usize, k: usize) -> u32 {
        let [nx, ny, _] = self.cells;
        (i + (nx + 1) * (j + (ny + 1) * k)) as u32
    }

    /// Nodes whose coordinate on `axis` equals `value` (exact grid planes).
    pub fn nodes_on_plane(&self, axis: usize, value: f64) -> Vec<u32> {
        let tol = 1e-12 * self.size[axis].max(1.0);
        (0..self.nodes.len() as u32)
            .filter(|&n| (self.nodes[n as usize][axis] - value).abs() <= tol)
            .collect()
    }

    /// Nodes on the boundary of the box.
    pub fn boundary_nodes(&self) -> Vec<u32> {
        let tol = 1e-12;
        (0..self.nodes.len() as u32)
            .filter(|&n| {
                let p = self.nodes[n as usize];
                (0..3).any(|a| p[a].abs() <= tol || (p[a] - self.size[a]).abs() <= tol)
            })
            .collect()
    }
}

/// A rectangle [0, size] in the z = 0 plane, cells[0]×cells[1] squares of 2 triangles, with
/// alternating diagonals.
pub fn rectangle_membrane(size: [f64; 2], cells: [usize; 2]) -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let [nx, ny] = cells;
    let mut nodes = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            nodes.push(Point3::new(
                size[0] * i as f64 / nx as f64,
                size[1] * j as f64 / ny as f64,
                0.0,
            ));
        }
    }
    let id = |i: usize, j: usize| (i + (nx + 1) * j) as u32;
    let mut tris = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                tris.extend([[a, b, c], [a, c, d]]);
            } else {
                tris.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    (nodes, tris)
}

/// Deterministic pseudo-random numbers in [−1, 1) (splitmix64), for mesh jitter.
pub struct Jitter(u64);

impl Jitter {
    pub fn new(seed: u64) -> Self {
        Jitter(seed)
    }

    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}
