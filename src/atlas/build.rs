//! Building the atlas from the parametric anatomy: the volumetric regions meshed into
//! conforming tetrahedra, the eardrum triangulated and attached to the manubrium by shared
//! nodes, the Table 1 materials (each region weighing what the anatomy's does: `mass`), the
//! boundary-condition sites found on the mesh, and the landmarks tied to it. The result
//! depends only on the anatomy and the two edge lengths, and is deterministic (same inputs,
//! byte-identical files).

use std::collections::BTreeMap;

use nalgebra::Point3;

use super::attachment::{self, ATTACH_TOLERANCE_MM, Attachment};
use super::joint_layer::{JointLayer, joint_layers};
use super::mass::{record_shape_volumes, restore_shape_masses};
use super::materials::{
    ANNULAR_LIGAMENT_SOURCE, ANNULAR_LIGAMENT_STIFFNESS_N_PER_M, COCHLEAR_IMPEDANCE_PA_S_PER_M3,
    DAMPING_SOURCE, ISJ_DENSITY_KG_M3, ISJ_SOURCE, ISJ_YOUNG_PA, MALLEUS_DENSITY_KG_M3,
    MALLEUS_DENSITY_SOURCE, POISSON, RAYLEIGH, Structure, TABLE1, membrane_thickness_mm,
};
use super::membrane::{MembraneMesh, triangulate_eardrum};
use super::model::{
    Atlas, Damping, MaterialInfo, MeshPoint, Part, RegionInfo, Supports, TiedLandmarks, sets,
};
use super::region::{Bone, MembraneRegion, Region};
use super::volume::mesh_anatomy;
use super::{Anatomy, AnatomyError};
#[cfg(test)]
use crate::ear::Side;
use crate::mesh::TetMesh;
use crate::mesh::io::VolumeMesh;
use crate::mesh::mesher::MesherError;
use crate::mesh::tet::BoundaryOf;

/// Target edge of the eardrum triangles in the default atlas \[mm\]: about 2,500 triangles
/// (the source study: 2,492).
pub const DEFAULT_MEMBRANE_EDGE_MM: f64 = 0.24;
/// Target edge of the eardrum triangles in the fine atlas \[mm\]: √2 finer than the default,
/// about 5,000 triangles, every node of the attachment line tied to the manubrium (at 0.12 mm
/// one is refused on the fine lattice and the drum passes the chain less above 2 kHz:
/// docs/mechanics.md, "Masses that do not depend on the mesh").
pub const FINE_MEMBRANE_EDGE_MM: f64 = 0.17;

