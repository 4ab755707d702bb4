//! What `atlas info` reports: per region its element count, volume or area, mass and mesh
//! quality, each ossicle's volume and mass, with the materials, boundary sets, load surfaces
//! and landmarks of the atlas.

use serde::Serialize;

use super::materials::KG_PER_M3_TO_G_PER_MM3;
use super::model::{Atlas, MaterialInfo, Part};
use crate::mesh::quality::quality_stats;

/// One region's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RegionSummary {
    pub label: u16,
    pub name: String,
    pub part: Part,
    pub material: String,
    pub elements: usize,
    /// Tetrahedra: volume \[mm³\]; membranes: area \[mm²\].
    pub size: f64,
    pub unit: &'static str,
    /// Volume (or area × thickness) × density \[mg\]; NaN (JSON null) without a material or,
    /// for a membrane, a thickness.
    pub mass_mg: f64,
    /// Tetrahedra only: dihedral angles \[deg\] and radius-edge ratios.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<QualitySummary>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct QualitySummary {
    pub min_dihedral_deg: f64,
    pub median_min_dihedral_deg: f64,
    pub median_radius_edge: f64,
    pub max_radius_edge: f64,
}

/// One ossicle's figures: the sums over its regions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OssicleSummary {
    /// Volume of its tetrahedra.
    pub volume_mm3: f64,
    /// Its volume in the shape the mesh was built from, when every region of it records one
    /// (`RegionInfo::shape_volume_mm3`): the volume its mass belongs to.
    pub shape_volume_mm3: Option<f64>,
    pub mass_mg: f64,
}

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AtlasSummary {
    pub name: String,
    pub side: crate::ear::Side,
    pub nodes: usize,
    pub tetrahedra: usize,
    pub membrane_triangles: usize,
    pub regions: Vec<RegionSummary>,
    /// Malleus, incus and stapes, by name.
    pub ossicles: std::collections::BTreeMap<&'static str, OssicleSummary>,
    pub materials: std::collections::BTreeMap<String, MaterialInfo>,
    pub node_sets: std::collections::BTreeMap<String, usize>,
    pub surfaces: std::collections::BTreeMap<String, usize>,
    /// Landmark positions at the rest shape \[mm\].
    pub landmarks: std::collections::BTreeMap<&'static str, [f64; 3]>,
    pub provenance: std::collections::BTreeMap<String, String>,
}

/// Summarises `atlas` at its rest shape.
pub fn summarise(atlas: &Atlas) -> AtlasSummary {
    let m = &atlas.mesh;
    // mm³ × g/mm³ = g; 1 g = 1e3 mg
    let mass_mg = |material: &str, volume_mm3: f64| {
        atlas.materials.get(material).map_or(f64::NAN, |mi| {
            volume_mm3 * mi.density_kg_m3 * KG_PER_M3_TO_G_PER_MM3 * 1e3
        })
    };
    let regions: Vec<RegionSummary> = atlas
        .regions
        .iter()
        .map(|r| {
            let tets: Vec<usize> = (0..m.tets.tets.len())
                .filter(|&t| m.tets.regions[t] == r.label)
                .collect();
            if tets.is_empty() {
                let tris: Vec<&[u32; 3]> = m
                    .triangles
                    .iter()
                    .zip(&m.triangle_regions)
                    .filter(|(_, l)| **l == r.label)
                    .map(|(t, _)| t)
                    .collect();
                let area = tris
                    .iter()
                    .map(|t| {
                        let [a, b, c] = t.map(|v| m.tets.nodes[v as usize]);
                        0.5 * (b - a).cross(&(c - a)).norm()
                    })
                    .sum();
                return RegionSummary {
                    label: r.label,
                    name: r.name.clone(),
                    part: r.part,
                    material: r.material.clone(),
                    elements: tris.len(),
                    size: area,
                    unit: "mm^2",
                    mass_mg: mass_mg(&r.material, area * r.thickness_mm.unwrap_or(f64::NAN)),
                    quality: None,
                };
            }
            let q = quality_stats(&m.tets, |t| m.tets.regions[t] == r.label);
            let volume = m.tets.region_volume(r.label);
            RegionSummary {
                label: r.label,
                name: r.name.clone(),
                part: r.part,
                material: r.material.clone(),
                elements: tets.len(),
                size: volume,
                unit: "mm^3",
                mass_mg: mass_mg(&r.material, volume),
                quality: Some(QualitySummary {
                    min_dihedral_deg: q.min_dihedral_deg,
                    median_min_dihedral_deg: q.median_min_dihedral_deg,
                    median_radius_edge: q.median_radius_edge,
                    max_radius_edge: q.max_radius_edge,
                }),
            }
        })
        .collect();
    let ossicles = Part::BONES
        .iter()
        .map(|&part| {
            let of_part = regions.iter().filter(|r| r.part == part);
            let summary = OssicleSummary {
                volume_mm3: of_part.clone().map(|r| r.size).sum(),
                shape_volume_mm3: atlas
                    .regions
                    .iter()
                    .filter(|r| r.part == part)
                    .map(|r| r.shape_volume_mm3)
                    .sum(),
                mass_mg: of_part.map(|r| r.mass_mg).sum(),
            };
            (part.name(), summary)
        })
        .collect();
    AtlasSummary {
        name: atlas.name.clone(),
        side: atlas.side,
        nodes: m.tets.nodes.len(),
        tetrahedra: m.tets.tets.len(),
        membrane_triangles: m.triangles.len(),
        regions,
        ossicles,
        materials: atlas.materials.clone(),
        node_sets: atlas
            .node_sets
            .iter()
            .map(|(k, v)| (k.clone(), v.len()))
            .collect(),
        surfaces: atlas
            .surfaces
            .iter()
            .map(|(k, v)| (k.clone(), v.len()))
            .collect(),
        landmarks: {
            let l = atlas.landmark_positions(atlas.nodes());
            crate::ear::LandmarkName::ALL
                .iter()
                .map(|n| {
                    let p = l.get(*n);
                    (n.key(), [p.x, p.y, p.z])
                })
                .collect()
        },
        provenance: atlas.provenance.clone(),
    }
}
