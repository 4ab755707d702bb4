//! The eardrum's membrane mesh: the cone of [`Eardrum`] triangulated in concentric rings
//! around the umbo, each ring with as many nodes as its perimeter needs at the target edge,
//! every ring holding a node on the superior generator (θ = 0) so that the manubrium
//! attachment line is a row of nodes. Triangles face laterally (their normal points into the
//! ear canal), the side a sound pressure acts on.

use std::f64::consts::TAU;

use nalgebra::Point3;

use super::eardrum::Eardrum;
use super::region::MembraneRegion;

/// The triangulated eardrum, before it is attached to the manubrium.
#[derive(Debug, Clone, PartialEq)]
pub struct MembraneMesh {
    pub nodes: Vec<Point3<f64>>,
    /// (s, θ) of every node on the cone.
    pub coords: Vec<(f64, f64)>,
    /// Triangles, normal pointing laterally.
    pub triangles: Vec<[u32; 3]>,
    pub regions: Vec<MembraneRegion>,
    /// Nodes on the tympanic annulus (s = 1), in angle order.
    pub rim: Vec<u32>,
    /// Nodes on the manubrium attachment line (θ = 0, s ≤ the pars flaccida start), from the
    /// umbo upwards.
    pub attachment: Vec<u32>,
}

/// Triangulates the eardrum cone with edges of about `edge_mm`.
pub fn triangulate_eardrum(drum: &Eardrum, edge_mm: f64) -> MembraneMesh {
    let slant = (0..64)
        .map(|k| (drum.rim(TAU * k as f64 / 64.0) - drum.apex).norm())
        .fold(0.0, f64::max);
    let rings = ((slant / edge_mm).ceil() as usize).max(2);
    let perimeter = |s: f64| {
        (0..256)
            .map(|k| {
                let (a, b) = (TAU * k as f64 / 256.0, TAU * (k + 1) as f64 / 256.0);
                (drum.point(s, b) - drum.point(s, a)).norm()
            })
            .sum::<f64>()
    };
    let mut mesh = MembraneMesh {
        nodes: vec![drum.apex],
        coords: vec![(0.0, 0.0)],
        triangles: Vec::new(),
        regions: Vec::new(),
        rim: Vec::new(),
        attachment: vec![0],
    };
    // previous ring: first node index and node count (the apex is a ring of one)
    let mut previous = (0u32, 1usize);
    for k in 1..=rings {
        let s = k as f64 / rings as f64;
        let count = ((perimeter(s) / edge_mm).round() as usize).max(6);
        let first = mesh.nodes.len() as u32;
        for j in 0..count {
            let theta = TAU * j as f64 / count as f64;
            mesh.nodes.push(drum.point(s, theta));
            mesh.coords.push((s, theta));
        }
        if s <= drum.flaccida_start_fraction + 1e-9 {
            mesh.attachment.push(first);
        }
        stitch(&mut mesh, previous, (first, count));
        previous = (first, count);
    }
    mesh.rim = (previous.0..previous.0 + previous.1 as u32).collect();
    orient_laterally(&mut mesh, drum);
    mesh.regions = mesh
        .triangles
        .iter()
        .map(|t| {
            let (mut s, mut c, mut n) = (0.0, 0.0, 0.0);
            for &v in t {
                let (sv, tv) = mesh.coords[v as usize];
                s += sv / 3.0;
                c += tv.cos();
                n += tv.sin();
            }
            drum.region(s, n.atan2(c))
        })
        .collect();
    mesh
}

