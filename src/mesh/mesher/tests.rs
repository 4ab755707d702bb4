//! Mesher tests on analytic domains with exact volumes and interfaces.

use nalgebra::{Point3, Vector3};

use super::*;
use crate::mesh::quality::quality_by_region;
use crate::mesh::tet::{Boundary, BoundaryOf};
use crate::mesh::topology::surface_topology;

/// A ball of radius `r` at the origin, region 1.
struct Ball {
    r: f64,
}

impl LabelledDomain for Ball {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (
            Point3::new(-self.r, -self.r, -self.r),
            Point3::new(self.r, self.r, self.r),
        )
    }
    fn region_count(&self) -> u16 {
        1
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        u16::from(p.coords.norm() < self.r)
    }
    fn signed_distance(&self, _: u16, p: &Point3<f64>) -> f64 {
        p.coords.norm() - self.r
    }
}

/// Exact signed distance of the box `lo..hi`.
fn box_sd(lo: &Vector3<f64>, hi: &Vector3<f64>, p: &Point3<f64>) -> f64 {
    let c = (lo + hi) / 2.0;
    let half = (hi - lo) / 2.0;
    let q = (p.coords - c).abs() - half;
    q.map(|x| x.max(0.0)).norm() + q.max().min(0.0)
}

/// Axis-aligned boxes, region i+1 for box i (the first containing box wins).
struct Boxes(Vec<(Vector3<f64>, Vector3<f64>)>);

impl LabelledDomain for Boxes {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let lo = self
            .0
            .iter()
            .fold(Vector3::repeat(f64::INFINITY), |a, b| a.inf(&b.0));
        let hi = self
            .0
            .iter()
            .fold(Vector3::repeat(f64::NEG_INFINITY), |a, b| a.sup(&b.1));
        (Point3::from(lo), Point3::from(hi))
    }
    fn region_count(&self) -> u16 {
        self.0.len() as u16
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        self.0
            .iter()
            .position(|(lo, hi)| box_sd(lo, hi, p) < 0.0)
            .map_or(0, |i| i as u16 + 1)
    }
    fn signed_distance(&self, region: u16, p: &Point3<f64>) -> f64 {
        let (lo, hi) = &self.0[region as usize - 1];
        box_sd(lo, hi, p)
    }
}

fn params(edge: f64) -> MesherParams {
    MesherParams {
        target_edge_mm: edge,
        ..MesherParams::default()
    }
}

/// Checks shared by every mesh: valid, positive, ≥ 10° dihedrals, and each region's boundary
/// a closed oriented manifold enclosing the region's volume.
fn check_mesh(mesh: &TetMesh) {
    mesh.validate().unwrap();
    assert_eq!(mesh.inverted_count(), 0);
    for (r, q) in quality_by_region(mesh) {
        eprintln!("region {r}: {q:?}");
        assert!(q.min_dihedral_deg >= 10.0 - 1e-9, "region {r}: {q:?}");
        let b = mesh.boundary(BoundaryOf::Region(r));
        let topo = surface_topology(&b.surface);
        assert!(topo.is_closed_oriented_manifold(), "region {r}: {topo:?}");
        let v = mesh.region_volume(r);
        assert!((b.surface.signed_volume() - v).abs() < 1e-9 * v.max(1.0));
    }
}

#[test]
fn ball_volume_boundary_and_quality() {
    let r = 2.0;
    let out = mesh_domain(&Ball { r }, &params(0.3)).unwrap();
    eprintln!("{:?} tets {}", out.report, out.mesh.tets.len());
    check_mesh(&out.mesh);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let v = out.mesh.volume();
    assert!((v - exact).abs() / exact < 0.02);
    // Boundary nodes lie on the sphere.
    let b = out.mesh.boundary(BoundaryOf::Whole);
    let offsets: Vec<f64> = b
        .surface
        .vertices
        .iter()
        .map(|p| (p.coords.norm() - r).abs())
        .collect();
    let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
    // Snapped, not a staircase: a lattice surface would sit up to h ≈ 0.33 mm off.
    assert!(
        mean < 0.01 * out.report.spacing_mm,
        "mean radial offset {mean}"
    );
    // Peeling flat caps lets nearly every boundary node reach the surface.
    let snap = out.report.snap;
    assert!(snap.held_back * 20 < snap.boundary_nodes, "{snap:?}");
    assert!(out.report.peeled > 0);
    assert!(offsets.iter().all(|&o| o < 0.3 * out.report.spacing_mm));
    let topo = surface_topology(&b.surface);
    assert_eq!(topo.euler, 2);
    assert_eq!(topo.components, 1);
}

