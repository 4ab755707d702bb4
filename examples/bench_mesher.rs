//! Mesher benchmark: a 2 mm-radius ball (33.5 mm³, about the ossicular chain's volume) at the
//! default edge length and at a fine one, as an analytic domain and as a closed triangle
//! surface (`SurfaceDomain`), plus an optional OBJ surface given on the command line.
//!
//! Run: `cargo run --release --example bench_mesher [-- path/to/closed_surface.obj]`

use std::time::Instant;

use nalgebra::Point3;
use otoatlas::mesh::LabelledDomain;
use otoatlas::mesh::io::obj::read_obj;
use otoatlas::mesh::mesher::{MesherParams, SurfaceDomain, mesh_domain};
use otoatlas::mesh::quality::quality_by_region;

struct Ball(f64);

impl LabelledDomain for Ball {
    fn bounds(&self) -> (Point3<f64>, Point3<f64>) {
        (Point3::from([-self.0; 3]), Point3::from([self.0; 3]))
    }
    fn region_count(&self) -> u16 {
        1
    }
    fn label(&self, p: &Point3<f64>) -> u16 {
        u16::from(p.coords.norm() < self.0)
    }
    fn signed_distance(&self, _: u16, p: &Point3<f64>) -> f64 {
        p.coords.norm() - self.0
    }
}

fn run(name: &str, domain: &dyn LabelledDomain, edge: f64) {
    let params = MesherParams {
        target_edge_mm: edge,
        ..MesherParams::default()
    };
    let start = Instant::now();
    let out = match mesh_domain(domain, &params) {
        Ok(out) => out,
        Err(e) => {
            println!("{name}: {e}");
            return;
        }
    };
    let secs = start.elapsed().as_secs_f64();
    let m = &out.mesh;
    let q = quality_by_region(m);
    let s = &out.report.snap;
    println!(
        "{name:<28} edge {edge:.3} mm: {:>7} tets {:>6} nodes, lattice {:>8} tets, {secs:>6.2} s, volume {:.3} mm³",
        m.tets.len(),
        m.nodes.len(),
        out.report.lattice_tets,
        m.volume()
    );
    for (r, q) in q {
        println!(
            "    region {r}: dihedral min {:.1}° median-of-min {:.1}° max {:.1}°, radius-edge median {:.3} max {:.3}; boundary nodes {} snapped {} held {} (mean offset {:.4} mm, max {:.4} mm); repair relabelled {}",
            q.min_dihedral_deg,
            q.median_min_dihedral_deg,
            q.max_dihedral_deg,
            q.median_radius_edge,
            q.max_radius_edge,
            s.boundary_nodes,
            s.snapped,
            s.held_back,
            s.mean_offset,
            s.max_offset,
            out.report.repair.relabelled
        );
    }
}

fn main() {
    println!("threads: {}", rayon::current_num_threads());
    let ball = Ball(2.0);
    println!(
        "exact ball volume {:.3} mm³",
        4.0 / 3.0 * std::f64::consts::PI * 8.0
    );
    run("analytic ball r=2", &ball, 0.35);
    run("analytic ball r=2", &ball, 0.115);
    let surface = otoatlas::mesh::shapes::uv_sphere(2.0, 50, 100);
    println!(
        "sphere surface: {} triangles, volume {:.3} mm³",
        surface.triangles.len(),
        surface.signed_volume()
    );
    match SurfaceDomain::new(&[surface]) {
        Ok(d) => {
            run("surface ball r=2", &d, 0.35);
            run("surface ball r=2", &d, 0.115);
        }
        Err(e) => println!("surface ball: {e}"),
    }
    if let Some(path) = std::env::args().nth(1) {
        match read_obj(std::path::Path::new(&path))
            .map_err(|e| e.to_string())
            .and_then(|s| {
                println!(
                    "{path}: {} triangles, volume {:.3} mm³",
                    s.triangles.len(),
                    s.signed_volume()
                );
                SurfaceDomain::new(&[s]).map_err(|e| e.to_string())
            }) {
            Ok(d) => {
                run("obj surface", &d, 0.35);
                run("obj surface", &d, 0.2);
                run("obj surface", &d, 0.1);
            }
            Err(e) => println!("{path}: {e}"),
        }
    }
}
