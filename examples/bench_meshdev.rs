//! Benchmark of the symmetric surface comparison: two ~100,000-triangle closed surfaces (a
//! torus and a displaced, differently tessellated torus), 200,000 area samples on each.
//!
//! `cargo run --release --example bench_meshdev` prints the time of `meshdev::compare`
//! (median of 5) and of its parts; add `-- --trimesh` to time Python trimesh's
//! `proximity.closest_point` on the same samples once (slow) and print the speed-up.

#[path = "../tests/common/external.rs"]
#[allow(dead_code)]
mod external;
#[path = "../tests/common/python.rs"]
mod python;
#[path = "../tests/common/trimesh_io.rs"]
mod trimesh_io;

use std::time::Instant;

use nalgebra::{Point3, Vector3};
use otoatlas::mesh::{TriMesh, shapes};
use otoatlas::meshdev::{Bvh, CompareOptions, Sampling, SignedSurface, compare, sample_surface};
use rayon::prelude::*;

const SAMPLES: usize = 200_000;

fn seconds(start: Instant) -> f64 {
    start.elapsed().as_secs_f64()
}

/// CPU time (user + system) of this process in seconds, from /proc/self/stat (Linux,
/// 100 ticks per second); `None` elsewhere. Other agents share the 2 cores, so CPU time
/// is reported next to wall time.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit(')').next()?.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg").map_or_else(|_| "n/a".into(), |s| s.trim().to_string())
}

/// A torus of the same size, tessellated differently, with a 0.1 mm wave, shifted.
fn displaced_torus() -> TriMesh {
    let mut m = shapes::torus(10.0, 3.0, 200, 250);
    for v in &mut m.vertices {
        let u = v.y.atan2(v.x);
        let scale = 1.0 + 0.01 * (5.0 * u).sin();
        *v = Point3::new(v.x * scale, v.y * scale, v.z) + Vector3::new(0.05, -0.03, 0.02);
    }
    m
}

fn main() {
    let reference = shapes::torus(10.0, 3.0, 250, 200);
    let test = displaced_torus();
    let options = CompareOptions {
        sampling: Sampling::Area {
            count: Some(SAMPLES),
            seed: 1,
        },
        ..CompareOptions::with_tolerance(0.2)
    };
    println!(
        "meshes: reference {} triangles, test {} triangles; {} samples per surface; {} threads",
        reference.triangles.len(),
        test.triangles.len(),
        SAMPLES,
        rayon::current_num_threads()
    );

    println!("load average before: {}", load_average());
    let mut times = Vec::new();
    let mut result = None;
    let cpu0 = cpu_seconds();
    for _ in 0..5 {
        let start = Instant::now();
        result = Some(compare(&test, &reference, &options).expect("valid meshes"));
        times.push(seconds(start));
    }
    let cpu = cpu_seconds().zip(cpu0).map(|(b, a)| (b - a) / 5.0);
    times.sort_by(f64::total_cmp);
    println!(
        "compare (symmetric, full): wall median {:.3} s, min {:.3} s, max {:.3} s; CPU {} s per call",
        times[2],
        times[0],
        times[4],
        cpu.map_or("n/a".into(), |c| format!("{c:.3}"))
    );
    if let Some(r) = &result {
        let s = &r.distances;
        println!(
            "  masd {:.4} assd {:.4} rms {:.4} hd {:.4} hd95 {:.4} bias {:+.4} dice@0.2 {:.4} meshdev mean/max {:.4}/{:.4} mm",
            s.masd,
            s.assd,
            s.rms,
            s.hd,
            s.hd95,
            s.bias,
            s.surface_dice,
            s.meshdev_mean,
            s.meshdev_max
        );
    }

    let start = Instant::now();
    let signed = SignedSurface::new(&reference, "reference").expect("valid");
    let t_signed = seconds(start);
    let start = Instant::now();
    let test_bvh = Bvh::new(&test, "test").expect("valid");
    let t_bvh = seconds(start);
    let start = Instant::now();
    let a = sample_surface(&test, &options.sampling).expect("valid mesh");
    let b = sample_surface(&reference, &options.sampling).expect("valid mesh");
    let t_sample = seconds(start);
    let start = Instant::now();
    let d_a: Vec<f64> = a
        .points
        .par_iter()
        .map(|p| signed.signed_distance(p).abs())
        .collect();
    let t_a = seconds(start);
    let start = Instant::now();
    let d_b: Vec<f64> = b
        .points
        .par_iter()
        .map(|p| test_bvh.closest(p).distance)
        .collect();
    let t_b = seconds(start);
    let start = Instant::now();
    let one: f64 = b
        .points
        .iter()
        .take(50_000)
        .map(|p| test_bvh.closest(p).distance)
        .sum();
    let t_one = seconds(start);
    println!(
        "  parts: BVH+pseudonormals {:.3} s, BVH {:.3} s, sampling both {:.3} s, signed test->ref {:.3} s, ref->test {:.3} s",
        t_signed, t_bvh, t_sample, t_a, t_b
    );
    println!(
        "  per query: {:.2} us wall (all threads), {:.2} us on one thread (checksum {:.3})",
        1e6 * (t_a + t_b) / (2 * SAMPLES) as f64,
        1e6 * t_one / 50_000.0,
        one
    );

    if std::env::args().any(|a| a == "--trimesh") {
        let dir = tempfile::tempdir().expect("temp dir");
        let start = Instant::now();
        if let Some(t) = trimesh_io::run_trimesh_check(dir.path(), &test, &reference, &a, &b) {
            println!(
                "trimesh {}: closest-point queries, both directions: {:.2} s (script total {:.1} s); speed-up of compare (wall median): {:.0}x",
                t.version,
                t.seconds,
                seconds(start),
                t.seconds / times[2]
            );
            // (largest |ours − trimesh|, samples where ours is the farther by > 1e-12 mm)
            let worst = |ours: &[f64], theirs: &[f64]| {
                let farther = ours.iter().zip(theirs).filter(|(x, y)| **x > **y + 1e-12);
                let largest = ours
                    .iter()
                    .zip(theirs)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max);
                (largest, farther.count())
            };
            for (label, mine, theirs, dist) in [
                (
                    "test->ref",
                    d_a.as_slice(),
                    &t.test_to_ref,
                    result.as_ref().map(|r| r.distances.test_to_ref),
                ),
                (
                    "ref->test",
                    d_b.as_slice(),
                    &t.ref_to_test,
                    result.as_ref().map(|r| r.distances.ref_to_test),
                ),
            ] {
                if let Some(s) = dist {
                    println!(
                        "  {label}: trimesh mean {:.5} max {:.5} p95 {:.5}; ours {:.5} {:.5} {:.5}; largest per-sample difference {:.1e} mm, ours farther on {} samples",
                        theirs.mean,
                        theirs.max,
                        theirs.p95,
                        s.mean,
                        s.max,
                        s.p95,
                        worst(mine, &theirs.distances).0,
                        worst(mine, &theirs.distances).1
                    );
                }
            }
        }
    }
}