#[test]
fn touching_boxes_conform_at_their_interface() {
    let boxes = Boxes(vec![
        (Vector3::new(0., 0., 0.), Vector3::new(2., 2., 2.)),
        (Vector3::new(2., 0., 0.), Vector3::new(3., 2., 2.)),
    ]);
    let out = mesh_domain(&boxes, &params(0.25)).unwrap();
    eprintln!("{:?} tets {}", out.report, out.mesh.tets.len());
    let mesh = &out.mesh;
    check_mesh(mesh);
    let (b1, b2) = (
        mesh.boundary(BoundaryOf::Region(1)),
        mesh.boundary(BoundaryOf::Region(2)),
    );
    let mut f1 = b1.node_triangles();
    let f2 = b2.node_triangles();
    // Interface: faces of region 1 whose reverse is a face of region 2.
    let sorted = |f: &[u32; 3]| {
        let mut k = *f;
        k.sort_unstable();
        k
    };
    let s2: std::collections::HashSet<[u32; 3]> = f2.iter().map(sorted).collect();
    f1.retain(|f| s2.contains(&sorted(f)));
    let area: f64 = f1
        .iter()
        .map(|f| {
            let p = f.map(|v| mesh.nodes[v as usize]);
            0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
        })
        .sum();
    // The interface is the plane x = 2 (2 × 2 mm), snapped flat.
    assert!((area - 4.0).abs() < 0.02, "interface area {area}");
    // Independent check: faces of each region lying on x = 2 are the same node triples.
    let on_plane = |b: &Boundary| -> std::collections::BTreeSet<[u32; 3]> {
        b.node_triangles()
            .iter()
            .filter(|f| {
                f.iter()
                    .all(|&v| (mesh.nodes[v as usize].x - 2.0).abs() < 0.05)
            })
            .map(sorted)
            .collect()
    };
    assert_eq!(on_plane(&b1), on_plane(&b2));
    assert_eq!(on_plane(&b1).len(), f1.len());
    // Volumes: exact 8 and 4 mm³ less the rounding of the outer box edges (O(h²) per length).
    let (v1, v2) = (mesh.region_volume(1), mesh.region_volume(2));
    assert!(
        (v1 - 8.0).abs() / 8.0 < 0.01 && (v2 - 4.0).abs() / 4.0 < 0.04,
        "{v1} {v2}"
    );
    assert!((mesh.volume() - v1 - v2).abs() < 1e-12);
}

/// A 3 × 3 × `t` mm slab, tilted off the lattice axes, region 1.
struct TiltedSlab {
    t: f64,
    to_slab: nalgebra::Rotation3<f64>,
}

impl TiltedSlab {
    fn new(t: f64) -> Self {
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 0.5));
        Self {
            t,
            to_slab: nalgebra::Rotation3::from_axis_angle(&axis, 0.4),
        }
    }
    fn half(&self) -> Vector3<f64> {
        Vector3::new(1.5, 1.5, self.t / 2.0)
    }
}

impl LabelledDomain for TiltedSlab {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        let r = 2.2;
        (Point3::new(-r, -r, -r), Point3::new(r, r, r))
    }
    fn region_count(&self) -> u16 {
        1
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        u16::from(self.signed_distance(1, p) < 0.0)
    }
    fn signed_distance(&self, _: u16, p: &Point3<f64>) -> f64 {
        let q = self.to_slab * p;
        box_sd(&-self.half(), &self.half(), &q)
    }
}

#[test]
fn thin_slab_survives_as_one_closed_sheet() {
    // 0.3 mm (stapes crus thickness) at the default 0.33 mm edge: h ≈ 0.36 mm > thickness.
    let p = MesherParams {
        thin_regions: vec![1],
        ..MesherParams::default()
    };
    let out = mesh_domain(&TiltedSlab::new(0.3), &p).unwrap();
    check_mesh(&out.mesh);
    let topo = surface_topology(&out.mesh.boundary(BoundaryOf::Region(1)).surface);
    assert_eq!((topo.components, topo.euler), (1, 2), "{topo:?}");
    let v = out.mesh.volume();
    assert!((v - 2.7).abs() / 2.7 < 0.05, "volume {v}");
}

#[test]
fn sheet_below_the_centroid_feature_size_gets_holes_unless_thin() {
    // 0.15 mm ≈ 0.4 h: the centroid rule alone leaves holes (Euler characteristic < 2).
    let plain = mesh_domain(&TiltedSlab::new(0.15), &params(0.35)).unwrap();
    let topo = surface_topology(&plain.mesh.boundary(BoundaryOf::Region(1)).surface);
    assert!(topo.euler < 2, "{topo:?}");
    let thin = MesherParams {
        thin_regions: vec![1],
        ..params(0.35)
    };
    let out = mesh_domain(&TiltedSlab::new(0.15), &thin).unwrap();
    check_mesh(&out.mesh);
    let topo = surface_topology(&out.mesh.boundary(BoundaryOf::Region(1)).surface);
    assert_eq!((topo.components, topo.euler), (1, 2), "{topo:?}");
}

