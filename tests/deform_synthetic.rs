//! The deformable stage against analytic truth: a bone block imaged with partial volume,
//! blur and noise; the "atlas" is a smaller, shifted tetrahedral block; after the stage its
//! surface must sit on the true block's surface (scored with meshdev against the exact box).
//! The surface level alone, from a block stretched differently along each axis, likewise,
//! with every element kept the right way out; on a block already on its edges it moves
//! nothing beyond the image noise.

use crate::common::BoxMesh;
use nalgebra::{Matrix3, Point3, Vector3};
use otoatlas::config::Config;
use otoatlas::fem::{FemModel, MembraneElements, TetElements, TetMaterial};
use otoatlas::image::Sampler;
use otoatlas::mesh::quality::{ElementFloors, REGISTRATION_SHAPE_QUALITY};
use otoatlas::mesh::tet::BoundaryOf;
use otoatlas::mesh::{TetMesh, TriMesh, shapes};
use otoatlas::meshdev::{CompareOptions, compare};
use otoatlas::phantom::imaging::{Grid, ImagingParams, render};
use otoatlas::progress::Silent;
use otoatlas::register::DeformSettings;
use otoatlas::register::deform::{
    DeformConfig, ProbeConfig, ProbeKind, ProbeTriangle, Steps, deform, probe,
};
use otoatlas::register::refine::{RefineStop, refine};

