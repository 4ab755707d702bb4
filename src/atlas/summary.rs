//! What `atlas info` reports: per region its element count, volume or area and mesh quality,
//! with the materials, boundary sets, load surfaces and landmarks of the atlas.

use serde::Serialize;

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

/// The whole report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AtlasSummary {
    pub name: String,
    pub side: crate::ear::Side,
    pub nodes: usize,
    pub tetrahedra: usize,
    pub membrane_triangles: usize,
    pub regions: Vec<RegionSummary>,
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
    let regions = atlas
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
                    quality: None,
                };
            }
            let q = quality_stats(&m.tets, |t| m.tets.regions[t] == r.label);
            RegionSummary {
                label: r.label,
                name: r.name.clone(),
                part: r.part,
                material: r.material.clone(),
                elements: tets.len(),
                size: m.tets.region_volume(r.label),
                unit: "mm^3",
                quality: Some(QualitySummary {
                    min_dihedral_deg: q.min_dihedral_deg,
                    median_min_dihedral_deg: q.median_min_dihedral_deg,
                    median_radius_edge: q.median_radius_edge,
                    max_radius_edge: q.max_radius_edge,
                }),
            }
        })
        .collect();
    AtlasSummary {
        name: atlas.name.clone(),
        side: atlas.side,
        nodes: m.tets.nodes.len(),
        tetrahedra: m.tets.tets.len(),
        membrane_triangles: m.triangles.len(),
        regions,
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
