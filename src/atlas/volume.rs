//! The atlas's volume mesh: the anatomy's labelled regions (ossicles, joints, ligaments,
//! tendons) meshed into conforming tetrahedra by the multi-domain mesher. Joints, ligaments,
//! tendons and the stapes (crura about 0.3 mm) are declared thin so they survive the lattice.

use crate::atlas::{Anatomy, Bone, Region};
use crate::mesh::mesher::{MeshOutput, MesherError, MesherParams, mesh_domain};

/// Target edge of the default atlas \[mm\]: about 7,600 tetrahedra for the chain and its
/// ligaments (the source study's atlas: 4,361). The coarsest lattice whose malleus is one
/// face-connected piece: at 0.34-0.35 mm the manubrium's tip, which holds the umbo, hangs on
/// the tensor tympani tendon only and the transfer function is 5-6 dB off the fine atlas;
/// from 0.33 mm down it is within 1 dB (docs/mechanics.md, Convergence). It is also the
/// mesher's default (one constant, `mesh::mesher::DEFAULT_TARGET_EDGE_MM`).
pub const DEFAULT_EDGE_MM: f64 = crate::mesh::mesher::DEFAULT_TARGET_EDGE_MM;
/// Target edge of the fine variant for convergence studies \[mm\]: about 200,000 tetrahedra.
pub const FINE_EDGE_MM: f64 = 0.11;

/// The regions that need the mesher's thin-structure rule.
pub fn thin_regions() -> Vec<u16> {
    Region::ALL
        .iter()
        .filter(|r| r.bone().is_none() || **r == Region::Stapes)
        .map(|r| r.label())
        .collect()
}

/// The labels of `bone`'s regions.
fn bone_labels(bone: Bone) -> Vec<u16> {
    bone.regions().iter().map(|r| r.label()).collect()
}

/// The unions whose boundary must be a manifold besides each region's: each bone's regions
/// (its exported surface) and all regions (the whole chain).
pub fn manifold_groups() -> Vec<Vec<u16>> {
    vec![
        bone_labels(Bone::Malleus),
        bone_labels(Bone::Incus),
        Region::ALL.iter().map(|r| r.label()).collect(),
    ]
}

/// The groups that may share no node: each bone's regions (bones meet only through their
/// joints; a node shared by two would bond them, and leave one of them out of the package
/// check's rigid bodies).
pub fn apart_groups() -> Vec<Vec<u16>> {
    [Bone::Malleus, Bone::Incus, Bone::Stapes]
        .into_iter()
        .map(bone_labels)
        .collect()
}

/// Meshes the anatomy's volumetric regions at the target edge length (mm).
pub fn mesh_anatomy(anatomy: &Anatomy, target_edge_mm: f64) -> Result<MeshOutput, MesherError> {
    let params = MesherParams {
        target_edge_mm,
        thin_regions: thin_regions(),
        manifold_groups: manifold_groups(),
        apart_groups: apart_groups(),
        ..MesherParams::default()
    };
    mesh_domain(anatomy, &params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality::quality_by_region;
    use crate::mesh::tet::BoundaryOf;
    use crate::mesh::topology::surface_topology;

    #[test]
    fn default_anatomy_meshes_into_a_conforming_atlas_sized_mesh() {
        let anatomy = Anatomy::default_right().unwrap();
        let out = mesh_anatomy(&anatomy, DEFAULT_EDGE_MM).unwrap();
        let m = &out.mesh;
        assert_eq!(out.report.repair.defects_left, 0);
        assert_eq!(out.report.repair.shared_nodes_left, 0);
        assert!(
            (4_000..=8_000).contains(&m.tets.len()),
            "{} tets",
            m.tets.len()
        );
        assert_eq!(m.inverted_count(), 0);
        // every region of Table 1 that is a volume is present
        let ids = m.region_ids();
        for r in Region::ALL {
            assert!(ids.contains(&r.label()), "{} missing", r.name());
        }
        for (region, q) in quality_by_region(m) {
            assert!(
                q.min_dihedral_deg >= 9.9,
                "region {region}: {}°",
                q.min_dihedral_deg
            );
        }
        // every region's boundary, each bone's (the union of its regions) and the whole
        // chain's are closed, manifold and outward; the whole is one connected system
        for r in Region::ALL {
            let b = m.boundary(BoundaryOf::Region(r.label())).surface;
            assert!(
                surface_topology(&b).is_closed_oriented_manifold(),
                "{}",
                r.name()
            );
        }
        for group in manifold_groups() {
            let b = m.boundary(BoundaryOf::Regions(&group)).surface;
            let topo = surface_topology(&b);
            assert!(topo.is_closed_oriented_manifold(), "{group:?}: {topo:?}");
        }
        let whole = m.boundary(BoundaryOf::Whole).surface;
        let topo = surface_topology(&whole);
        assert_eq!((topo.components, topo.border_edges), (1, 0), "{topo:?}");
        // volumes within 10 % of the implicit anatomy's (malleus ~10.3 mm³, measured by
        // lattice integration in tests/atlas_anatomy.rs)
        let malleus: f64 = [
            Region::MalleusHead,
            Region::MalleusNeck,
            Region::MalleusHandle,
        ]
        .iter()
        .map(|r| m.region_volume(r.label()))
        .sum();
        assert!((malleus - 10.25).abs() < 1.0, "malleus {malleus} mm³");
        // deterministic
        let again = mesh_anatomy(&anatomy, DEFAULT_EDGE_MM).unwrap();
        assert_eq!(again.mesh, out.mesh);
    }
}
