//! Surface distances against analytic truth: concentric icospheres (radius difference up to
//! the tessellation's chord error), parallel planes, a mesh against itself, a box inside a
//! longer box (exact one-sided means, maxima, P95 and Surface Dice), and the
//! pseudonormal sign against exact box and torus signed distances; a reference prepared once
//! scores as a fresh comparison.

use nalgebra::Point3;
use otoatlas::mesh::spatial::SpatialError;
use otoatlas::mesh::{TriMesh, shapes};
use otoatlas::meshdev::{
    CompareOptions, Feature, MeshDevError, PreparedReference, Sampling, SignedSurface, compare,
    compare_prepared,
};

fn options(count: usize, tolerance: f64) -> CompareOptions {
    CompareOptions {
        sampling: Sampling::Area {
            count: Some(count),
            seed: 42,
        },
        ..CompareOptions::with_tolerance(tolerance)
    }
}

/// The square [0, 1]² at height z, n×n quads, normal +z (or −z if `down`).
fn plane(z: f64, n: usize, down: bool) -> TriMesh {
    let mut m = TriMesh::default();
    for i in 0..=n {
        for j in 0..=n {
            m.vertices
                .push(Point3::new(i as f64 / n as f64, j as f64 / n as f64, z));
        }
    }
    let id = |i: usize, j: usize| (i * (n + 1) + j) as u32;
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if down {
                m.triangles.extend([[a, c, b], [a, d, c]]);
            } else {
                m.triangles.extend([[a, b, c], [a, c, d]]);
            }
        }
    }
    m
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn concentric_icospheres_differ_by_the_radius_gap_up_to_the_chord_error() {
    let c = Point3::new(10.0, -4.0, 3.0);
    let (r1, r2) = (1.0, 1.25);
    let inner = shapes::icosphere(c, r1, 3);
    let outer = shapes::icosphere(c, r2, 3);
    // Face planes of the unit icosphere sit at cos θ_f from the centre; both spheres share
    // the directions. Inner → outer distances lie in [Δ·cos_min, Δ·cos_max] (outer is convex
    // and its planes are parallel to the inner's); outer → inner in [Δ·cos_min, Δ + ε₁] with
    // chord error ε₁ = r₁(1 − cos_min).
    let (cos_min, cos_max) = (0..inner.triangles.len())
        .map(|t| {
            inner
                .area_normal2(t)
                .normalize()
                .dot(&(inner.corners(t)[0] - c))
                / r1
        })
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    let gap = r2 - r1;
    let chord = r1 * (1.0 - cos_min);
    assert!(chord > 1e-4 && chord < 2e-2, "chord error {chord}");
    let eps = 1e-12;

    let result = compare(&inner, &outer, &options(10_000, 0.01)).unwrap();
    let s = &result.distances;
    let a = &s.test_to_ref;
    assert!(a.max <= gap * cos_max + eps && a.mean >= gap * cos_min - eps);
    assert!(a.p95 <= gap * cos_max + eps);
    let b = &s.ref_to_test;
    assert!(b.max <= gap + chord + eps && b.mean >= gap * cos_min - eps);
    assert!(close(s.masd, gap, chord), "masd {} vs {gap}", s.masd);
    assert!(s.hd <= gap + chord + eps && s.hd >= gap * cos_max - eps);
    // The test sphere is inside: every signed distance is negative.
    assert!(close(s.bias, -a.mean, 1e-12));
    assert!(result.deviation.quality.iter().all(|&q| q < 0.0));
    // Vertices of the inner sphere: within [Δ·cos_min, Δ] of the outer (a vertex of the
    // outer sphere is at Δ).
    assert!(s.meshdev_max <= gap + eps && s.meshdev_mean >= gap * cos_min - eps);
    assert_eq!(s.surface_dice, 0.0);
    // Swapping roles flips the sign and swaps the directed means.
    let swapped = compare(&outer, &inner, &options(10_000, 0.01)).unwrap();
    assert!(swapped.distances.bias > 0.0);
    assert!(close(swapped.distances.masd, s.masd, 2e-3 * gap));
}