#[test]
fn meshing_is_deterministic() {
    let domain = Boxes(vec![
        (Vector3::new(0., 0., 0.), Vector3::new(1.3, 1.1, 0.9)),
        (Vector3::new(0.4, 0.3, 0.9), Vector3::new(1.0, 0.9, 1.2)),
    ]);
    let a = mesh_domain(&domain, &params(0.2)).unwrap();
    let b = mesh_domain(&domain, &params(0.2)).unwrap();
    let bits = |m: &TetMesh| -> Vec<u64> {
        m.nodes
            .iter()
            .flat_map(|p| p.coords.iter().map(|x| x.to_bits()))
            .collect()
    };
    assert_eq!(bits(&a.mesh), bits(&b.mesh));
    assert_eq!(a, b);
    assert_eq!(a.mesh.region_ids(), vec![1, 2]);
    check_mesh(&a.mesh);
}

#[test]
fn bad_parameters_are_errors() {
    let ball = Ball { r: 1.0 };
    assert!(matches!(
        mesh_domain(&ball, &params(0.0)),
        Err(MesherError::Parameter { .. })
    ));
    assert!(matches!(
        mesh_domain(&ball, &params(f64::NAN)),
        Err(MesherError::Parameter { .. })
    ));
    assert!(matches!(
        mesh_domain(&ball, &params(1e-4)),
        Err(MesherError::TooFine { .. })
    ));
    assert!(matches!(
        mesh_domain(&Ball { r: 0.01 }, &params(0.5)),
        Err(MesherError::Empty { .. })
    ));
}

/// A core ball (region 1, radius 1) inside a shell (region 2, radii 1..2).
pub(crate) struct CoreShell;

impl LabelledDomain for CoreShell {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (Point3::new(-2., -2., -2.), Point3::new(2., 2., 2.))
    }
    fn region_count(&self) -> u16 {
        2
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        match p.coords.norm() {
            r if r < 1.0 => 1,
            r if r < 2.0 => 2,
            _ => 0,
        }
    }
    fn signed_distance(&self, region: u16, p: &Point3<f64>) -> f64 {
        let r = p.coords.norm();
        if region == 1 {
            r - 1.0
        } else {
            (r - 2.0).max(1.0 - r)
        }
    }
}

#[test]
fn curved_interface_between_core_and_shell_conforms() {
    let out = mesh_domain(&CoreShell, &params(0.2)).unwrap();
    let mesh = &out.mesh;
    check_mesh(mesh);
    let ball = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let (v1, v2) = (mesh.region_volume(1), mesh.region_volume(2));
    assert!((v1 - ball(1.0)).abs() / ball(1.0) < 0.02, "core {v1}");
    assert!(
        (v2 - (ball(2.0) - ball(1.0))).abs() / (ball(2.0) - ball(1.0)) < 0.02,
        "shell {v2}"
    );
    // The core's whole boundary is the interface: every core boundary face is a shell face,
    // with its nodes on the unit sphere.
    let core = mesh.boundary(BoundaryOf::Region(1));
    let shell = mesh.boundary(BoundaryOf::Region(2));
    let key = |f: &[u32; 3]| {
        let mut k = *f;
        k.sort_unstable();
        k
    };
    let shell_faces: std::collections::HashSet<[u32; 3]> =
        shell.node_triangles().iter().map(key).collect();
    assert!(
        core.node_triangles()
            .iter()
            .all(|f| shell_faces.contains(&key(f)))
    );
    let offsets: Vec<f64> = core
        .surface
        .vertices
        .iter()
        .map(|p| (p.coords.norm() - 1.0).abs())
        .collect();
    let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
    assert!(mean < 0.05 * out.report.spacing_mm, "mean offset {mean}");
    let topo = surface_topology(&shell.surface);
    assert_eq!((topo.components, topo.euler), (2, 4));
}

