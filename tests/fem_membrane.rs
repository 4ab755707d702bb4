//! Corotational CST membrane against analytic truth: in-plane patch test (solved), a
//! homogeneous stress state in a tilted, rotated plane (interior forces vanish, edge
//! resultant = h·W·σ·n), rigid motion of a curved patch, uniaxial plane-stress tension,
//! lumped membrane mass.

use crate::common::{Jitter, rectangle_membrane};
use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use otoatlas::fem::{
    CorotationalState, Elements, FemModel, FixedDofs, MembraneMaterial, StaticLoads, StaticOptions,
    StaticSolver,
};

const MAT: MembraneMaterial = MembraneMaterial {
    youngs_modulus: 3.0e7,
    poisson_ratio: 0.3,
    thickness: 0.075,
    bending_thickness: None,
    density: 1.2e-3,
};
const SIZE: [f64; 2] = [2.0, 1.5];
const CELLS: [usize; 2] = [6, 5];

fn model(nodes: &[Point3<f64>], tris: &[[u32; 3]]) -> FemModel {
    let index = vec![0; tris.len()];
    let set = Elements {
        cells: tris,
        material_index: &index,
        materials: &[MAT],
    };
    FemModel::new(nodes, Elements::none(), set).unwrap()
}

fn on_edge(p: &Point3<f64>) -> bool {
    let t = 1e-12;
    p.x.abs() < t || p.y.abs() < t || (p.x - SIZE[0]).abs() < t || (p.y - SIZE[1]).abs() < t
}

/// Rectangle in z = 0 with interior nodes jittered in-plane by up to 15 % of a cell.
fn jittered_patch() -> (Vec<Point3<f64>>, Vec<[u32; 3]>) {
    let (mut nodes, tris) = rectangle_membrane(SIZE, CELLS);
    let mut rng = Jitter::new(11);
    for p in nodes.iter_mut().filter(|p| !on_edge(p)) {
        p.x += 0.15 * 0.3 * rng.next();
        p.y += 0.15 * 0.3 * rng.next();
    }
    (nodes, tris)
}

fn max_norm<'a>(v: impl Iterator<Item = &'a Vector3<f64>>) -> f64 {
    v.map(|f| f.norm()).fold(0.0, f64::max)
}

#[test]
fn in_plane_patch_test_solved() {
    let (nodes, tris) = jittered_patch();
    let model = model(&nodes, &tris);
    let a = Matrix3::new(2e-3, -1e-3, 0.0, 5e-4, -1e-3, 0.0, 0.0, 0.0, 0.0);
    let exact: Vec<_> = nodes.iter().map(|p| p + a * p.coords).collect();
    let mut x = nodes.clone();
    let mut dofs: Vec<u32> = (0..nodes.len() as u32).map(|n| 3 * n + 2).collect();
    for (n, _) in nodes.iter().enumerate().filter(|(_, p)| on_edge(p)) {
        x[n] = exact[n];
        dofs.extend([3 * n as u32, 3 * n as u32 + 1]);
    }
    let fixed = FixedDofs::from_dofs(nodes.len(), &dofs).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let options = StaticOptions {
        tolerance_mm: 1e-14,
        ..StaticOptions::default()
    };
    solver
        .solve(&mut x, &StaticLoads::default(), &options)
        .unwrap();
    let scale = max_norm(
        nodes
            .iter()
            .zip(&exact)
            .map(|(p, q)| q - p)
            .collect::<Vec<_>>()
            .iter(),
    );
    let err = max_norm(
        x.iter()
            .zip(&exact)
            .map(|(p, q)| p - q)
            .collect::<Vec<_>>()
            .iter(),
    );
    println!("membrane patch: max error {err:e} mm (scale {scale:e} mm)");
    assert!(err <= 1e-9 * scale);
}

