//! Sparse assembly and factorisation against independent truth: the assembled warped tangent
//! equals −∂f/∂x by central finite differences at a rigidly rotated state (where the warped
//! tangent is exact), fixed DOFs are projected, and the Cholesky solve of the assembled
//! system satisfies A x = b when A is rebuilt densely from the stored lower triangle; the
//! matrix-free step operator equals the assembled step matrix at a deformed state; a
//! single-precision factor solves to single precision, and a matrix that is positive definite
//! only in double precision is factorised in double.

use crate::common::BoxMesh;
use nalgebra::{DMatrix, DVector, Point3, Rotation3, Unit, Vector3};
use otoatlas::fem::{
    CorotationalState, Dashpot, Elements, FactorPrecision, FemModel, FixedDofs, MembraneMaterial,
    SparseCholesky, SparsePattern, StepOperator, TetMaterial,
};

fn box_with_membrane_lid() -> (BoxMesh, FemModel) {
    let mesh = BoxMesh::new([1.0, 0.8, 0.6], [3, 2, 2]);
    let [nx, ny, nz] = mesh.cells;
    let mut lid = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b) = (mesh.node(i, j, nz), mesh.node(i + 1, j, nz));
            let (c, d) = (mesh.node(i + 1, j + 1, nz), mesh.node(i, j + 1, nz));
            lid.extend([[a, b, c], [a, c, d]]);
        }
    }
    let tet_mats = [
        TetMaterial {
            youngs_modulus: 1.0e6,
            poisson_ratio: 0.3,
            density: 1e-3,
        },
        TetMaterial {
            youngs_modulus: 5.0e7,
            poisson_ratio: 0.2,
            density: 2e-3,
        },
    ];
    let tet_index: Vec<u32> = (0..mesh.tets.len() as u32).map(|i| i % 2).collect();
    let lid_index = vec![0; lid.len()];
    let membrane = [MembraneMaterial {
        youngs_modulus: 3.0e7,
        poisson_ratio: 0.3,
        thickness: 0.1,
        bending_thickness: None,
        density: 1.2e-3,
    }];
    let model = FemModel::new(
        &mesh.nodes,
        Elements {
            cells: &mesh.tets,
            material_index: &tet_index,
            materials: &tet_mats,
        },
        Elements {
            cells: &lid,
            material_index: &lid_index,
            materials: &membrane,
        },
    )
    .unwrap()
    .with_membrane_bending(0.05)
    .unwrap();
    assert!(model.hinge_count() > 0);
    assert!(model.hinge_coupling_count() > 0);
    (mesh, model)
}

/// The full symmetric matrix from the stored lower triangle.
fn dense(pattern: &SparsePattern, values: &[f64]) -> DMatrix<f64> {
    let n = pattern.dof_count();
    let sym = pattern.symbolic();
    let mut a = DMatrix::zeros(n, n);
    for col in 0..n {
        let range = sym.col_ptr()[col]..sym.col_ptr()[col + 1];
        for (&row, &v) in sym.row_idx()[range.clone()].iter().zip(&values[range]) {
            assert!(row >= col, "upper-triangle entry stored");
            a[(row, col)] = v;
            a[(col, row)] = v;
        }
    }
    a
}

fn rigidly_rotated(nodes: &[Point3<f64>]) -> Vec<Point3<f64>> {
    let q = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(2.0, -1.0, 1.0)), 1.0);
    nodes
        .iter()
        .map(|p| q * p + Vector3::new(0.5, 0.1, -0.3))
        .collect()
}

#[test]
fn tangent_equals_finite_difference_of_forces_at_rigid_state() {
    let (mesh, model) = box_with_membrane_lid();
    let x = rigidly_rotated(&mesh.nodes);
    let pattern = SparsePattern::new(&model);
    let mut state = CorotationalState::new(&model);
    state.update(&model, &x).unwrap();
    let free = FixedDofs::from_nodes(x.len(), &[]).unwrap();
    let mut values = pattern.zero_values();
    pattern
        .assemble(&model, &state, 1.0, None, &free, &mut values)
        .unwrap();
    let k = dense(&pattern, &values);

    let n = model.dof_count();
    let mut fd = DMatrix::zeros(n, n);
    let (mut fp, mut fm) = (
        vec![Vector3::zeros(); x.len()],
        vec![Vector3::zeros(); x.len()],
    );
    let h = 1e-6;
    for dof in 0..n {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[dof / 3][dof % 3] += h;
        xm[dof / 3][dof % 3] -= h;
        model.elastic_forces(&xp, &mut state, &mut fp).unwrap();
        model.elastic_forces(&xm, &mut state, &mut fm).unwrap();
        for v in 0..x.len() {
            for i in 0..3 {
                fd[(3 * v + i, dof)] = -(fp[v][i] - fm[v][i]) / (2.0 * h);
            }
        }
    }
    let err = (&k - &fd).norm();
    println!("tangent vs FD: |K - FD| = {err:e}, |K| = {:e}", k.norm());
    assert!(err <= 1e-6 * k.norm());
}

