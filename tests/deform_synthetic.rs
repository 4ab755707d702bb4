//! The deformable stage against analytic truth: a bone block imaged with partial volume,
//! blur and noise; the "atlas" is a smaller, shifted tetrahedral block; after the stage its
//! surface must sit on the true block's surface (scored with meshdev against the exact box).

mod common;

use common::BoxMesh;
use nalgebra::{Matrix3, Point3, Vector3};
use otoatlas::config::Config;
use otoatlas::fem::{FemModel, MembraneElements, TetElements, TetMaterial};
use otoatlas::image::Sampler;
use otoatlas::mesh::tet::BoundaryOf;
use otoatlas::mesh::{TetMesh, TriMesh, shapes};
use otoatlas::meshdev::{CompareOptions, compare};
use otoatlas::phantom::imaging::{Grid, ImagingParams, render};
use otoatlas::register::deform::{DeformConfig, ProbeKind, ProbeTriangle, deform};

#[test]
fn a_shrunken_shifted_block_deforms_onto_the_imaged_block() {
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(3.0, 2.4, 2.0));
    let field = move |p: &Point3<f64>| {
        let inside = (0..3).all(|a| p[a] > lo[a] && p[a] < hi[a]);
        if inside { 1800.0 } else { -1000.0 }
    };
    let grid = Grid {
        dims: [30, 27, 25],
        spacing: [0.2; 3],
        origin: Vector3::new(-1.3, -1.4, -1.5),
        direction: Matrix3::identity(),
    };
    let image = render(&field, &grid, &ImagingParams::clean(11));
    let sampler = Sampler::new(&image).unwrap();

    // the atlas: 12 % smaller, off-centre by up to 0.3 mm
    let mesh = BoxMesh::new([3.0 * 0.88, 2.4 * 0.88, 2.0 * 0.88], [15, 12, 10]);
    let nodes: Vec<Point3<f64>> = mesh
        .nodes
        .iter()
        .map(|p| p + Vector3::new(0.36, 0.0, 0.24))
        .collect();
    let materials = [TetMaterial {
        youngs_modulus: 1.0,
        poisson_ratio: 0.3,
        density: 1e-6,
    }];
    // the pipeline's knobs, but a softer body: this block must stretch 12 % elastically, which
    // the similarity fit does for a real case before the deformable stage
    let cfg = DeformConfig {
        regularisation_modulus_pa: 1000.0,
        ..Config::default_config().unwrap().deform
    };
    let scaled = [TetMaterial {
        youngs_modulus: cfg.regularisation_modulus_pa,
        ..materials[0]
    }];
    let material_index = vec![0u32; mesh.tets.len()];
    let model = FemModel::new(
        &nodes,
        TetElements {
            cells: &mesh.tets,
            material_index: &material_index,
            materials: &scaled,
        },
        MembraneElements::none(),
    )
    .unwrap();
    // the Kuhn split leaves half the tets negatively oriented; boundaries need them positive
    let mut tet_mesh = TetMesh {
        nodes: nodes.clone(),
        tets: mesh.tets.clone(),
        regions: vec![1; mesh.tets.len()],
    };
    tet_mesh.orient_positive();
    let faces = tet_mesh.boundary(BoundaryOf::Whole).node_triangles();
    let probes: Vec<ProbeTriangle> = faces
        .iter()
        .map(|f| ProbeTriangle {
            nodes: *f,
            kind: ProbeKind::Bone,
        })
        .collect();

    let truth = shapes::box_mesh(lo, hi, 12);
    let surface = |x: &[Point3<f64>]| TriMesh {
        vertices: x.to_vec(),
        triangles: faces.clone(),
    };
    let options = CompareOptions::with_tolerance(0.2);
    let before = compare(&surface(&nodes), &truth, &options)
        .unwrap()
        .distances;

    let result = deform(&model, &probes, &sampler, 0.2, &cfg).unwrap();
    let after = compare(&surface(&result.positions), &truth, &options)
        .unwrap()
        .distances;
    eprintln!(
        "MASD before {:.3} mm, after {:.3} mm; HD95 {:.3} -> {:.3}; {} iterations, {:?}",
        before.masd,
        after.masd,
        before.hd95,
        after.hd95,
        result.history.len(),
        result.status
    );
    assert!(
        before.masd > 0.1,
        "the test must start off the truth: {}",
        before.masd
    );
    assert!(
        after.masd < 0.05,
        "MASD after deform {} mm (a quarter voxel is 0.05)",
        after.masd
    );
    assert!(after.hd95 < 0.2, "HD95 after deform {} mm", after.hd95);
}