#[test]
fn homogeneous_stress_in_rotated_tilted_plane() {
    let (flat, tris) = jittered_patch();
    let tilt = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 1.0, 0.2)), 0.9);
    let rest: Vec<_> = flat.iter().map(|p| tilt * p).collect();
    let model = model(&rest, &tris);
    // In-plane symmetric strain (rest-plane coordinates), then a 60° rigid rotation.
    let (exx, eyy, exy) = (1e-3, -4e-4, 3e-4);
    let s = Matrix3::new(1.0 + exx, exy, 0.0, exy, 1.0 + eyy, 0.0, 0.0, 0.0, 1.0);
    let spin = Rotation3::from_axis_angle(
        &Unit::new_normalize(Vector3::new(-2.0, 1.0, 3.0)),
        60f64.to_radians(),
    );
    let q = spin * tilt;
    let t = Vector3::new(1.0, 2.0, -3.0);
    let x: Vec<_> = flat
        .iter()
        .map(|p| q * Point3::from(s * p.coords) + t)
        .collect();
    let mut state = CorotationalState::new(&model);
    let mut f = vec![Vector3::zeros(); x.len()];
    model.elastic_forces(&x, &mut state, &mut f).unwrap();
    // Plane stress: σ = E/(1−ν²)[[1,ν],[ν,1]]ε, τ = E/(2(1+ν))·2ε_xy.
    let (e, nu, h) = (MAT.youngs_modulus, MAT.poisson_ratio, MAT.thickness);
    let sxx = e / (1.0 - nu * nu) * (exx + nu * eyy);
    let sxy = e / (2.0 * (1.0 + nu)) * 2.0 * exy;
    let edge_resultant = q * Vector3::new(sxx, sxy, 0.0) * (-h * SIZE[1]);
    let right: Vector3<f64> = flat
        .iter()
        .zip(&f)
        .filter(|(p, _)| (p.x - SIZE[0]).abs() < 1e-12)
        .map(|(_, f)| f)
        .sum();
    let interior = max_norm(
        flat.iter()
            .zip(&f)
            .filter(|(p, _)| !on_edge(p))
            .map(|(_, f)| f),
    );
    println!("tilted plane: edge {right:?} vs {edge_resultant:?}, interior max {interior:e}");
    assert!((right - edge_resultant).norm() <= 1e-9 * edge_resultant.norm());
    assert!(interior <= 1e-9 * edge_resultant.norm());
}

#[test]
fn rigid_motion_of_curved_patch_gives_zero_force() {
    let (mut nodes, tris) = rectangle_membrane(SIZE, CELLS);
    for p in &mut nodes {
        // A shallow cone like the eardrum: z = 0.3 r about the patch centre.
        p.z = 0.3 * ((p.x - 1.0).powi(2) + (p.y - 0.75).powi(2)).sqrt();
    }
    let model = model(&nodes, &tris);
    let q = Rotation3::from_axis_angle(
        &Unit::new_normalize(Vector3::new(0.3, -1.0, 0.7)),
        60f64.to_radians(),
    );
    let x: Vec<_> = nodes
        .iter()
        .map(|p| q * p + Vector3::new(4.0, 0.5, -1.0))
        .collect();
    let mut state = CorotationalState::new(&model);
    let mut f = vec![Vector3::zeros(); x.len()];
    model.elastic_forces(&x, &mut state, &mut f).unwrap();
    // Force scale: unit strain across one cell edge, E·h·(cell size) in µN.
    let scale = MAT.youngs_modulus * MAT.thickness * 0.3;
    let worst = max_norm(f.iter());
    println!("curved patch rigid motion: max |f| {worst:e} µN (scale {scale:e})");
    assert!(worst <= 1e-9 * scale);
    assert!(state.failed_elements().is_empty());
}

#[test]
fn uniaxial_plane_stress_tension() {
    let strain = 1e-4;
    let (nodes, tris) = rectangle_membrane(SIZE, CELLS);
    let model = model(&nodes, &tris);
    let mut dofs: Vec<u32> = (0..nodes.len() as u32).map(|n| 3 * n + 2).collect();
    let mut x = nodes.clone();
    let mut right = Vec::new();
    for (n, p) in nodes.iter().enumerate() {
        let n = n as u32;
        if p.x.abs() < 1e-12 {
            dofs.push(3 * n);
        }
        if p.y.abs() < 1e-12 {
            dofs.push(3 * n + 1);
        }
        if (p.x - SIZE[0]).abs() < 1e-12 {
            dofs.push(3 * n);
            x[n as usize].x = SIZE[0] * (1.0 + strain);
            right.push(n as usize);
        }
    }
    let fixed = FixedDofs::from_dofs(nodes.len(), &dofs).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let options = StaticOptions {
        tolerance_mm: 1e-14,
        ..StaticOptions::default()
    };
    solver
        .solve(&mut x, &StaticLoads::default(), &options)
        .unwrap();
    let mut state = CorotationalState::new(&model);
    let mut f = vec![Vector3::zeros(); x.len()];
    model.elastic_forces(&x, &mut state, &mut f).unwrap();
    let stress = -right.iter().map(|&n| f[n].x).sum::<f64>() / (MAT.thickness * SIZE[1]);
    let expected = MAT.youngs_modulus * strain;
    println!("membrane uniaxial: sigma {stress} Pa vs E eps {expected} Pa");
    assert!((stress - expected).abs() <= 1e-6 * expected);
    for (n, p) in nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.y - SIZE[1]).abs() < 1e-12)
    {
        let lateral = (x[n].y - p.y) / SIZE[1];
        let want = -MAT.poisson_ratio * strain;
        assert!((lateral - want).abs() <= 1e-6 * want.abs(), "{lateral}");
    }
}

