//! The body-centred cubic (BCC) tetrahedral lattice the mesher starts from, and node→tet
//! adjacency.
//!
//! Nodes are the corners of a cubic grid of spacing `h` plus the cube centres. Each tet has one
//! axis-parallel grid edge (length `h`), one edge between neighbouring centres (length `h`) and
//! four corner–centre edges (length `h√3/2`): around every grid edge the four centres of the
//! cells sharing it form four tets, 12 tets of volume `h³/12` per cell, all congruent, with
//! dihedral angles of 60° and 90° (Labelle & Shewchuk, "Isosurface stuffing", SIGGRAPH 2007).

use nalgebra::Point3;

use crate::mesh::tet::signed_volume;

/// Mean edge length of a BCC tet in units of the grid spacing: (2 + 4·√3/2) / 6.
pub const MEAN_EDGE_PER_SPACING: f64 = (2.0 + 2.0 * 1.732_050_807_568_877_2) / 6.0;

/// A BCC lattice covering a box.
#[derive(Debug, Clone)]
pub struct Lattice {
    pub spacing: f64,
    pub nodes: Vec<Point3<f64>>,
    /// Positively oriented tets.
    pub tets: Vec<[u32; 4]>,
    /// True for nodes on the outer faces of the grid (their stars are incomplete).
    pub on_shell: Vec<bool>,
}

impl Lattice {
    /// Number of nodes a lattice of `spacing` over `lo..hi` padded by `pad` cells would have.
    pub fn node_count(lo: &Point3<f64>, hi: &Point3<f64>, spacing: f64, pad: usize) -> f64 {
        let dims = Self::dims(lo, hi, spacing, pad);
        let (x, y, z) = (dims[0] as f64, dims[1] as f64, dims[2] as f64);
        (x + 1.0) * (y + 1.0) * (z + 1.0) + x * y * z
    }

    fn dims(lo: &Point3<f64>, hi: &Point3<f64>, spacing: f64, pad: usize) -> [usize; 3] {
        [0, 1, 2].map(|a| ((hi[a] - lo[a]) / spacing).ceil().max(1.0) as usize + 2 * pad)
    }

    /// Builds the lattice over the box `lo..hi`, centred on it, with `pad` extra cells on
    /// every side.
    pub fn new(lo: &Point3<f64>, hi: &Point3<f64>, spacing: f64, pad: usize) -> Lattice {
        let [nx, ny, nz] = Self::dims(lo, hi, spacing, pad);
        let n = [nx, ny, nz];
        let origin = Point3::from(
            (lo.coords + hi.coords) / 2.0
                - nalgebra::Vector3::new(nx as f64, ny as f64, nz as f64) * (spacing / 2.0),
        );
        let corner = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
        let n_corners = (nx + 1) * (ny + 1) * (nz + 1);
        let centre = |i: usize, j: usize, k: usize| (n_corners + i + nx * (j + ny * k)) as u32;

        let mut nodes = Vec::with_capacity(n_corners + nx * ny * nz);
        let mut on_shell = Vec::with_capacity(nodes.capacity());
        for k in 0..=nz {
            for j in 0..=ny {
                for i in 0..=nx {
                    nodes.push(
                        origin + nalgebra::Vector3::new(i as f64, j as f64, k as f64) * spacing,
                    );
                    on_shell.push(i == 0 || j == 0 || k == 0 || i == nx || j == ny || k == nz);
                }
            }
        }
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = nalgebra::Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5);
                    nodes.push(origin + c * spacing);
                    on_shell.push(false);
                }
            }
        }

        let mut tets = Vec::with_capacity(12 * nx * ny * nz);
        for axis in 0..3 {
            let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
            for k in 0..=nz {
                for j in 0..=ny {
                    for i in 0..=nx {
                        let ijk = [i, j, k];
                        // The edge runs from ijk to ijk + e_axis; the four cells around it.
                        if ijk[axis] >= n[axis]
                            || ijk[b] == 0
                            || ijk[b] >= n[b]
                            || ijk[c] == 0
                            || ijk[c] >= n[c]
                        {
                            continue;
                        }
                        let mut end = ijk;
                        end[axis] += 1;
                        let (p0, p1) = (corner(i, j, k), corner(end[0], end[1], end[2]));
                        let cell = |db: usize, dc: usize| {
                            let mut q = ijk;
                            q[b] = q[b] + db - 1;
                            q[c] = q[c] + dc - 1;
                            centre(q[0], q[1], q[2])
                        };
                        let ring = [cell(0, 0), cell(1, 0), cell(1, 1), cell(0, 1)];
                        for m in 0..4 {
                            let mut t = [p0, p1, ring[m], ring[(m + 1) % 4]];
                            let [a, bb, cc, d] = t.map(|v| nodes[v as usize]);
                            if signed_volume(&a, &bb, &cc, &d) < 0.0 {
                                t.swap(2, 3);
                            }
                            tets.push(t);
                        }
                    }
                }
            }
        }
        Lattice {
            spacing,
            nodes,
            tets,
            on_shell,
        }
    }
}

/// Compressed node → incident tets adjacency, tets in ascending order per node.
#[derive(Debug, Clone)]
pub struct NodeTets {
    offsets: Vec<u32>,
    tets: Vec<u32>,
}

impl NodeTets {
    /// Adjacency of `n_nodes` nodes over `tets`.
    pub fn new(n_nodes: usize, tets: &[[u32; 4]]) -> NodeTets {
        let mut offsets = vec![0u32; n_nodes + 1];
        for t in tets {
            for &v in t {
                offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..n_nodes {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut list = vec![0u32; offsets[n_nodes] as usize];
        for (ti, t) in tets.iter().enumerate() {
            for &v in t {
                list[fill[v as usize] as usize] = ti as u32;
                fill[v as usize] += 1;
            }
        }
        NodeTets {
            offsets,
            tets: list,
        }
    }

    /// Tets incident to node `v`.
    #[inline]
    pub fn of(&self, v: usize) -> &[u32] {
        &self.tets[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality::dihedral_range;

    #[test]
    fn bcc_tiles_the_box_with_congruent_tets() {
        let h = 0.5;
        let lat = Lattice::new(&Point3::new(0., 0., 0.), &Point3::new(2., 1.5, 1.), h, 1);
        // Every tet: volume h³/12, dihedrals 60° or 90°.
        for t in &lat.tets {
            let p = t.map(|v| lat.nodes[v as usize]);
            let vol = signed_volume(&p[0], &p[1], &p[2], &p[3]);
            assert!((vol - h * h * h / 12.0).abs() < 1e-12);
            let (lo, hi) = dihedral_range(&p);
            assert!((lo.to_degrees() - 60.0).abs() < 1e-9);
            assert!((hi.to_degrees() - 90.0).abs() < 1e-9);
        }
        // Interior nodes have full stars of 24 tets; the interior cells are completely tiled.
        let adj = NodeTets::new(lat.nodes.len(), &lat.tets);
        let interior = (0..lat.nodes.len())
            .filter(|&v| !lat.on_shell[v] && adj.of(v).len() == 24)
            .count();
        assert!(interior > 0);
        for v in 0..lat.nodes.len() {
            assert!(adj.of(v).len() <= 24);
        }
    }
}