#[test]
fn parallel_planes_are_exactly_the_offset_apart() {
    let reference = plane(0.0, 7, false);
    for (z, sign) in [(0.3, 1.0), (-0.3, -1.0)] {
        let test = plane(z, 10, false);
        let r = compare(&test, &reference, &options(20_000, 0.25)).unwrap();
        let s = &r.distances;
        for v in [
            s.masd,
            s.assd,
            s.rms,
            s.hd,
            s.hd95,
            s.mean_test_to_ref,
            s.mean_ref_to_test,
            s.meshdev_mean,
            s.meshdev_max,
            s.test_to_ref.p95,
            s.ref_to_test.p95,
        ] {
            assert!(close(v, 0.3, 1e-12), "{v}");
        }
        assert!(close(s.bias, 0.3 * sign, 1e-12));
        assert_eq!(s.surface_dice, 0.0);
        assert!(
            r.deviation
                .quality
                .iter()
                .all(|&q| close(q, 0.3 * sign, 1e-12))
        );
        let wide = compare(&test, &reference, &options(20_000, 0.35)).unwrap();
        assert_eq!(wide.distances.surface_dice, 1.0);
    }
    // A reference facing down sees the same offset with the opposite sign.
    let r = compare(
        &plane(0.3, 10, false),
        &plane(0.0, 7, true),
        &options(1000, 0.1),
    )
    .unwrap();
    assert!(close(r.distances.bias, -0.3, 1e-12));
}

/// A reference prepared once (`PreparedReference`: indexed and sampled) scores each test
/// surface exactly as `compare` does from scratch, here planes at several exact offsets; a
/// comparison asking for another sampling than the reference was prepared with is refused.
#[test]
fn a_prepared_reference_scores_as_a_fresh_comparison() {
    let reference = plane(0.0, 7, false);
    let opts = options(5_000, 0.25);
    let prepared = PreparedReference::new(&reference, &opts.sampling).unwrap();
    for z in [0.1, -0.2, 0.3] {
        let test = plane(z, 10, false);
        let fresh = compare(&test, &reference, &opts).unwrap();
        let reused = compare_prepared(&test, &prepared, &opts).unwrap();
        assert_eq!(fresh, reused);
        assert!(close(reused.distances.masd, z.abs(), 1e-12));
    }
    let other = options(6_000, 0.25);
    assert!(matches!(
        compare_prepared(&plane(0.1, 10, false), &prepared, &other),
        Err(MeshDevError::InvalidOption {
            field: "sampling",
            ..
        })
    ));
}

#[test]
fn a_mesh_against_itself_is_zero_everywhere() {
    let m = shapes::torus(3.0, 1.0, 60, 30);
    for sampling in [Sampling::default(), Sampling::VertexAreas] {
        let opts = CompareOptions {
            sampling,
            ..CompareOptions::with_tolerance(0.0)
        };
        let r = compare(&m, &m, &opts).unwrap();
        let s = &r.distances;
        for v in [
            s.masd,
            s.assd,
            s.rms,
            s.hd,
            s.hd95,
            s.bias.abs(),
            s.meshdev_max,
        ] {
            assert!(v <= 1e-12, "{v}");
        }
        assert_eq!(s.meshdev_max, 0.0);
        assert!(r.deviation.quality.iter().all(|&q| q == 0.0));
        assert_eq!(r.deviation.colours[0], [0xf7, 0xf7, 0xf7]);
        assert!(close(s.test_to_ref.area_mm2, m.area(), 1e-9 * m.area()));
        // Area samples land on the surface up to rounding, so they pass even a zero
        // tolerance only approximately; vertices pass exactly.
        if sampling == Sampling::VertexAreas {
            assert_eq!(s.surface_dice, 1.0);
        }
    }
}

