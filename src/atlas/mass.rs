//! Each volumetric region weighs what the shape it was meshed from weighs.
//!
//! The lattice mesher snaps boundary nodes onto curved interfaces, so a region's tetrahedra
//! are the shape with its curved surface cut by chords: at the default 0.33 mm edge the
//! regions have up to 15 % less volume than the anatomy they mesh (the manubrium 15 %, each
//! bone 5-7 %), a finer mesh less. Lumped masses from the mesh would make the same anatomy
//! lighter at a coarser edge, and a convergence study would compare ears of different weights.
//! The builder therefore records each region's volume in the shape (`shape_volume_mm3`, by
//! `region_volumes`) and scales its material's density by the shape's volume over the mesh's,
//! so that every mesh of an anatomy carries the anatomy's masses (docs/mechanics.md, "Masses
//! that do not depend on the mesh").

use std::collections::BTreeMap;

use super::model::{MaterialInfo, RegionInfo};
use crate::mesh::domain::region_volumes;
use crate::mesh::{LabelledDomain, TetMesh};

/// Lattice spacing of the shape's volume integration (mm): within 1 % of the converged volume
/// for every region of the default anatomy (the thinnest, the superior mallear ligament, 1.0 %
/// under), in about half a second on two cores.
pub const SHAPE_VOLUME_SPACING_MM: f64 = 0.05;

/// How the density correction is written after a material's source.
const CORRECTION_NOTE: &str = "; density x ";

/// Sets each volumetric region's `shape_volume_mm3` (regions without a membrane thickness
/// whose label `domain` holds; an empty region of the shape is left unset).
pub fn record_shape_volumes<D: LabelledDomain + ?Sized>(domain: &D, regions: &mut [RegionInfo]) {
    let shape = region_volumes(domain, SHAPE_VOLUME_SPACING_MM);
    for r in regions.iter_mut().filter(|r| r.thickness_mm.is_none()) {
        r.shape_volume_mm3 = shape
            .get(usize::from(r.label))
            .copied()
            .filter(|v| *v > 0.0);
    }
}

/// The shape's and the mesh's volume (mm³) of the regions made of each material, over the
/// regions with a shape volume and tetrahedra.
fn volumes_by_material<'a>(
    regions: &'a [RegionInfo],
    mesh: &TetMesh,
) -> BTreeMap<&'a str, (f64, f64)> {
    let mut by_material: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
    for r in regions {
        let Some(shape) = r.shape_volume_mm3 else {
            continue;
        };
        let entry = by_material.entry(&r.material).or_default();
        entry.0 += shape;
        entry.1 += mesh.region_volume(r.label);
    }
    by_material.retain(|_, (shape, mesh)| *shape > 0.0 && *mesh > 0.0);
    by_material
}

/// Scales the density of each material whose regions have a shape volume so that its
/// tetrahedra weigh what the shape does, and says so in the material's source.
pub fn restore_shape_masses(
    materials: &mut BTreeMap<String, MaterialInfo>,
    regions: &[RegionInfo],
    mesh: &TetMesh,
) {
    for (name, (shape, meshed)) in volumes_by_material(regions, mesh) {
        if let Some(m) = materials.get_mut(name) {
            let scale = shape / meshed;
            m.density_kg_m3 *= scale;
            m.source = format!(
                "{}{CORRECTION_NOTE}{scale:.3}: {meshed:.3} mm3 in the mesh for {shape:.3} mm3 in \
                 the shape (the shape's mass)",
                m.source
            );
        }
    }
}

/// The materials as the literature gives them, without `restore_shape_masses`'s correction
/// of the mesh they were built on: what another mesh of other shapes should start from.
pub fn without_mesh_correction(
    materials: &BTreeMap<String, MaterialInfo>,
    regions: &[RegionInfo],
    mesh: &TetMesh,
) -> BTreeMap<String, MaterialInfo> {
    let by_material = volumes_by_material(regions, mesh);
    materials
        .iter()
        .map(|(name, m)| {
            let mut m = m.clone();
            if let Some((shape, meshed)) = by_material.get(name.as_str()) {
                m.density_kg_m3 *= meshed / shape;
                if let Some((source, _)) = m.source.split_once(CORRECTION_NOTE) {
                    m.source = source.to_string();
                }
            }
            (name.clone(), m)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::model::Part;
    use nalgebra::Point3;

    /// Three unit-corner tetrahedra (1/6 mm³ each), labels 1, 2 (both of material `bone`) and 3
    /// (`soft`).
    fn mesh() -> TetMesh {
        let corner = |x: f64| {
            [
                Point3::new(x, 0.0, 0.0),
                Point3::new(x + 1.0, 0.0, 0.0),
                Point3::new(x, 1.0, 0.0),
                Point3::new(x, 0.0, 1.0),
            ]
        };
        TetMesh {
            nodes: [corner(0.0), corner(2.0), corner(4.0)].concat(),
            tets: vec![[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]],
            regions: vec![1, 2, 3],
        }
    }

    fn region(label: u16, material: &str, shape: Option<f64>) -> RegionInfo {
        RegionInfo {
            label,
            name: format!("r{label}"),
            part: Part::Connective,
            material: material.into(),
            thickness_mm: None,
            bending_thickness_mm: None,
            shape_volume_mm3: shape,
        }
    }

    fn material(density: f64) -> MaterialInfo {
        MaterialInfo {
            density_kg_m3: density,
            youngs_modulus_pa: 1e6,
            poisson_ratio: 0.3,
            source: "a book".into(),
        }
    }

    #[test]
    fn regions_of_one_material_share_its_correction_and_it_undoes_exactly() {
        let mesh = mesh();
        let sixth = 1.0 / 6.0;
        let regions = [
            region(1, "bone", Some(0.2)),
            region(2, "bone", Some(0.25)),
            region(3, "soft", None),
        ];
        let original: BTreeMap<String, MaterialInfo> = [
            ("bone".into(), material(2000.0)),
            ("soft".into(), material(1000.0)),
        ]
        .into();
        let mut materials = original.clone();
        restore_shape_masses(&mut materials, &regions, &mesh);
        // the two bone regions weigh what their shapes do, together
        let scale = 0.45 / (2.0 * sixth);
        assert!((materials["bone"].density_kg_m3 - 2000.0 * scale).abs() < 1e-9);
        assert!(
            materials["bone"]
                .source
                .starts_with("a book; density x 1.350: 0.333 mm3")
        );
        // a region without a shape volume keeps its material as it is
        assert_eq!(materials["soft"], original["soft"]);
        let undone = without_mesh_correction(&materials, &regions, &mesh);
        assert_eq!(undone["bone"].source, "a book");
        for name in ["bone", "soft"] {
            assert!(
                (undone[name].density_kg_m3 / original[name].density_kg_m3 - 1.0).abs() < 1e-12
            );
        }
    }
}