/// Fills the band between two rings (each closed, in increasing angle from θ = 0) with
/// triangles, advancing on whichever ring's next node comes first in angle.
fn stitch(mesh: &mut MembraneMesh, inner: (u32, usize), outer: (u32, usize)) {
    let angle = |ring: (u32, usize), i: usize| TAU * i as f64 / ring.1 as f64;
    let node = |ring: (u32, usize), i: usize| ring.0 + (i % ring.1) as u32;
    let (mut i, mut o) = (0usize, 0usize);
    while i < inner.1 || o < outer.1 {
        let advance_inner =
            o >= outer.1 || (i < inner.1 && angle(inner, i + 1) < angle(outer, o + 1));
        if advance_inner && inner.1 > 1 {
            mesh.triangles
                .push([node(inner, i), node(inner, i + 1), node(outer, o)]);
            i += 1;
        } else {
            mesh.triangles
                .push([node(inner, i), node(outer, o + 1), node(outer, o)]);
            o += 1;
            if inner.1 == 1 && o >= outer.1 {
                i = inner.1;
            }
        }
    }
}

/// Makes every triangle's normal point laterally (against the eardrum's medial normal).
fn orient_laterally(mesh: &mut MembraneMesh, drum: &Eardrum) {
    for t in &mut mesh.triangles {
        let [a, b, c] = t.map(|v| mesh.nodes[v as usize]);
        if (b - a).cross(&(c - a)).dot(&drum.medial_normal) > 0.0 {
            t.swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::Anatomy;
    use crate::mesh::TriMesh;
    use crate::mesh::topology::surface_topology;

    #[test]
    fn the_drum_is_a_single_oriented_disc_with_the_drums_area() {
        let anatomy = Anatomy::default_right().unwrap();
        let drum = anatomy.eardrum();
        let m = triangulate_eardrum(drum, 0.25);
        let surface = TriMesh {
            vertices: m.nodes.clone(),
            triangles: m.triangles.clone(),
        };
        let topo = surface_topology(&surface);
        // a disc: one component, one border loop (the rim), Euler characteristic 1
        assert_eq!(topo.components, 1, "{topo:?}");
        assert_eq!(topo.border_edges, m.rim.len(), "{topo:?}");
        assert_eq!(
            topo.non_manifold_edges + topo.misoriented_edges,
            0,
            "{topo:?}"
        );
        assert_eq!(topo.euler, 1, "{topo:?}");
        // every triangle faces the ear canal
        for t in &m.triangles {
            let [a, b, c] = t.map(|v| m.nodes[v as usize]);
            assert!((b - a).cross(&(c - a)).dot(&drum.medial_normal) < 0.0);
        }
        // the area of the bowed elliptic cone, by a fine (s, θ) quadrature of its surface
        let (ns, nt) = (400, 1600);
        let exact: f64 = (0..ns)
            .flat_map(|i| (0..nt).map(move |k| (i, k)))
            .map(|(i, k)| {
                let (s0, s1) = (i as f64 / ns as f64, (i + 1) as f64 / ns as f64);
                let (t0, t1) = (TAU * k as f64 / nt as f64, TAU * (k + 1) as f64 / nt as f64);
                let [a, b, c, d] =
                    [(s0, t0), (s1, t0), (s1, t1), (s0, t1)].map(|(sf, th)| drum.point(sf, th));
                0.5 * ((b - a).cross(&(c - a)).norm() + (c - a).cross(&(d - a)).norm())
            })
            .sum();
        let area: f64 = m
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| m.nodes[v as usize]);
                0.5 * (b - a).cross(&(c - a)).norm()
            })
            .sum();
        assert!((area / exact - 1.0).abs() < 0.01, "{area} vs {exact}");
        // the attachment row runs from the umbo up the superior generator
        assert_eq!(m.attachment[0], 0);
        assert!(m.attachment.len() >= 5);
        for &v in &m.attachment {
            assert_eq!(m.coords[v as usize].1, 0.0);
            assert!(m.coords[v as usize].0 <= drum.flaccida_start_fraction + 1e-9);
        }
        // both membrane regions, the flaccida the smaller
        let flaccida = m
            .regions
            .iter()
            .filter(|r| **r == MembraneRegion::ParsFlaccida)
            .count();
        assert!(
            flaccida > 0 && flaccida < m.triangles.len() / 4,
            "{flaccida}"
        );
    }
}