#[test]
fn fixed_dofs_are_projected_and_cholesky_solves() {
    let (mesh, model) = box_with_membrane_lid();
    let x = rigidly_rotated(&mesh.nodes);
    let pattern = SparsePattern::new(&model);
    let mut state = CorotationalState::new(&model);
    state.update(&model, &x).unwrap();
    let n = model.dof_count();
    let free = FixedDofs::from_nodes(x.len(), &[]).unwrap();
    let clamp = mesh.nodes_on_plane(0, 0.0);
    let fixed = FixedDofs::from_nodes(x.len(), &clamp).unwrap();
    let diag: Vec<f64> = (0..x.len()).map(|v| 10.0 + v as f64).collect();
    let (mut a_free, mut a_fixed) = (pattern.zero_values(), pattern.zero_values());
    pattern
        .assemble(&model, &state, 0.5, Some(&diag), &free, &mut a_free)
        .unwrap();
    pattern
        .assemble(&model, &state, 0.5, Some(&diag), &fixed, &mut a_fixed)
        .unwrap();
    let (a_free, a_fixed) = (dense(&pattern, &a_free), dense(&pattern, &a_fixed));
    for r in 0..n {
        for c in 0..n {
            let want = match (fixed.is_fixed(r), fixed.is_fixed(c)) {
                (false, false) => a_free[(r, c)],
                _ if r == c => 1.0,
                _ => 0.0,
            };
            assert_eq!(a_fixed[(r, c)], want, "entry ({r}, {c})");
        }
    }
    let mut values = pattern.zero_values();
    pattern
        .assemble(&model, &state, 0.5, Some(&diag), &fixed, &mut values)
        .unwrap();
    let mut chol = SparseCholesky::analyse(&pattern).unwrap();
    let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
    for round in 0..2 {
        // Re-factorise with the same symbolic analysis.
        chol.factorise(pattern.matrix(&values)).unwrap();
        let mut sol = b.clone();
        chol.solve_in_place(&mut sol).unwrap();
        let res = &a_fixed * DVector::from_vec(sol) - DVector::from_vec(b.clone());
        println!("round {round}: residual {:e}", res.norm());
        assert!(res.norm() <= 1e-10 * DVector::from_vec(b.clone()).norm());
    }
}

/// A single-precision factorisation of the box's tangent solves it with a normwise backward
/// error ‖b − A x̂‖ / (‖A‖ ‖x̂‖ + ‖b‖) of single precision's order, n ε₃₂ (and above double's,
/// so the factor really is single; Higham, Accuracy and Stability of Numerical Algorithms,
/// §7.1 and §10.1), and one of a matrix
/// whose rounding to single precision is singular (a 2 × 2 block [[1, 1 − ε], [1 − ε, 1]],
/// ε = 1e-9, in an identity) falls back to double and meets the analytic solution.
#[test]
fn a_single_precision_factor_solves_to_its_precision_and_falls_back_when_singular() {
    let (mesh, model) = box_with_membrane_lid();
    let x = rigidly_rotated(&mesh.nodes);
    let mut state = CorotationalState::new(&model);
    state.update(&model, &x).unwrap();
    let pattern = SparsePattern::new(&model);
    let n = 3 * x.len();
    let free = FixedDofs::from_nodes(x.len(), &[]).unwrap();
    let diag: Vec<f64> = (0..x.len()).map(|v| 10.0 + v as f64).collect();
    let mut values = pattern.zero_values();
    pattern
        .assemble(&model, &state, 0.5, Some(&diag), &free, &mut values)
        .unwrap();
    let a = dense(&pattern, &values);
    let b = DVector::from_fn(n, |i, _| ((i * 7919) % 13) as f64 - 6.0);
    let mut chol = SparseCholesky::analyse(&pattern).unwrap();
    let a_norm = a.clone().svd(false, false).singular_values.max();
    let mut backward_error = |precision| {
        chol.factorise_in(pattern.matrix(&values), precision)
            .unwrap();
        assert_eq!(chol.precision(), Some(precision));
        let mut sol = b.as_slice().to_vec();
        chol.solve_in_place(&mut sol).unwrap();
        let sol = DVector::from_vec(sol);
        (&a * &sol - &b).norm() / (a_norm * sol.norm() + b.norm())
    };
    let (single, double) = (
        backward_error(FactorPrecision::Single),
        backward_error(FactorPrecision::Double),
    );
    let n_eps = |eps: f64| n as f64 * eps;
    println!(
        "backward error: single {single:e} (n ε₃₂ {:e}), double {double:e} (n ε₆₄ {:e})",
        n_eps(f32::EPSILON.into()),
        n_eps(f64::EPSILON)
    );
    assert!(single <= n_eps(f32::EPSILON.into()), "single {single:e}");
    assert!(single > 1e3 * n_eps(f64::EPSILON), "single {single:e}");
    assert!(double <= n_eps(f64::EPSILON), "double {double:e}");

    // the identity with one near-singular 2 × 2 block on node 0's x and y
    let eps = 1e-9;
    let symbolic = pattern.symbolic();
    let mut near_singular = pattern.zero_values();
    for c in 0..n {
        let range = symbolic.col_ptr()[c]..symbolic.col_ptr()[c + 1];
        for (v, &r) in near_singular[range.clone()]
            .iter_mut()
            .zip(&symbolic.row_idx()[range])
        {
            *v = match (r, c) {
                (r, c) if r == c => 1.0,
                (1, 0) => 1.0 - eps,
                _ => 0.0,
            };
        }
    }
    chol.factorise_in(pattern.matrix(&near_singular), FactorPrecision::Single)
        .unwrap();
    assert_eq!(chol.precision(), Some(FactorPrecision::Double));
    let mut sol = vec![0.0; n];
    sol[0] = 1.0;
    chol.solve_in_place(&mut sol).unwrap();
    // [[1, 1 − ε], [1 − ε, 1]]⁻¹ e₀ = (1, −(1 − ε)) / (1 − (1 − ε)²)
    let det = 1.0 - (1.0 - eps) * (1.0 - eps);
    let want = [1.0 / det, -(1.0 - eps) / det];
    for (got, want) in sol.iter().zip(want) {
        assert!((got - want).abs() <= 1e-5 * want.abs(), "{got} vs {want}");
    }
    assert!(sol[2..].iter().all(|v| *v == 0.0));
}

