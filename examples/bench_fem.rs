//! Benchmark of the FEM core on structured box meshes (6 tetrahedra per cube): model build,
//! pattern (once), symbolic analysis (once), corotational update, assembly, numeric
//! factorisation, solve, and a full spring equilibrium.
//!
//! Run: `cargo run --release --example bench_fem` (add `-- --large` for the ~200k-tet mesh).

#[path = "../tests/common/meshes.rs"]
#[allow(dead_code)]
mod meshes;

use std::time::Instant;

use meshes::BoxMesh;
use nalgebra::{Point3, Vector3};
use otoatlas::fem::{
    CorotationalState, Elements, FemModel, FixedDofs, ImplicitEuler, Rayleigh, SparseCholesky,
    SparsePattern, Spring, StaticOptions, StaticSolver, TetMaterial,
};

const MAT: TetMaterial = TetMaterial {
    youngs_modulus: 1.0e7,
    poisson_ratio: 0.3,
    density: 1.2e-3,
};

/// Best of `reps` wall-clock runs, in milliseconds.
fn best_ms(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn bench(size: [f64; 3], cells: [usize; 3], reps: usize, equilibrium: bool) {
    let mesh = BoxMesh::new(size, cells);
    let index = vec![0; mesh.tets.len()];
    let set = Elements {
        cells: &mesh.tets,
        material_index: &index,
        materials: &[MAT],
    };
    let t = Instant::now();
    let model = FemModel::new(&mesh.nodes, set, Elements::none()).expect("valid mesh");
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    println!(
        "mesh {:?} cells: {} tets, {} nodes, {} DOF; model build {build_ms:.1} ms",
        cells,
        model.tet_count(),
        model.node_count(),
        model.dof_count()
    );
    let t = Instant::now();
    let pattern = SparsePattern::new(&model);
    println!(
        "  pattern (once):            {:9.2} ms  nnz(lower A) = {}",
        t.elapsed().as_secs_f64() * 1e3,
        pattern.nnz()
    );
    let t = Instant::now();
    let mut chol = SparseCholesky::analyse(&pattern).expect("symbolic");
    println!(
        "  symbolic analysis (once):  {:9.2} ms  nnz(L) = {}",
        t.elapsed().as_secs_f64() * 1e3,
        chol.factor_nnz()
    );
    // A deformed state: the box bent and twisted a little.
    let x: Vec<Point3<f64>> = mesh
        .nodes
        .iter()
        .map(|p| p + Vector3::new(0.0, 0.01 * p.x * p.z, 0.005 * p.x * p.x))
        .collect();
    let mut state = CorotationalState::new(&model);
    let update = best_ms(reps, || state.update(&model, &x).expect("finite"));
    println!("  rotations + forces (par):  {update:9.2} ms");
    let clamp = mesh.nodes_on_plane(2, 0.0);
    let fixed = FixedDofs::from_nodes(model.node_count(), &clamp).expect("nodes");
    let mut values = pattern.zero_values();
    let assemble = best_ms(reps, || {
        pattern
            .assemble(&model, &state, 1.0, None, &fixed, &mut values)
            .expect("assembly")
    });
    println!("  assembly (scatter):        {assemble:9.2} ms");
    let numeric = best_ms(reps, || {
        chol.factorise(pattern.matrix(&values)).expect("SPD")
    });
    println!("  numeric factorisation:     {numeric:9.2} ms");
    let mut rhs = vec![1.0; model.dof_count()];
    let solve = best_ms(reps, || chol.solve_in_place(&mut rhs).expect("solve"));
    println!("  solve:                     {solve:9.2} ms");
    if !equilibrium {
        return;
    }
    // Registration-like load: top-face nodes pulled by springs towards displaced targets.
    let top = mesh.nodes_on_plane(2, size[2]);
    let springs: Vec<Spring> = top
        .iter()
        .map(|&n| Spring {
            node: n,
            target: mesh.nodes[n as usize] + Vector3::new(0.8, -0.4, 1.0),
            stiffness: 1.0e5,
        })
        .collect();
    let t = Instant::now();
    let mut solver = StaticSolver::new(&model, fixed).expect("solver");
    let setup = t.elapsed().as_secs_f64() * 1e3;
    let mut previous: Option<Vec<Point3<f64>>> = None;
    for tol in [1e-3, 1e-6, 1e-6] {
        let mut y = mesh.nodes.clone();
        let options = StaticOptions {
            tolerance_mm: tol,
            ..StaticOptions::default()
        };
        let t = Instant::now();
        let report = solver
            .solve_with_springs(&mut y, &springs, &options)
            .expect("equilibrium");
        let ms = t.elapsed().as_secs_f64() * 1e3;
        println!(
            "  spring equilibrium tol {tol:e} mm: {ms:9.1} ms, {} iterations ({:.1} ms/iter), \
             {} halvings, max residual {:.2e} µN (solver setup {setup:.1} ms)",
            report.iterations,
            ms / report.iterations as f64,
            report.halvings,
            report.max_residual
        );
        if tol == 1e-6 {
            if let Some(p) = &previous {
                println!("  repeated solve bitwise identical: {}", p == &y);
            }
            previous = Some(y);
        }
    }
    let free_fixed = FixedDofs::from_nodes(model.node_count(), &clamp).expect("nodes");
    let damping = Rayleigh {
        mass: 0.1,
        stiffness: 0.1e-3,
    };
    let mut euler = ImplicitEuler::new(&model, free_fixed, damping).expect("integrator");
    let mut y = x.clone();
    let mut v = vec![Vector3::zeros(); model.node_count()];
    let step = best_ms(reps, || {
        euler.step(&mut y, &mut v, 1e-4, None).expect("step");
    });
    println!("  implicit Euler step:       {step:9.2} ms");
}

fn main() {
    println!(
        "threads: rayon {}, faer {:?}",
        rayon::current_num_threads(),
        faer::get_global_parallelism()
    );
    bench([20.0, 10.0, 5.0], [20, 10, 5], 5, true);
    if std::env::args().any(|a| a == "--large") {
        bench([40.0, 30.0, 28.0], [40, 30, 28], 1, false);
    }
}
