//! Topology of a triangle surface: closedness, edge and vertex manifoldness, consistent
//! orientation, connected components and Euler characteristic (V − E + F).
//!
//! A surface is a closed oriented 2-manifold when every edge has exactly two triangles that
//! use it in opposite directions and the triangles around each vertex form a single fan.

use std::collections::HashMap;

use super::TriMesh;

/// Topological summary of a triangle surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SurfaceTopology {
    /// Edges with a single triangle.
    pub border_edges: usize,
    /// Edges with more than two triangles.
    pub non_manifold_edges: usize,
    /// Two-triangle edges used twice in the same direction (inconsistent orientation).
    pub misoriented_edges: usize,
    /// Vertices whose triangles form more than one fan (pinch points).
    pub non_manifold_vertices: usize,
    /// Edge-connected components of triangles.
    pub components: usize,
    /// V − E + F over the vertices used by triangles.
    pub euler: i64,
}

impl SurfaceTopology {
    /// True for a closed, consistently oriented 2-manifold.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.border_edges == 0
            && self.non_manifold_edges == 0
            && self.misoriented_edges == 0
            && self.non_manifold_vertices == 0
    }
}

/// Smallest-root union-find, deterministic.
pub(crate) struct UnionFind(Vec<u32>);

impl UnionFind {
    pub(crate) fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }
    pub(crate) fn find(&mut self, mut i: u32) -> u32 {
        while self.0[i as usize] != i {
            let p = self.0[i as usize];
            self.0[i as usize] = self.0[p as usize];
            i = p;
        }
        i
    }
    pub(crate) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        let (lo, hi) = (ra.min(rb), ra.max(rb));
        self.0[hi as usize] = lo;
    }
}

/// Computes the topological summary of `mesh`.
pub fn surface_topology(mesh: &TriMesh) -> SurfaceTopology {
    // Undirected edge -> (triangle count, sum of directions: +1 for a<b, -1 for a>b).
    let mut edges: HashMap<(u32, u32), (u32, i32)> = HashMap::new();
    for tri in &mesh.triangles {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            let e = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
            e.0 += 1;
            e.1 += if a < b { 1 } else { -1 };
        }
    }
    let mut topo = SurfaceTopology::default();
    let mut tri_uf = UnionFind::new(mesh.triangles.len());
    for &(n, dir) in edges.values() {
        match n {
            1 => topo.border_edges += 1,
            2 if dir != 0 => topo.misoriented_edges += 1,
            2 => {}
            _ => topo.non_manifold_edges += 1,
        }
    }
    // Components: union triangles sharing an edge.
    let mut first_tri: HashMap<(u32, u32), u32> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for i in 0..3 {
            let (a, b) = (tri[i], tri[(i + 1) % 3]);
            match first_tri.entry((a.min(b), a.max(b))) {
                std::collections::hash_map::Entry::Occupied(o) => tri_uf.union(*o.get(), t as u32),
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(t as u32);
                }
            }
        }
    }
    topo.components = (0..mesh.triangles.len() as u32)
        .filter(|&t| tri_uf.find(t) == t)
        .count();
    // Vertex fans: triangles around a vertex linked through shared edges at that vertex.
    let mut corner_tris: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertices.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &v in tri {
            corner_tris[v as usize].push(t as u32);
        }
    }
    let mut used = 0usize;
    for (v, tris) in corner_tris.iter().enumerate() {
        if tris.is_empty() {
            continue;
        }
        used += 1;
        let mut uf = UnionFind::new(tris.len());
        // Other corners of each triangle at v; two triangles sharing one link fan together.
        let others: Vec<[u32; 2]> = tris
            .iter()
            .map(|&t| {
                let tri = mesh.triangles[t as usize];
                let mut o = [0u32; 2];
                let mut k = 0;
                for &w in &tri {
                    if w as usize != v && k < 2 {
                        o[k] = w;
                        k += 1;
                    }
                }
                o
            })
            .collect();
        for i in 0..tris.len() {
            for j in i + 1..tris.len() {
                if others[i].iter().any(|w| others[j].contains(w)) {
                    uf.union(i as u32, j as u32);
                }
            }
        }
        let fans = (0..tris.len() as u32).filter(|&i| uf.find(i) == i).count();
        if fans > 1 {
            topo.non_manifold_vertices += 1;
        }
    }
    topo.euler = used as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    topo
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    fn tetra_surface() -> TriMesh {
        TriMesh {
            vertices: vec![
                Point3::new(0., 0., 0.),
                Point3::new(1., 0., 0.),
                Point3::new(0., 1., 0.),
                Point3::new(0., 0., 1.),
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn closed_tetrahedron_is_a_sphere() {
        let t = surface_topology(&tetra_surface());
        assert!(t.is_closed_oriented_manifold());
        assert_eq!(t.euler, 2);
        assert_eq!(t.components, 1);
    }

    #[test]
    fn defects_are_counted() {
        let mut s = tetra_surface();
        s.triangles[3] = [1, 3, 2]; // flipped
        let t = surface_topology(&s);
        assert_eq!(t.misoriented_edges, 3);
        s.triangles.pop();
        let t = surface_topology(&s);
        assert_eq!(t.border_edges, 3);
        // Two tetrahedra sharing only vertex 0: a pinch.
        let mut s = tetra_surface();
        s.vertices.extend([
            Point3::new(-1., 0., 0.),
            Point3::new(0., -1., 0.),
            Point3::new(0., 0., -1.),
        ]);
        s.triangles
            .extend([[0, 4, 5], [0, 5, 6], [0, 6, 4], [4, 6, 5]]);
        let t = surface_topology(&s);
        assert_eq!(t.non_manifold_vertices, 1);
        assert_eq!(t.border_edges, 0);
        assert_eq!(t.components, 2);
    }
}