#[test]
fn a_shrunken_shifted_block_deforms_onto_the_imaged_block() {
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(3.0, 2.4, 2.0));
    let image = imaged_block(lo, hi);
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
    // the similarity fit does for a real case before the deformable stage; and the FEM level
    // run to its equilibrium (the pipeline stops it after a few iterations and lets the
    // surface level finish)
    let cfg = DeformConfig {
        regularisation_modulus_pa: 1000.0,
        max_iterations: 60,
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
    let (_, faces, probes) = oriented_with_probes(&nodes, &mesh.tets);

    let truth = shapes::box_mesh(lo, hi, 12);
    let surface = |x: &[Point3<f64>]| TriMesh {
        vertices: x.to_vec(),
        triangles: faces.clone(),
    };
    let options = CompareOptions::with_tolerance(0.2);
    let before = compare(&surface(&nodes), &truth, &options)
        .unwrap()
        .distances;

    let floors = ElementFloors::new(&mesh.tets, &nodes, &nodes, REGISTRATION_SHAPE_QUALITY);
    let result = deform(
        &model,
        &floors,
        &probes,
        &sampler,
        0.2,
        &cfg,
        Steps::Newton,
        &Silent,
    )
    .unwrap();
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

/// The block as a tetrahedral mesh at `nodes` (the Kuhn split leaves half the tets negatively
/// oriented; boundaries need them positive), its outer faces, and those faces as bone probes.
fn oriented_with_probes(
    nodes: &[Point3<f64>],
    tets: &[[u32; 4]],
) -> (TetMesh, Vec<[u32; 3]>, Vec<ProbeTriangle>) {
    let mut mesh = TetMesh {
        nodes: nodes.to_vec(),
        tets: tets.to_vec(),
        regions: vec![1; tets.len()],
    };
    mesh.orient_positive();
    let faces = mesh.boundary(BoundaryOf::Whole).node_triangles();
    let probes = faces
        .iter()
        .map(|f| ProbeTriangle {
            nodes: *f,
            kind: ProbeKind::Bone,
        })
        .collect();
    (mesh, faces, probes)
}

/// The imaged block of the tests: bone inside `[lo, hi]`, air around, 0.2 mm voxels, noise.
fn imaged_block(lo: Point3<f64>, hi: Point3<f64>) -> otoatlas::image::Volume {
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
    render(&field, &grid, &ImagingParams::clean(11))
}

#[test]
fn the_surface_level_moves_a_stretched_block_onto_the_imaged_block() {
    let (lo, hi) = (Point3::new(0.0, 0.0, 0.0), Point3::new(3.0, 2.4, 2.0));
    let image = imaged_block(lo, hi);
    let sampler = Sampler::new(&image).unwrap();
    let config = Config::default_config().unwrap();
    let truth = shapes::box_mesh(lo, hi, 12);
    let options = CompareOptions::with_tolerance(0.2);
    // (scale per axis, shift): off the truth by up to 0.2 mm; exactly on it
    for (scale, shift, on_truth) in [
        ([0.92, 1.08, 0.93], Vector3::new(0.1, -0.08, 0.06), false),
        ([1.0, 1.0, 1.0], Vector3::zeros(), true),
    ] {
        let block = BoxMesh::new([3.0, 2.4, 2.0], [15, 12, 10]);
        let centre = Vector3::new(1.5, 1.2, 1.0);
        let nodes: Vec<Point3<f64>> = block
            .nodes
            .iter()
            .map(|p| {
                let d = p.coords - centre;
                Point3::from(
                    centre + Vector3::new(d.x * scale[0], d.y * scale[1], d.z * scale[2]) + shift,
                )
            })
            .collect();
        let (mut mesh, faces, probes) = oriented_with_probes(&nodes, &block.tets);
        let surface = |x: &[Point3<f64>]| TriMesh {
            vertices: x.to_vec(),
            triangles: faces.clone(),
        };
        let before = compare(&surface(&nodes), &truth, &options)
            .unwrap()
            .distances;
        let mut x = nodes.clone();
        let record = refine(
            &mesh,
            &nodes,
            &probes,
            &mut x,
            &sampler,
            0.2,
            DeformSettings {
                articulate: &config.articulate,
                deform: &config.deform,
                refine: &config.refine,
                steps: Steps::Newton,
            },
        );
        let after = compare(&surface(&x), &truth, &options).unwrap().distances;
        mesh.nodes = x;
        eprintln!(
            "scale {scale:?}: MASD {:.3} -> {:.3} mm, HD95 {:.3} -> {:.3} mm; {record:?}",
            before.masd, after.masd, before.hd95, after.hd95
        );
        assert_eq!(mesh.inverted_count(), 0);
        assert!(
            matches!(record.stop, RefineStop::Plateau | RefineStop::Rounds),
            "{record:?}"
        );
        if on_truth {
            // noise and the blur that rounds the box's corners move the surface by less than
            // half a voxel anywhere, a tenth of one on average
            assert!(record.max_move_mm < 0.1, "{record:?}");
            assert!(after.masd < 0.02, "MASD {}", after.masd);
        } else {
            assert!(
                before.masd > 0.08,
                "the test must start off the truth: {}",
                before.masd
            );
            assert!(
                after.masd < 0.03,
                "MASD after the surface level {}",
                after.masd
            );
            assert!(
                after.hd95 < 0.1,
                "HD95 after the surface level {}",
                after.hd95
            );
        }
    }
}

// The border probe on its own, on images rendered by the phantom's imaging model.

fn probe_cfg() -> ProbeConfig {
    ProbeConfig {
        search_range_mm: 1.0,
        intensity_shift_hu: 2000.0,
        ratio_threshold: 0.15,
        bone_min_hu: 300.0,
        sheet_contrast_hu: 200.0,
    }
}

/// Bone for x < 2.13 mm, air beyond; rendered with partial volume and blur, no noise.
fn half_space() -> otoatlas::image::Volume {
    let field = |p: &Point3<f64>| if p.x < 2.13 { 1800.0 } else { -1000.0 };
    let grid = Grid {
        dims: [30, 8, 8],
        spacing: [0.2; 3],
        origin: Vector3::zeros(),
        direction: Matrix3::identity(),
    };
    render(
        &field,
        &grid,
        &ImagingParams {
            noise_sd_hu: 0.0,
            psf_fwhm_mm: 0.25,
            ..ImagingParams::clean(1)
        },
    )
}

#[test]
fn finds_a_bone_edge_from_inside_and_from_outside_within_a_fifth_of_a_voxel() {
    let v = half_space();
    let s = Sampler::new(&v).unwrap();
    for start in [1.63, 1.9, 2.3, 2.71] {
        let b = Point3::new(start, 0.8, 0.8);
        let border = probe(&s, &b, &Vector3::x(), ProbeKind::Bone, 0.2, &probe_cfg()).unwrap();
        assert!(
            (border.point.x - 2.13).abs() < 0.04,
            "from {start}: {}",
            border.point.x
        );
        assert!((border.offset_mm - (2.13 - start)).abs() < 0.04);
    }
    // with the normal reversed, the outward walk enters bone: that is not a bone boundary
    // seen from this side, and nothing else is in range
    let b = Point3::new(2.9, 0.8, 0.8);
    assert!(probe(&s, &b, &-Vector3::x(), ProbeKind::Bone, 0.2, &probe_cfg()).is_none());
}

#[test]
fn finds_a_thin_sheet_as_a_ridge() {
    let field = |p: &Point3<f64>| {
        if (p.x - 2.05).abs() < 0.05 {
            40.0
        } else {
            -1000.0
        }
    };
    let grid = Grid {
        dims: [30, 6, 6],
        spacing: [0.2; 3],
        origin: Vector3::zeros(),
        direction: Matrix3::identity(),
    };
    let v = render(
        &field,
        &grid,
        &ImagingParams {
            noise_sd_hu: 0.0,
            supersample: 5,
            ..ImagingParams::clean(1)
        },
    );
    let s = Sampler::new(&v).unwrap();
    let b = Point3::new(1.7, 0.6, 0.6);
    let border = probe(&s, &b, &Vector3::x(), ProbeKind::Sheet, 0.2, &probe_cfg()).unwrap();
    assert!((border.point.x - 2.05).abs() < 0.05, "{}", border.point.x);
}