/// Test = [0.2, 1.2]×[0, 1]², reference = [0, 2]×[0, 1]²: the test box is inside and shares
/// the four long faces.
///
/// Test → reference: 0 on the shared faces (area 4); on x = 0.2, min(0.2, g); on x = 1.2, g,
/// where g = distance to the unit square's border, P(g > t) = (1 − 2t)². Mean =
/// (1/6 + (1 − 0.6³)/6)/6, max 0.5 (face centre), P95: (1 − 2t)²/6 = 0.05.
/// Reference → test: 0.2 on x = 0 (area 1), 0.8 on x = 2 (area 1), on each long face
/// 0.2 − x for x < 0.2 and x − 1.2 for x > 1.2: mean 2.36/10, max and P95 0.8.
#[test]
fn box_inside_a_longer_box_has_known_one_sided_statistics() {
    let test = shapes::box_mesh(Point3::new(0.2, 0.0, 0.0), Point3::new(1.2, 1.0, 1.0), 4);
    let reference = shapes::box_mesh(Point3::origin(), Point3::new(2.0, 1.0, 1.0), 4);
    let r = compare(&test, &reference, &options(100_000, 0.1)).unwrap();
    let s = &r.distances;
    let mean_ab = (1.0 / 6.0 + (1.0 - 0.6f64.powi(3)) / 6.0) / 6.0;
    let p95_ab = (1.0 - 0.3f64.sqrt()) / 2.0;
    assert!(
        close(s.mean_test_to_ref, mean_ab, 5e-4),
        "{} vs {mean_ab}",
        s.mean_test_to_ref
    );
    assert!(
        close(s.mean_ref_to_test, 0.236, 1e-3),
        "{}",
        s.mean_ref_to_test
    );
    assert!(close(s.masd, 0.5 * (mean_ab + 0.236), 1e-3));
    assert!(close(s.assd, (6.0 * mean_ab + 2.36) / 16.0, 1e-3));
    assert!(s.test_to_ref.max <= 0.5 + 1e-12 && s.test_to_ref.max > 0.49);
    assert!(
        close(s.test_to_ref.p95, p95_ab, 3e-3),
        "{} vs {p95_ab}",
        s.test_to_ref.p95
    );
    assert!(close(s.ref_to_test.max, 0.8, 1e-12));
    assert!(close(s.ref_to_test.p95, 0.8, 1e-12));
    assert!(close(s.hd, 0.8, 1e-12) && close(s.hd95, 0.8, 1e-12));
    // Surface Dice@0.1: (4 + 2·0.36 + 4 + 0.8) / 16.
    assert!(
        close(s.surface_dice, 9.52 / 16.0, 2e-3),
        "{}",
        s.surface_dice
    );
    // Inside the reference: the signed distances are −d, so bias = −mean.
    assert!(close(s.bias, -s.mean_test_to_ref, 1e-12));
    // The test box's face-centre vertex (1.2, 0.5, 0.5) is 0.5 from the reference.
    assert_eq!(s.meshdev_max, 0.5);
    let centre = test
        .vertices
        .iter()
        .position(|v| *v == Point3::new(1.2, 0.5, 0.5))
        .unwrap();
    assert_eq!(r.deviation.quality[centre], -0.5);
    assert_eq!(r.deviation.colours[centre], [0x05, 0x30, 0x61]);
}

/// Exact signed distance to the box [0, 1]³: positive outside.
fn box_sdf(p: &Point3<f64>) -> f64 {
    let outside = (0..3)
        .map(|k| (-p[k]).max(p[k] - 1.0).max(0.0).powi(2))
        .sum::<f64>()
        .sqrt();
    if outside > 0.0 {
        outside
    } else {
        -(0..3)
            .map(|k| p[k].min(1.0 - p[k]))
            .fold(f64::INFINITY, f64::min)
    }
}

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn box_signed_distance_matches_the_exact_field() {
    let m = shapes::box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), 3);
    let surface = SignedSurface::new(&m, "reference").unwrap();
    let mut seed = 5;
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..20_000 {
        let p = Point3::new(
            lcg(&mut seed) * 2.0 - 0.5,
            lcg(&mut seed) * 2.0 - 0.5,
            lcg(&mut seed) * 2.0 - 0.5,
        );
        let exact = box_sdf(&p);
        let got = surface.signed_distance(&p);
        assert!(close(got, exact, 1e-12), "{p}: {got} vs {exact}");
        if exact < 0.0 {
            inside += 1
        } else {
            outside += 1
        }
    }
    assert!(inside > 1000 && outside > 1000);
    // Edge and corner regions, where a single face normal can give the wrong sign.
    let cases = [
        (Point3::new(1.1, 1.1, 0.5), 0.1 * 2f64.sqrt(), true),
        (Point3::new(1.1, 1.1, 1.1), 0.1 * 3f64.sqrt(), false),
        (Point3::new(-0.2, 0.5, -0.2), 0.2 * 2f64.sqrt(), true),
        (Point3::new(1.0, 1.0, 1.0 + 1e-9), 1e-9, false),
    ];
    for (p, d, edge) in cases {
        let hit = surface.bvh.closest(&p);
        assert!(close(hit.distance, d, 1e-12));
        assert!(
            matches!(hit.feature, Feature::Edge(_)) == edge,
            "{p}: {:?}",
            hit.feature
        );
        if !edge {
            assert!(matches!(hit.feature, Feature::Vertex(_)));
        }
        assert!(surface.signed_distance(&p) > 0.0);
    }
    // Just inside an edge and a corner.
    assert!(close(
        surface.signed_distance(&Point3::new(0.99, 0.99, 0.5)),
        -0.01,
        1e-12
    ));
    assert!(close(
        surface.signed_distance(&Point3::new(0.01, 0.02, 0.03)),
        -0.01,
        1e-12
    ));
}

