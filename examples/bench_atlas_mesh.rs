//! Meshing the default anatomy: tetrahedra, nodes, time and quality for the default and the
//! fine atlas edge lengths.
//!
//! `cargo run --release --example bench_atlas_mesh`

use std::time::Instant;

use otoatlas::atlas::volume::{DEFAULT_EDGE_MM, FINE_EDGE_MM, mesh_anatomy};
use otoatlas::atlas::{Anatomy, Region};
use otoatlas::mesh::quality::quality_by_region;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let anatomy = Anatomy::default_right()?;
    for edge in [DEFAULT_EDGE_MM, FINE_EDGE_MM] {
        let start = Instant::now();
        let out = mesh_anatomy(&anatomy, edge)?;
        let m = &out.mesh;
        println!(
            "edge {edge} mm: {} tets, {} nodes, {:.2} s, volume {:.2} mm³, repair defects left {}",
            m.tets.len(),
            m.nodes.len(),
            start.elapsed().as_secs_f64(),
            m.volume(),
            out.report.repair.defects_left
        );
        for (label, q) in quality_by_region(m) {
            let name = Region::from_label(label).map_or("?", |r| r.name());
            println!(
                "  {name:<28} {:>7} tets {:>7.3} mm³  min dihedral {:>5.1}°  median-of-min {:>5.1}°  max radius-edge {:.2}",
                q.tets,
                m.region_volume(label),
                q.min_dihedral_deg,
                q.median_min_dihedral_deg,
                q.max_radius_edge
            );
        }
    }
    Ok(())
}