/// The matrix-free product of `StepOperator` equals the assembled matrix (warped tangent,
/// tensile stress stiffness, node diagonal, directional dashpots (one on a fixed node),
/// projected fixed DOFs) times the vector, at a
/// stretched, sheared and rotated state where the membrane is partly in tension and partly
/// in compression.
#[test]
fn matrix_free_step_operator_equals_the_assembled_matrix() {
    let (mesh, model) = box_with_membrane_lid();
    let q = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(-1.0, 2.0, 0.5)), 0.7);
    let x: Vec<Point3<f64>> = mesh
        .nodes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let wobble = 0.01 * ((i * 37 % 11) as f64 - 5.0);
            let stretched = Point3::new(
                1.03 * p.x + 0.02 * p.y,
                0.98 * p.y + wobble * p.z,
                p.z + 0.01 * p.x * p.y + 0.3 * wobble * p.x,
            );
            q * stretched + Vector3::new(0.2, -0.4, 1.0)
        })
        .collect();
    let mut state = CorotationalState::new(&model);
    state.update(&model, &x).unwrap();
    assert!(state.failed_elements().is_empty());
    let fixed = FixedDofs::from_nodes(x.len(), &mesh.nodes_on_plane(0, 0.0)).unwrap();
    let diag: Vec<f64> = (0..x.len()).map(|v| 3.0 + 0.5 * v as f64).collect();
    let fixed_node = mesh.nodes_on_plane(0, 0.0)[0];
    let dashpots: Vec<Dashpot> = [1, x.len() as u32 / 2, x.len() as u32 - 1, fixed_node]
        .iter()
        .map(|&node| Dashpot {
            node,
            coefficient: 7.0 + node as f64,
            direction: Vector3::new(0.3, -0.4, 0.5 + 0.01 * node as f64).normalize(),
        })
        .collect();
    let scale = 0.04 * 0.0401;
    let pattern = SparsePattern::new(&model);
    let mut values = pattern.zero_values();
    pattern
        .assemble(&model, &state, scale, Some(&diag), &fixed, &mut values)
        .unwrap();
    pattern
        .add_membrane_stress_stiffness(&model, &x, &state, scale, &fixed, &mut values)
        .unwrap();
    pattern
        .add_dashpots(&dashpots, &fixed, &mut values)
        .unwrap();
    let a = dense(&pattern, &values);
    let mut operator = StepOperator::new(&model);
    operator.update(&model, &x, &state).unwrap();
    let n = model.dof_count();
    for round in 0..3 {
        let p: Vec<f64> = (0..n)
            .map(|i| (((i + round) * 7919) % 23) as f64 / 11.0 - 1.0)
            .collect();
        let mut y = vec![0.0; n];
        operator
            .apply(&model, &state, scale, &diag, &dashpots, &fixed, &p, &mut y)
            .unwrap();
        let want = &a * DVector::from_vec(p);
        let err = (DVector::from_vec(y) - &want).norm();
        println!(
            "round {round}: |Ap - A_assembled p| = {err:e}, |Ap| = {:e}",
            want.norm()
        );
        assert!(err <= 1e-12 * want.norm());
    }
}