#[test]
fn lumped_membrane_mass_is_rho_h_area_over_three() {
    let (nodes, tris) = rectangle_membrane(SIZE, CELLS);
    let model = model(&nodes, &tris);
    let total: f64 = model.lumped_masses().iter().sum();
    let expected = MAT.density * MAT.thickness * SIZE[0] * SIZE[1];
    assert!((total - expected).abs() <= 1e-12 * expected);
    // Corner (0, 0) belongs to both triangles (area cell/2 each) of its cell.
    let cell = SIZE[0] / CELLS[0] as f64 * SIZE[1] / CELLS[1] as f64;
    let corner = MAT.density * MAT.thickness * cell / 2.0 / 3.0;
    let m0 = model.lumped_masses()[0];
    assert!(
        (m0 - 2.0 * corner).abs() <= 1e-12 * corner,
        "{m0} vs {corner}"
    );
}

#[test]
fn prestretched_flat_membrane_pulled_in_plane_with_tangent_shift() {
    // Interior nodes of a flat membrane have no out-of-plane stiffness in the warped tangent;
    // a tangent shift above the membrane tension keeps the iteration definite and stable
    // without changing the equilibrium. The edges are pre-stretched by 1 % so the membrane
    // stays in tension (a compressed membrane without bending has no flat equilibrium).
    let (nodes, tris) = rectangle_membrane(SIZE, CELLS);
    let model = model(&nodes, &tris);
    let centre = Vector3::new(SIZE[0] / 2.0, SIZE[1] / 2.0, 0.0);
    let mut x: Vec<_> = nodes
        .iter()
        .map(|p| Point3::from(centre + (p.coords - centre) * 1.01))
        .collect();
    let edge: Vec<u32> = (0..nodes.len() as u32)
        .filter(|&n| on_edge(&nodes[n as usize]))
        .collect();
    let fixed = FixedDofs::from_nodes(nodes.len(), &edge).unwrap();
    let pulled = (CELLS[0] / 2 + (CELLS[0] + 1) * (CELLS[1] / 2)) as u32;
    let spring = otoatlas::fem::Spring {
        node: pulled,
        target: x[pulled as usize] + Vector3::new(0.01, -0.006, 0.0),
        stiffness: 1e5,
    };
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let options = StaticOptions {
        tolerance_mm: 1e-12,
        tangent_shift: 0.1 * MAT.youngs_modulus * MAT.thickness,
        ..StaticOptions::default()
    };
    let start = x[pulled as usize];
    let report = solver
        .solve_with_springs(&mut x, &[spring], &options)
        .unwrap();
    let mut state = CorotationalState::new(&model);
    let mut f = vec![Vector3::zeros(); x.len()];
    model.elastic_forces(&x, &mut state, &mut f).unwrap();
    f[pulled as usize] += (spring.target - x[pulled as usize]) * spring.stiffness;
    let pull = (spring.target - start).norm() * spring.stiffness;
    let imbalance = max_norm(
        f.iter()
            .zip(&nodes)
            .filter(|(_, p)| !on_edge(p))
            .map(|(f, _)| f),
    );
    println!("flat membrane: {report:?}, imbalance {imbalance:e} µN of {pull:e}");
    assert!(imbalance <= 1e-9 * pull);
    assert!(
        x.iter().all(|p| p.z.abs() < 1e-12),
        "in-plane load must stay in plane"
    );
    assert!((x[pulled as usize] - start).norm() > 1e-4);
}