/// Why the atlas could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error(transparent)]
    Anatomy(#[from] AnatomyError),
    #[error(transparent)]
    Mesher(#[from] MesherError),
    #[error("atlas build: {what}")]
    Assembly { what: String },
}

fn assembly(what: impl Into<String>) -> BuildError {
    BuildError::Assembly { what: what.into() }
}

/// Builds the atlas of `anatomy` with tetrahedra of about `edge_mm` and membrane triangles
/// of about `membrane_edge_mm`, each region weighing what the anatomy's does (`mass`).
pub fn build_atlas(
    anatomy: &Anatomy,
    name: &str,
    edge_mm: f64,
    membrane_edge_mm: f64,
) -> Result<Atlas, BuildError> {
    let mut atlas = mesh_atlas(anatomy, name, edge_mm, membrane_edge_mm)?;
    record_shape_volumes(anatomy, &mut atlas.regions);
    restore_shape_masses(&mut atlas.materials, &atlas.regions, &atlas.mesh.tets);
    Ok(atlas)
}

/// `atlas`'s anatomy meshed again at other edges, with `atlas`'s own regions, materials,
/// damping and supports (so an atlas whose `atlas.json` was edited keeps its edits): the drum
/// convergence study's rebuilds, which would discard `build_atlas`'s measurement of the
/// anatomy's volumes.
pub fn remesh_atlas(
    anatomy: &Anatomy,
    atlas: &Atlas,
    edge_mm: f64,
    membrane_edge_mm: f64,
) -> Result<Atlas, BuildError> {
    let remeshed = mesh_atlas(anatomy, &atlas.name, edge_mm, membrane_edge_mm)?;
    Ok(Atlas {
        regions: atlas.regions.clone(),
        materials: atlas.materials.clone(),
        damping: atlas.damping.clone(),
        supports: atlas.supports.clone(),
        ..remeshed
    })
}

/// The atlas of `anatomy` at the given edges, its materials as `materials` makes them (no
/// region's mass restored to the anatomy's yet).
fn mesh_atlas(
    anatomy: &Anatomy,
    name: &str,
    edge_mm: f64,
    membrane_edge_mm: f64,
) -> Result<Atlas, BuildError> {
    let mut tets = mesh_anatomy(anatomy, edge_mm)?.mesh;
    tets.orient_positive();
    let layers = joint_layers(&tets, anatomy).map_err(assembly)?;
    let drum = anatomy.eardrum();
    let membrane = triangulate_eardrum(drum, membrane_edge_mm);
    let merged = attach_membrane(&mut tets, &membrane, drum.medial_normal)?;
    let (node_sets, surfaces) = boundary_sites(anatomy, &merged)?;
    let landmarks = tie_landmarks(&merged.mesh.tets, anatomy)?;
    let mut provenance = BTreeMap::new();
    provenance.insert("builder".into(), "otoatlas atlas build".into());
    provenance.insert("anatomy_sha256".into(), anatomy_digest(anatomy));
    provenance.insert("tet_edge_mm".into(), edge_mm.to_string());
    provenance.insert("membrane_edge_mm".into(), membrane_edge_mm.to_string());
    for layer in &layers {
        provenance.insert(
            format!("layer:{}", layer.region.name()),
            format!(
                "{:.3} mm thick in the mesh ({:.3} mm3 over {:.3} mm2) for {:.3} mm in the anatomy",
                layer.mesh_thickness_mm(),
                layer.volume_mm3,
                layer.area_mm2,
                layer.anatomical_thickness_mm
            ),
        );
    }
    provenance.insert(
        "manubrium_attachment".into(),
        format!(
            "{} membrane nodes tied to the manubrium ({} merged with its nodes, {} inserted into \
             its surface), {} left free, farthest move {:.3} mm",
            merged.attachment.merged + merged.attachment.inserted,
            merged.attachment.merged,
            merged.attachment.inserted,
            merged.attachment.refused,
            merged.attachment.farthest_mm
        ),
    );
    Ok(Atlas {
        name: name.to_string(),
        side: anatomy.side(),
        mesh: merged.mesh,
        regions: regions(),
        materials: materials(&layers),
        damping: Damping {
            rayleigh_alpha_per_s: RAYLEIGH.alpha_per_s,
            rayleigh_beta_s: RAYLEIGH.beta_s,
            cochlear_impedance_pa_s_per_m3: COCHLEAR_IMPEDANCE_PA_S_PER_M3,
            source: DAMPING_SOURCE.into(),
        },
        supports: Supports {
            annular_ligament_stiffness_n_per_m: ANNULAR_LIGAMENT_STIFFNESS_N_PER_M,
            source: ANNULAR_LIGAMENT_SOURCE.into(),
        },
        node_sets,
        surfaces,
        landmarks,
        provenance,
    })
}

/// The SHA-256 of `anatomy`'s canonical TOML, as the atlas's provenance `anatomy_sha256`
/// records it.
pub fn anatomy_digest(anatomy: &Anatomy) -> String {
    let text = toml::to_string(anatomy.spec()).unwrap_or_default();
    crate::io_util::sha256_hex(text.as_bytes())
}

/// The Table 1 regions: 15 volumetric, 2 membrane.
fn regions() -> Vec<RegionInfo> {
    let part_of = |r: Region| match r.bone() {
        Some(Bone::Malleus) => Part::Malleus,
        Some(Bone::Incus) => Part::Incus,
        Some(Bone::Stapes) => Part::Stapes,
        None => Part::Connective,
    };
    Region::ALL
        .iter()
        .map(|r| RegionInfo {
            label: r.label(),
            name: r.name().into(),
            part: part_of(*r),
            material: r.name().into(),
            thickness_mm: None,
            bending_thickness_mm: None,
            shape_volume_mm3: None,
        })
        .chain(
            [MembraneRegion::ParsTensa, MembraneRegion::ParsFlaccida].map(|m| {
                // a shell: the same thickness stretches and bends
                let h = Some(membrane_thickness_mm(m));
                RegionInfo {
                    label: m.id(),
                    name: m.name().into(),
                    part: Part::Eardrum,
                    material: m.name().into(),
                    thickness_mm: h,
                    bending_thickness_mm: h,
                    shape_volume_mm3: None,
                }
            }),
        )
        .collect()
}

/// One material per Table 1 row, named after its region: Table 1's values (the incudostapedial
/// joint's from [W16] and the malleus's density from its weighed mass, `materials`), each joint's
/// modulus scaled to its layer's thickness in the mesh (`JointLayer::stiffness_scale`).
fn materials(layers: &[JointLayer]) -> BTreeMap<String, MaterialInfo> {
    TABLE1
        .iter()
        .map(|(structure, rho, e)| {
            let (rho, e, table_source) = match structure {
                Structure::Volume(Region::IncudostapedialJoint) => {
                    (ISJ_DENSITY_KG_M3, ISJ_YOUNG_PA, ISJ_SOURCE)
                }
                Structure::Volume(
                    Region::MalleusHead | Region::MalleusNeck | Region::MalleusHandle,
                ) => (MALLEUS_DENSITY_KG_M3, *e, MALLEUS_DENSITY_SOURCE),
                _ => (*rho, *e, "Kazmitcheff et al. 2013, Table 1"),
            };
            let layer = layers
                .iter()
                .find(|l| Structure::Volume(l.region) == *structure);
            let e = e * layer.map_or(1.0, JointLayer::stiffness_scale);
            let (poisson, poisson_source) = match structure {
                Structure::Volume(_) => (
                    POISSON,
                    "Poisson's ratio: Sun, Gan et al. 2002, Biomech Model Mechanobiol 1:109",
                ),
                Structure::Membrane(_) => (
                    POISSON,
                    "Poisson's ratio: Sun, Gan et al. 2002, Biomech Model Mechanobiol 1:109; \
                     thickness: Kirikae 1960 (pars tensa), Lim 1970 (pars flaccida)",
                ),
            };
            let (name, source) = match structure {
                Structure::Volume(Region::TensorTympaniTendon) => (
                    Region::TensorTympaniTendon.name(),
                    "density: Kazmitcheff et al. 2013 Table 1; E: Koike, Wada & Kobayashi 2002, \
                     J Acoust Soc Am 111:1306 (via Gentil et al. 2016, Table 1)",
                ),
                Structure::Volume(r) => (r.name(), table_source),
                Structure::Membrane(m) => (m.name(), table_source),
            };
            let source = match layer {
                Some(l) => format!(
                    "{source}, x {:.3}: the layer is {:.3} mm thick in the mesh for {:.3} mm in \
                     the anatomy (same stiffness per area)",
                    l.stiffness_scale(),
                    l.mesh_thickness_mm(),
                    l.anatomical_thickness_mm
                ),
                None => source.to_string(),
            };
            (
                name.to_string(),
                MaterialInfo {
                    density_kg_m3: rho,
                    youngs_modulus_pa: e,
                    poisson_ratio: poisson,
                    source: format!("{source}; {poisson_source}"),
                },
            )
        })
        .collect()
}

/// Named node sets and named triangle surfaces of an atlas.
type NodeSets = BTreeMap<String, Vec<u32>>;
type Surfaces = BTreeMap<String, Vec<[u32; 3]>>;

/// The tetrahedra and the membrane on one node set.
struct Merged {
    mesh: VolumeMesh,
    rim: Vec<u32>,
    attachment: Attachment,
}

/// Appends the membrane to the tetrahedral mesh, every node of its manubrium attachment line
/// tied to the malleus (`attachment`).
fn attach_membrane(
    tets: &mut TetMesh,
    membrane: &MembraneMesh,
    medial: nalgebra::Vector3<f64>,
) -> Result<Merged, BuildError> {
    let tie = attachment::attach_membrane(tets, membrane, Region::MalleusHandle.label(), medial);
    let attached = tie.merged + tie.inserted;
    if attached < 3 {
        return Err(assembly(format!(
            "the eardrum could be attached to the manubrium at {attached} nodes only; expected \
             at least 3 of its attachment line within {ATTACH_TOLERANCE_MM} mm of the \
             manubrium's surface (is the umbo at the manubrium tip?)"
        )));
    }
    let triangles: Vec<[u32; 3]> = membrane
        .triangles
        .iter()
        .map(|t| t.map(|v| tie.membrane_node[v as usize]))
        .collect();
    let rim = membrane
        .rim
        .iter()
        .map(|&v| tie.membrane_node[v as usize])
        .collect();
    Ok(Merged {
        mesh: VolumeMesh {
            tets: std::mem::take(tets),
            triangles,
            triangle_regions: membrane.regions.iter().map(|r| r.id()).collect(),
        },
        rim,
        attachment: tie,
    })
}

/// Boundary-condition node sets and load surfaces found on the mesh.
fn boundary_sites(anatomy: &Anatomy, merged: &Merged) -> Result<(NodeSets, Surfaces), BuildError> {
    let mesh = &merged.mesh.tets;
    let mut node_sets = BTreeMap::new();
    node_sets.insert(sets::TYMPANIC_ANNULUS.to_string(), merged.rim.clone());
    // footplate: rim nodes (annular ligament) and medial face (cochlear load)
    let fp = anatomy.footplate();
    let stapes = mesh.boundary(BoundaryOf::Region(Region::Stapes.label()));
    let local = |p: &Point3<f64>| fp.frame.local(&(p - fp.center));
    let slab = 0.5 * fp.thickness + 0.05;
    let mut rim: Vec<u32> = stapes
        .node_of_vertex
        .iter()
        .copied()
        .filter(|&v| {
            let q = local(&mesh.nodes[v as usize]);
            let radial = ((q.x / fp.semi_axes[0]).powi(2) + (q.y / fp.semi_axes[1]).powi(2)).sqrt();
            q.z.abs() <= slab && radial >= 0.8
        })
        .collect();
    rim.sort_unstable();
    if rim.len() < 6 {
        return Err(assembly(format!(
            "found {} footplate rim nodes for the annular ligament; expected at least 6",
            rim.len()
        )));
    }
    node_sets.insert(sets::ANNULAR_LIGAMENT.to_string(), rim);
    let medial_face: Vec<[u32; 3]> = stapes
        .node_triangles()
        .into_iter()
        .filter(|t| {
            let [a, b, c] = t.map(|v| mesh.nodes[v as usize]);
            let n = (b - a).cross(&(c - a)).normalize();
            let centre = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            n.dot(&fp.frame.e3) > 0.7 && local(&centre).z > 0.0
        })
        .collect();
    if medial_face.is_empty() {
        return Err(assembly(
            "found no medial footplate face for the cochlear load",
        ));
    }
    // the wall end of every ligament and tendon: its nodes within the end cap
    for (region, anchor) in anatomy.anchors() {
        let radius = anatomy
            .band(region)
            .and_then(|t| t.radii.last().copied())
            .unwrap_or(0.2);
        let mut nodes: Vec<(f64, u32)> = mesh
            .tets
            .iter()
            .zip(&mesh.regions)
            .filter(|(_, r)| **r == region.label())
            .flat_map(|(t, _)| t.iter().copied())
            .map(|v| ((mesh.nodes[v as usize] - anchor).norm(), v))
            .collect();
        nodes.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        nodes.dedup_by_key(|n| n.1);
        let within: Vec<u32> = nodes
            .iter()
            .filter(|(d, _)| *d <= 1.2 * radius + 0.1)
            .map(|(_, v)| *v)
            .collect();
        let mut set = if within.len() >= 3 {
            within
        } else {
            nodes.iter().take(3).map(|(_, v)| *v).collect()
        };
        if set.len() < 3 {
            return Err(assembly(format!(
                "region {} has {} nodes; expected at least 3 for its wall anchor",
                region.name(),
                set.len()
            )));
        }
        set.sort_unstable();
        node_sets.insert(format!("{}{}", sets::ANCHOR_PREFIX, region.name()), set);
    }
    let mut surfaces = BTreeMap::new();
    surfaces.insert(sets::FOOTPLATE_MEDIAL.to_string(), medial_face);
    surfaces.insert(
        sets::EARDRUM_LATERAL.to_string(),
        merged.mesh.triangles.clone(),
    );
    Ok((node_sets, surfaces))
}

/// Ties the anatomy's landmarks to the tetrahedra.
fn tie_landmarks(mesh: &TetMesh, anatomy: &Anatomy) -> Result<TiedLandmarks, BuildError> {
    let l = anatomy.landmarks();
    let tie = |name: &str, p: Point3<f64>| {
        MeshPoint::locate(mesh, &p)
            .map(|(mp, _)| mp)
            .ok_or_else(|| assembly(format!("no tetrahedron to tie the {name} landmark to")))
    };
    Ok(TiedLandmarks {
        umbo: tie("umbo", l.umbo)?,
        incudomalleolar: tie("incudomalleolar", l.incudomalleolar)?,
        incudostapedial: tie("incudostapedial", l.incudostapedial)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::format::{default_atlas, manifest_string};
    use crate::atlas::model::sets;
    use crate::atlas::volume::DEFAULT_EDGE_MM;
    use crate::mesh::io::vtu::{VtuEncoding, vtu_string};

    #[test]
    fn the_embedded_atlas_is_what_the_builder_makes_from_the_anatomy() {
        let anatomy = Anatomy::default_right().unwrap();
        let atlas = build_atlas(
            &anatomy,
            "default",
            DEFAULT_EDGE_MM,
            DEFAULT_MEMBRANE_EDGE_MM,
        )
        .unwrap();
        // byte-identical to the committed files (rebuild with `otoatlas atlas build --out
        // assets/atlas` when the anatomy or the mesher changes)
        assert_eq!(
            manifest_string(&atlas).unwrap(),
            include_str!("../../assets/atlas/atlas.json")
        );
        assert_eq!(
            vtu_string(&atlas.mesh, &[], VtuEncoding::Base64).unwrap(),
            include_str!("../../assets/atlas/mesh.vtu")
        );
        assert_eq!(default_atlas().unwrap(), atlas);
    }

    #[test]
    fn the_default_atlas_is_one_system_with_its_sites_and_landmarks() {
        let anatomy = Anatomy::default_right().unwrap();
        let atlas = default_atlas().unwrap();
        let m = &atlas.mesh;
        // about 2,500 membrane triangles (the study: 2,492), sharing nodes with the manubrium
        assert!((2_000..=3_000).contains(&m.triangles.len()));
        let tet_nodes: std::collections::BTreeSet<u32> =
            m.tets.tets.iter().flatten().copied().collect();
        let shared = m
            .triangles
            .iter()
            .flatten()
            .filter(|v| tet_nodes.contains(v))
            .collect::<std::collections::BTreeSet<_>>();
        assert!(shared.len() >= 5, "{} shared nodes", shared.len());
        let handle: std::collections::BTreeSet<u32> = m
            .tets
            .tets
            .iter()
            .zip(&m.tets.regions)
            .filter(|(_, r)| **r == Region::MalleusHandle.label())
            .flat_map(|(t, _)| t.iter().copied())
            .collect();
        assert!(shared.iter().all(|v| handle.contains(v)));
        // the annulus lies on the anatomy's rim ellipse, in its plane
        let drum = anatomy.eardrum();
        for &v in &atlas.node_sets[sets::TYMPANIC_ANNULUS] {
            let p = m.tets.nodes[v as usize] - drum.annulus_center;
            assert!(p.dot(&drum.medial_normal).abs() < 1e-9);
            let (u, w) = (p.dot(&drum.superior), p.dot(&drum.anterior));
            let r = (u / drum.semi_axis_superior).powi(2) + (w / drum.semi_axis_anterior).powi(2);
            assert!((r - 1.0).abs() < 1e-9, "{r}");
        }
        // the footplate load face points into the vestibule and covers the footplate
        let fp = anatomy.footplate();
        let area: f64 = atlas.surfaces[sets::FOOTPLATE_MEDIAL]
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| m.tets.nodes[v as usize]);
                let n = (b - a).cross(&(c - a));
                assert!(n.dot(&fp.frame.e3) > 0.0);
                0.5 * n.norm()
            })
            .sum();
        let ellipse = std::f64::consts::PI * fp.semi_axes[0] * fp.semi_axes[1];
        assert!(
            area > 0.6 * ellipse && area < 1.3 * ellipse,
            "{area} vs {ellipse}"
        );
        // every ligament and tendon is anchored at its wall end
        for (region, anchor) in anatomy.anchors() {
            let set = &atlas.node_sets[&format!("{}{}", sets::ANCHOR_PREFIX, region.name())];
            let nearest = set
                .iter()
                .map(|&v| (m.tets.nodes[v as usize] - anchor).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                set.len() >= 3 && nearest < 0.3,
                "{}: {nearest}",
                region.name()
            );
        }
        // the landmarks come back where the anatomy has them
        let back = atlas.landmark_positions(atlas.nodes());
        for (a, b) in back.points().iter().zip(anatomy.landmarks().points()) {
            assert!((a - b).norm() < 1e-9);
        }
        // the FEM system builds with the real materials; its mass is the tissue's
        let model = atlas.fem_model(atlas.nodes(), None, true).unwrap();
        assert_eq!(model.membrane_count(), m.triangles.len());
        let mass_mg = model.lumped_masses().iter().sum::<f64>() * 1e3;
        // ossicles ~ 60-80 mg in all (malleus ~25, incus ~27, stapes ~3 mg) plus soft tissue
        assert!((30.0..120.0).contains(&mass_mg), "{mass_mg} mg");
    }

    #[test]
    fn mirroring_keeps_elements_positive_and_membranes_lateral() {
        let atlas = default_atlas().unwrap();
        let left = atlas.mirrored();
        assert_eq!(left.side, Side::Left);
        assert_eq!(left.mesh.tets.inverted_count(), 0);
        // landmarks mirror with the mesh
        let (r, l) = (
            atlas.landmark_positions(atlas.nodes()),
            left.landmark_positions(left.nodes()),
        );
        for (a, b) in r.points().iter().zip(l.points()) {
            assert!((a.x + b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9);
        }
        // membrane normals still face the same way relative to the mirrored geometry
        let t = atlas.mesh.triangles[0];
        let n = |a: &Atlas| {
            let [p, q, s] = t.map(|v| a.nodes()[v as usize]);
            (q - p).cross(&(s - p))
        };
        let t2 = left.mesh.triangles[0];
        assert_eq!(t2, [t[0], t[2], t[1]]);
        let (nr, nl) = (n(&atlas), {
            let [p, q, s] = t2.map(|v| left.nodes()[v as usize]);
            (q - p).cross(&(s - p))
        });
        // mirrored vector of the right normal equals the left normal
        assert!((nr.x + nl.x).abs() < 1e-12 && (nr.y - nl.y).abs() < 1e-12);
        assert!(left.fem_model(left.nodes(), None, true).is_ok());
    }
}