#[test]
fn a_group_of_regions_touching_along_an_edge_gets_a_manifold_union() {
    // two boxes meeting along the line x = y = 1.03 only: each region's boundary is a
    // manifold by itself, their union's is not unless the pair is declared a group
    let domain = Boxes(vec![
        (Vector3::new(-1.0, -1.0, 0.0), Vector3::new(1.03, 1.03, 2.0)),
        (Vector3::new(1.03, 1.03, 0.0), Vector3::new(3.0, 3.0, 2.0)),
    ]);
    let plain = mesh_domain(&domain, &params(0.35)).unwrap();
    check_mesh(&plain.mesh);
    let union = |m: &TetMesh| surface_topology(&m.boundary(BoundaryOf::Whole).surface);
    assert!(
        !union(&plain.mesh).is_closed_oriented_manifold(),
        "{:?}",
        union(&plain.mesh)
    );
    let grouped = mesh_domain(
        &domain,
        &MesherParams {
            manifold_groups: vec![vec![1, 2]],
            ..params(0.35)
        },
    )
    .unwrap();
    assert_eq!(grouped.report.repair.defects_left, 0);
    check_mesh(&grouped.mesh);
    let topo = union(&grouped.mesh);
    assert!(topo.is_closed_oriented_manifold(), "{topo:?}");
    assert_eq!(topo.components, 1, "{topo:?}");
    // the repair fills a few lattice tets along the line: volumes stay near the exact ones
    for (region, exact) in [(1, 2.03 * 2.03 * 2.0), (2, 1.97 * 1.97 * 2.0)] {
        let v = grouped.mesh.region_volume(region);
        assert!(
            (v - exact).abs() < 0.03 * exact,
            "region {region}: {v} vs {exact}"
        );
    }
}

/// The nodes of `mesh` that tets of both `a` and `b` use.
fn nodes_shared_by(mesh: &TetMesh, a: u16, b: u16) -> usize {
    let mut seen = vec![(false, false); mesh.nodes.len()];
    for (tet, &region) in mesh.tets.iter().zip(&mesh.regions) {
        for &v in tet {
            let s = &mut seen[v as usize];
            s.0 |= region == a;
            s.1 |= region == b;
        }
    }
    seen.iter().filter(|s| s.0 && s.1).count()
}

#[test]
fn groups_kept_apart_share_no_node_across_a_gap_thinner_than_the_lattice() {
    // two boxes 0.1 mm apart (a lattice cell is 0.38 mm): the centroid rule gives them nodes
    // in common across the gap unless they are kept apart
    let domain = Boxes(vec![
        (Vector3::new(0.0, 0.0, 0.0), Vector3::new(2.0, 2.0, 2.0)),
        (Vector3::new(2.1, 0.0, 0.0), Vector3::new(4.0, 2.0, 2.0)),
    ]);
    let plain = mesh_domain(&domain, &params(0.35)).unwrap();
    assert!(nodes_shared_by(&plain.mesh, 1, 2) > 0);
    assert_eq!(plain.report.repair.separated, 0);
    let apart = mesh_domain(
        &domain,
        &MesherParams {
            apart_groups: vec![vec![1], vec![2]],
            ..params(0.35)
        },
    )
    .unwrap();
    let mesh = &apart.mesh;
    assert_eq!(nodes_shared_by(mesh, 1, 2), 0);
    assert_eq!(apart.report.repair.shared_nodes_left, 0);
    assert!(apart.report.repair.separated > 0);
    check_mesh(mesh);
    // each box one closed piece near its volume (8 and 7.6 mm³; the side that gave up its
    // tets at the gap lost a layer of at most a lattice cell over its 4 mm² face)
    for (region, exact) in [(1, 8.0), (2, 7.6)] {
        let topo = surface_topology(&mesh.boundary(BoundaryOf::Region(region)).surface);
        assert_eq!(topo.components, 1, "region {region}: {topo:?}");
        let v = mesh.region_volume(region);
        assert!(
            v < exact * 1.03 && v > exact - 4.0 * 0.38,
            "region {region}: {v} vs {exact}"
        );
    }
}

/// A ball with a hollow ball inside, region 1.
struct HollowBall {
    inner: f64,
}

impl LabelledDomain for HollowBall {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (Point3::from([-1.5; 3]), Point3::from([1.5; 3]))
    }
    fn region_count(&self) -> u16 {
        1
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        u16::from(self.signed_distance(1, p) < 0.0)
    }
    fn signed_distance(&self, _: u16, p: &Point3<f64>) -> f64 {
        let r = (p - Point3::new(0.05, 0.02, 0.03)).norm();
        (r - 1.5).max(self.inner - r)
    }
}

#[test]
fn voids_below_the_lattice_resolution_are_filled_larger_ones_kept() {
    let components = |inner: f64| {
        let out = mesh_domain(&HollowBall { inner }, &params(0.35)).unwrap();
        check_mesh(&out.mesh);
        (
            surface_topology(&out.mesh.boundary(BoundaryOf::Whole).surface).components,
            out.report.repair.cavities_filled,
        )
    };
    // a 0.2 mm void (well under one 0.35 mm lattice cell): filled, one boundary component
    let (small, filled) = components(0.2);
    assert_eq!(small, 1);
    assert!(filled <= 32, "{filled}");
    // a 0.7 mm void: a real cavity, kept as an inner boundary component
    assert_eq!(components(0.7).0, 2);
}