/// Non-convex surface: the sign agrees with the torus' implicit function wherever the point
/// is farther from the surface than the tessellation's deviation.
#[test]
fn torus_sign_agrees_with_the_implicit_surface() {
    let (big, small) = (3.0, 1.0);
    let m = shapes::torus(big, small, 96, 48);
    let surface = SignedSurface::new(&m, "reference").unwrap();
    let mut seed = 9;
    let mut checked = 0;
    for _ in 0..20_000 {
        let p = Point3::new(
            lcg(&mut seed) * 10.0 - 5.0,
            lcg(&mut seed) * 10.0 - 5.0,
            lcg(&mut seed) * 3.0 - 1.5,
        );
        let exact = ((p.x.hypot(p.y) - big).powi(2) + p.z * p.z).sqrt() - small;
        // Chord error of the grid is about (R + r)(1 − cos(π/96)) < 2e-3.
        if exact.abs() < 0.01 {
            continue;
        }
        let got = surface.signed_distance(&p);
        assert_eq!(got.signum(), exact.signum(), "{p}: {got} vs {exact}");
        assert!(close(got, exact, 0.01), "{p}: {got} vs {exact}");
        checked += 1;
    }
    assert!(checked > 15_000);
    // The centre of the hole is outside, the tube's core inside.
    // The hole's nearest points are the chords of the inner equator, 2·cos(π/96) away.
    let hole = (big - small) * (std::f64::consts::PI / 96.0).cos();
    assert!(close(
        surface.signed_distance(&Point3::origin()),
        hole,
        1e-12
    ));
    assert!(surface.signed_distance(&Point3::new(0.0, big, 0.0)) < -0.99);
}

#[test]
fn results_are_deterministic_and_bad_input_is_reported() {
    let a = shapes::icosphere(Point3::origin(), 1.0, 3);
    let b = shapes::box_mesh(Point3::new(-0.8, -0.8, -0.8), Point3::new(0.9, 0.8, 0.8), 5);
    let opts = CompareOptions::with_tolerance(0.1);
    assert_eq!(
        compare(&a, &b, &opts).unwrap(),
        compare(&a, &b, &opts).unwrap()
    );
    let json = serde_json::to_value(compare(&a, &b, &opts).unwrap().distances).unwrap();
    for key in [
        "masd",
        "assd",
        "rms",
        "hd",
        "hd95",
        "bias",
        "surface_dice",
        "mean_test_to_ref",
        "mean_ref_to_test",
        "meshdev_mean",
        "meshdev_max",
    ] {
        assert!(json[key].is_f64(), "{key}");
    }

    let bad = |o: CompareOptions| compare(&a, &b, &o).unwrap_err();
    assert!(matches!(
        bad(CompareOptions::with_tolerance(-1.0)),
        MeshDevError::InvalidOption {
            field: "tolerance_mm",
            ..
        }
    ));
    assert!(matches!(
        bad(options(0, 0.1)),
        MeshDevError::InvalidOption {
            field: "sampling.count",
            ..
        }
    ));
    let mut flat = b.clone();
    for v in &mut flat.vertices {
        v.z = 0.0;
        v.y = 0.0;
    }
    assert_eq!(
        compare(&a, &flat, &opts).unwrap_err(),
        MeshDevError::ZeroArea { mesh: "reference" }
    );
    assert_eq!(
        compare(&TriMesh::default(), &b, &opts).unwrap_err(),
        MeshDevError::Spatial(SpatialError::Empty { mesh: "test" })
    );
}
