//! Solvers against analytic truth: a single tetrahedron pulled by a spring (closed-form
//! linear answer), the inversion guard under a huge pull, implicit Euler free fall and one
//! damped oscillator step, lumped tetrahedron mass, the errors a caller can provoke, and rigid
//! bodies turning exactly.

use crate::common::BoxMesh;
use nalgebra::{Point3, Rotation3, Vector3};
use otoatlas::fem::{
    CorotationalState, Elements, FemError, FemModel, FixedDofs, ImplicitEuler, Rayleigh,
    RigidBodies, Spring, StaticLoads, StaticOptions, StaticSolver, TetMaterial,
};

/// E = 1000 Pa, ν = 0.25 gives λ = μ = 400 Pa.
const MAT: TetMaterial = TetMaterial {
    youngs_modulus: 1000.0,
    poisson_ratio: 0.25,
    density: 1.1e-3,
};

fn unit_tet() -> (Vec<Point3<f64>>, FemModel) {
    let rest = vec![
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(1.0, 0.0, 0.0),
        Point3::new(0.0, 1.0, 0.0),
        Point3::new(0.0, 0.0, 1.0),
    ];
    let set = Elements {
        cells: &[[0, 1, 2, 3]],
        material_index: &[0],
        materials: &[MAT],
    };
    let model = FemModel::new(&rest, set, Elements::none()).unwrap();
    (rest, model)
}

/// Stiffness of the free apex (0,0,1) of the unit tetrahedron: ∇N3 = e_z, V = 1/6, so
/// K33 = V(λ e_z e_zᵀ + μ e_z e_zᵀ + μ I) = diag(μ, μ, λ + 2μ)/6.
fn apex_stiffness() -> Vector3<f64> {
    let (lambda, mu) = (400.0, 400.0);
    Vector3::new(mu, mu, lambda + 2.0 * mu) / 6.0
}

fn signed_volume(x: &[Point3<f64>]) -> f64 {
    (x[1] - x[0]).cross(&(x[2] - x[0])).dot(&(x[3] - x[0])) / 6.0
}

#[test]
fn spring_on_single_tet_matches_linear_elasticity() {
    let (rest, model) = unit_tet();
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let k = 1000.0;
    let d = Vector3::new(1e-6, -2e-6, 3e-6);
    let spring = Spring {
        node: 3,
        target: rest[3] + d,
        stiffness: k,
    };
    let mut x = rest.clone();
    let report = solver
        .solve_with_springs(&mut x, &[spring], &StaticOptions::default())
        .unwrap();
    let kk = apex_stiffness();
    let expected = Vector3::new(
        k * d.x / (kk.x + k),
        k * d.y / (kk.y + k),
        k * d.z / (kk.z + k),
    );
    let got = x[3] - rest[3];
    println!("spring: {report:?}, u = {got:?}, linear {expected:?}");
    assert!((got - expected).norm() <= 1e-5 * expected.norm());
    assert_eq!(&x[..3], &rest[..3]);
}

/// A tangent shift 1e3 × the stiffness makes every update ~1e-3 of the remaining error: judged
/// on the update alone, the solve stops after one iteration at 1e-3 of the answer; judged on
/// the out-of-balance force too (1e-6 of the load), it goes on to the equilibrium.
#[test]
fn static_equilibrium_is_judged_on_the_residual_too() {
    let (rest, model) = unit_tet();
    let fixed = || FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let (k, d) = (10.0, Vector3::new(0.0, 0.0, 1e-3));
    let spring = Spring {
        node: 3,
        target: rest[3] + d,
        stiffness: k,
    };
    let options = StaticOptions {
        tolerance_mm: 1e-6,
        tangent_shift: 1e3 * (apex_stiffness().z + k),
        max_iterations: 50_000,
        ..StaticOptions::default()
    };
    let expected = k * d.z / (apex_stiffness().z + k);
    let mut x = rest.clone();
    let update_only = StaticSolver::new(&model, fixed())
        .unwrap()
        .solve_with_springs(&mut x, &[spring], &options)
        .unwrap();
    println!("update only: {update_only:?}, u = {:e}", x[3].z - 1.0);
    assert_eq!(update_only.iterations, 1);
    assert!(update_only.relative_residual > 0.99);
    assert!((x[3].z - 1.0) < 2e-3 * expected);
    let mut x = rest.clone();
    let judged = StaticSolver::new(&model, fixed())
        .unwrap()
        .with_residual_tolerance(1e-6)
        .unwrap()
        .solve_with_springs(&mut x, &[spring], &options)
        .unwrap();
    println!("with the residual: {judged:?}, u = {:e}", x[3].z - 1.0);
    assert!(judged.relative_residual <= 1e-6);
    assert!(((x[3].z - 1.0) - expected).abs() <= 1e-5 * expected);
    let short = StaticOptions {
        max_iterations: 100,
        ..options
    };
    let mut x = rest.clone();
    match StaticSolver::new(&model, fixed())
        .unwrap()
        .with_residual_tolerance(1e-6)
        .unwrap()
        .solve_with_springs(&mut x, &[spring], &short)
    {
        Err(FemError::NotConverged {
            relative_residual, ..
        }) => assert!(relative_residual > 0.9),
        other => panic!("expected NotConverged, got {other:?}"),
    }
}

#[test]
fn large_spring_pull_converges_without_inversion() {
    let (rest, model) = unit_tet();
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let spring = Spring {
        node: 3,
        target: Point3::new(0.4, 0.3, 3.0),
        stiffness: 500.0,
    };
    let mut x = rest.clone();
    let report = solver
        .solve_with_springs(&mut x, &[spring], &StaticOptions::default())
        .unwrap();
    println!("large pull: {report:?}, apex {:?}", x[3]);
    assert!(signed_volume(&x) > 0.0);
    // Independent balance check at the apex: elastic force + spring force = 0.
    let mut state = CorotationalState::new(&model);
    let mut f = vec![Vector3::zeros(); 4];
    model.elastic_forces(&x, &mut state, &mut f).unwrap();
    let pull = (spring.target - x[3]) * spring.stiffness;
    assert!(
        (f[3] + pull).norm() <= 1e-6 * pull.norm(),
        "{:?} vs {pull:?}",
        f[3]
    );
    assert!(x[3].z > 1.5, "the apex must follow the spring a long way");
}

/// A solve that stops at balance (residual 1e-6 of the first) ends at the equilibrium the
/// update test finds, in fewer iterations, and says how far from balance it stopped.
#[test]
fn balance_ends_the_solve_at_the_same_equilibrium() {
    let (rest, model) = unit_tet();
    let fixed = || FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let spring = Spring {
        node: 3,
        target: Point3::new(0.4, 0.3, 3.0),
        stiffness: 500.0,
    };
    let mut tight = rest.clone();
    let full = StaticSolver::new(&model, fixed())
        .unwrap()
        .solve_with_springs(&mut tight, &[spring], &StaticOptions::default())
        .unwrap();
    let options = StaticOptions {
        balanced_below: 1e-6,
        ..StaticOptions::default()
    };
    let mut x = rest.clone();
    let balanced = StaticSolver::new(&model, fixed())
        .unwrap()
        .solve_with_springs(&mut x, &[spring], &options)
        .unwrap();
    println!(
        "update test: {full:?}\nbalance: {balanced:?}, apex {:?}",
        x[3]
    );
    assert!(balanced.iterations < full.iterations);
    assert!((x[3] - tight[3]).norm() <= 1e-5 * (tight[3] - rest[3]).norm());
    assert!(balanced.relative_residual < 1e-5);
}

/// Where the guard keeps a spring from its target, each step is halved and the residual
/// creeps: with a stall fraction the solve ends after a few iterations, not at the limit,
/// and still returns an admissible state.
#[test]
fn a_stalled_solve_ends_early_and_admissible() {
    let (rest, model) = unit_tet();
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let spring = Spring {
        node: 3,
        target: Point3::new(0.2, 0.2, -3.0),
        stiffness: 1e6,
    };
    let options = StaticOptions {
        stalled_below: 0.05,
        ..StaticOptions::default()
    };
    let mut x = rest.clone();
    let result = StaticSolver::new(&model, fixed)
        .unwrap()
        .solve_with_springs(&mut x, &[spring], &options);
    println!("stalled: {result:?}, apex {:?}", x[3]);
    match result {
        Err(FemError::NotConverged { iterations, .. }) => {
            assert!(iterations < options.max_iterations)
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    assert!(signed_volume(&x) > 0.0, "returned an inverted state");
    assert!(x[3].z < 0.5, "the apex must have moved towards the target");
}

#[test]
fn pull_through_the_base_never_inverts() {
    let (rest, model) = unit_tet();
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let spring = Spring {
        node: 3,
        target: Point3::new(0.2, 0.2, -3.0),
        stiffness: 1e6,
    };
    let mut x = rest.clone();
    let result = solver.solve_with_springs(&mut x, &[spring], &StaticOptions::default());
    println!("pull through: {result:?}, apex {:?}", x[3]);
    match result {
        Ok(report) => assert!(report.halvings > 0),
        Err(FemError::StepRejected { .. } | FemError::NotConverged { .. }) => {}
        Err(e) => panic!("unexpected error {e}"),
    }
    assert!(signed_volume(&x) > 0.0, "returned an inverted state");
    assert!(
        x[3].z < 0.5,
        "the guard must still let the apex move towards the target"
    );
}

#[test]
fn implicit_euler_free_fall_is_exact() {
    let mesh = BoxMesh::new([1.0, 2.0, 1.0], [2, 3, 2]);
    let index = vec![0; mesh.tets.len()];
    let set = Elements {
        cells: &mesh.tets,
        material_index: &index,
        materials: &[MAT],
    };
    let model = FemModel::new(&mesh.nodes, set, Elements::none()).unwrap();
    let g = Vector3::new(0.0, 0.0, -9810.0);
    let gravity: Vec<_> = model.lumped_masses().iter().map(|m| g * *m).collect();
    let fixed = FixedDofs::from_nodes(mesh.nodes.len(), &[]).unwrap();
    let mut euler = ImplicitEuler::new(&model, fixed, Rayleigh::default()).unwrap();
    let (mut x, mut v) = (mesh.nodes.clone(), vec![Vector3::zeros(); mesh.nodes.len()]);
    let (h, steps) = (1e-3, 10);
    for _ in 0..steps {
        let report = euler.step(&mut x, &mut v, h, Some(&gravity)).unwrap();
        assert!(report.failed_elements.is_empty());
    }
    let n = steps as f64;
    let drop = g * (h * h * n * (n + 1.0) / 2.0);
    for ((p, p0), vel) in x.iter().zip(&mesh.nodes).zip(&v) {
        assert!((vel - g * (n * h)).norm() <= 1e-9 * g.norm() * n * h);
        assert!(((p - p0) - drop).norm() <= 1e-9 * drop.norm());
    }
}

#[test]
fn implicit_euler_damped_step_matches_scalar_formula() {
    let (rest, model) = unit_tet();
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let damping = Rayleigh {
        mass: 2.0,
        stiffness: 1e-4,
    };
    let mut euler = ImplicitEuler::new(&model, fixed, damping).unwrap();
    let u = Vector3::new(1e-6, 2e-6, -1e-6);
    let v0 = Vector3::new(1e-3, 0.0, 2e-3);
    let mut x = rest.clone();
    x[3] += u;
    let mut v = vec![Vector3::zeros(); 4];
    v[3] = v0;
    let h = 1e-3;
    euler.step(&mut x, &mut v, h, None).unwrap();
    // Per axis: (m(1 + hα) + h(h + β)k) v' = m v − h k u, with m = ρV/4.
    let m = MAT.density / 6.0 / 4.0;
    let k = apex_stiffness();
    let expected = Vector3::from_fn(|i, _| {
        (m * v0[i] - h * k[i] * u[i])
            / (m * (1.0 + h * damping.mass) + h * (h + damping.stiffness) * k[i])
    });
    println!("damped step: v' {:?}, expected {expected:?}", v[3]);
    assert!((v[3] - expected).norm() <= 1e-6 * expected.norm());
    assert!((x[3] - (rest[3] + u + expected * h)).norm() <= 1e-6 * (expected * h).norm());
    assert!(v[..3].iter().all(|w| w.norm() == 0.0));
}

#[test]
fn lumped_tet_mass_is_rho_v_over_four() {
    let mesh = BoxMesh::new([1.5, 1.0, 0.5], [3, 2, 1]);
    let index = vec![0; mesh.tets.len()];
    let set = Elements {
        cells: &mesh.tets,
        material_index: &index,
        materials: &[MAT],
    };
    let model = FemModel::new(&mesh.nodes, set, Elements::none()).unwrap();
    let total: f64 = model.lumped_masses().iter().sum();
    assert!((total - MAT.density * 0.75).abs() <= 1e-12 * total);
    // Node (0,0,0) is a vertex of all 6 Kuhn tetrahedra of its cube (volume 0.125 mm³).
    let corner = MAT.density * 0.125 / 4.0;
    assert!((model.lumped_masses()[0] - corner).abs() <= 1e-12 * corner);
}

#[test]
fn caller_errors_are_reported() {
    let (rest, model) = unit_tet();
    // No fixed DOF and no spring: rigid motions are free.
    let free = FixedDofs::from_nodes(4, &[]).unwrap();
    let mut solver = StaticSolver::new(&model, free).unwrap();
    let mut x = rest.clone();
    x[3].z += 0.01;
    let err = solver.solve_with_springs(&mut x, &[], &StaticOptions::default());
    assert!(
        matches!(err, Err(FemError::NotPositiveDefinite { .. })),
        "{err:?}"
    );
    // Inverted start.
    let fixed = FixedDofs::from_nodes(4, &[0, 1, 2]).unwrap();
    let mut solver = StaticSolver::new(&model, fixed).unwrap();
    let mut inverted = rest.clone();
    inverted[3].z = -0.5;
    let err = solver.solve_with_springs(&mut inverted, &[], &StaticOptions::default());
    assert!(
        matches!(err, Err(FemError::InvertedState { count: 1, .. })),
        "{err:?}"
    );
    // Bad references.
    let bad = Spring {
        node: 9,
        target: Point3::origin(),
        stiffness: 1.0,
    };
    let err = solver.solve_with_springs(&mut x, &[bad], &StaticOptions::default());
    assert!(matches!(
        err,
        Err(FemError::BadNodeReference { node: 9, .. })
    ));
    assert!(FixedDofs::from_nodes(4, &[4]).is_err());
    let out_of_range = Elements {
        cells: &[[0, 1, 2, 7]],
        material_index: &[0],
        materials: &[MAT],
    };
    let err = FemModel::new(&rest, out_of_range, Elements::none());
    assert!(matches!(err, Err(FemError::NodeOutOfRange { node: 7, .. })));
    let bad_material = Elements {
        cells: &[[0, 1, 2, 3]],
        material_index: &[1],
        materials: &[MAT],
    };
    let err = FemModel::new(&rest, bad_material, Elements::none());
    assert!(matches!(
        err,
        Err(FemError::MaterialOutOfRange { index: 1, .. })
    ));
    let repeated = Elements {
        cells: &[[0, 1, 1, 3]],
        material_index: &[0],
        materials: &[MAT],
    };
    let err = FemModel::new(&rest, repeated, Elements::none());
    assert!(matches!(err, Err(FemError::RepeatedNode { node: 1, .. })));
}

/// Rigid bodies in the static solver (`StaticSolver::with_rigid_bodies`), whose rotations are
/// taken exactly: a block, every node on one body, pulled by springs towards its own nodes
/// turned by 0.6 rad and moved, lands exactly on them, undeformed (a linearised turn would
/// stretch it by θ²/2 = 18 %); and a cantilever whose outer half is one body bends under a tip
/// load as the same cantilever with that half 10⁴ times stiffer, solved node by node.
#[test]
fn rigid_bodies_turn_exactly_and_answer_as_the_stiff_limit() {
    let block = BoxMesh::new([1.0, 2.0, 1.0], [2, 2, 2]);
    let n = block.nodes.len();
    let index = vec![0; block.tets.len()];
    let model = FemModel::new(
        &block.nodes,
        Elements {
            cells: &block.tets,
            material_index: &index,
            materials: &[MAT],
        },
        Elements::none(),
    )
    .unwrap();
    let turn = Rotation3::from_scaled_axis(Vector3::new(1.0, 2.0, 3.0).normalize() * 0.6);
    let shift = Vector3::new(0.3, -0.2, 0.5);
    let target: Vec<Point3<f64>> = block.nodes.iter().map(|p| turn * p + shift).collect();
    let springs: Vec<Spring> = (0..n)
        .map(|v| Spring {
            node: v as u32,
            target: target[v],
            stiffness: 50.0,
        })
        .collect();
    let bodies = RigidBodies::new(&block.nodes, &vec![Some(0); n]).unwrap();
    let none = FixedDofs::from_nodes(n, &[]).unwrap();
    let mut solver = StaticSolver::with_rigid_bodies(&model, none, &bodies).unwrap();
    let mut x = block.nodes.clone();
    let options = StaticOptions {
        tolerance_mm: 1e-12,
        ..StaticOptions::default()
    };
    let report = solver
        .solve_with_springs(&mut x, &springs, &options)
        .unwrap();
    assert!(report.iterations < 20, "{report:?}");
    for (p, q) in x.iter().zip(&target) {
        assert!((p - q).norm() < 1e-10, "{p} vs {q}");
    }

    let beam = BoxMesh::new([4.0, 1.0, 1.0], [8, 2, 2]);
    let n = beam.nodes.len();
    let centroid_x = |t: &[u32; 4]| t.iter().map(|&v| beam.nodes[v as usize].x).sum::<f64>() / 4.0;
    let outer: Vec<u32> = beam
        .tets
        .iter()
        .map(|t| u32::from(centroid_x(t) > 2.0))
        .collect();
    let mut body = vec![None; n];
    for (t, _) in beam.tets.iter().zip(&outer).filter(|(_, o)| **o == 1) {
        t.iter().for_each(|&v| body[v as usize] = Some(0));
    }
    let stiff = TetMaterial {
        youngs_modulus: MAT.youngs_modulus * 1e4,
        ..MAT
    };
    let materials = [MAT, stiff];
    let model = FemModel::new(
        &beam.nodes,
        Elements {
            cells: &beam.tets,
            material_index: &outer,
            materials: &materials,
        },
        Elements::none(),
    )
    .unwrap();
    let fixed = FixedDofs::from_nodes(n, &beam.nodes_on_plane(0, 0.0)).unwrap();
    let tip = beam.nodes_on_plane(0, 4.0);
    let mut force = vec![Vector3::zeros(); n];
    for &v in &tip {
        force[v as usize] = Vector3::new(0.0, 0.0, 0.2);
    }
    let loads = StaticLoads {
        springs: &[],
        nodal_forces: Some(&force),
    };
    let options = StaticOptions {
        tolerance_mm: 1e-9,
        ..StaticOptions::default()
    };
    let bodies = RigidBodies::new(&beam.nodes, &body).unwrap();
    let mut rigid = beam.nodes.clone();
    StaticSolver::with_rigid_bodies(&model, fixed.clone(), &bodies)
        .unwrap()
        .solve(&mut rigid, &loads, &options)
        .unwrap();
    let mut elastic = beam.nodes.clone();
    StaticSolver::new(&model, fixed)
        .unwrap()
        .solve(&mut elastic, &loads, &options)
        .unwrap();
    let deflection = |x: &[Point3<f64>]| x[tip[0] as usize].z - beam.nodes[tip[0] as usize].z;
    let (a, b) = (deflection(&rigid), deflection(&elastic));
    // a large deflection (about 5 % of the length): the body turns by several hundredths of a
    // radian, where a linearised turn would strain it
    assert!(b > 0.2, "{b}");
    println!("tip deflection: rigid {a} mm, stiff {b} mm");
    assert!((a - b).abs() < 2e-4 * b, "rigid {a} vs stiff {b}");
}
