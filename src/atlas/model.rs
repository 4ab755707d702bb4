//! The assembled atlas: one finite-element system of labelled tetrahedra (ossicles, joints,
//! ligaments, tendons) and membrane triangles (the eardrum) on a shared node set, with the
//! material of every region, the boundary-condition node sets, the load surfaces and the
//! three landmarks tied to the mesh. This is what `run` registers and `export` writes.
//!
//! Materials are kept as the source table gives them (SI: kg/m³, Pa) and converted once, in
//! [`Atlas::fem_model`], to the FEM's mm-g-s system.

use std::collections::BTreeMap;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::materials::KG_PER_M3_TO_G_PER_MM3;
use super::region::Region;
use crate::ear::{LandmarkName, Landmarks, Side};
use crate::fem::{
    FemError, FemModel, MembraneElements, MembraneMaterial, TetElements, TetMaterial,
};
use crate::mesh::io::VolumeMesh;
use crate::mesh::tet::BoundaryOf;
use crate::mesh::{TetMesh, TriMesh};

/// What anatomical part a region belongs to: the four structures a segmentation shows, and
/// the connective tissue (joints, ligaments, tendons) that no CT shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    Malleus,
    Incus,
    Stapes,
    Eardrum,
    Connective,
}

impl Part {
    /// The structures with a surface of their own in exports and scores, in file order.
    pub const STRUCTURES: [Part; 4] = [Part::Malleus, Part::Incus, Part::Stapes, Part::Eardrum];
    /// The ossicles.
    pub const BONES: [Part; 3] = [Part::Malleus, Part::Incus, Part::Stapes];

    pub fn name(self) -> &'static str {
        match self {
            Part::Malleus => "malleus",
            Part::Incus => "incus",
            Part::Stapes => "stapes",
            Part::Eardrum => "eardrum",
            Part::Connective => "connective",
        }
    }
}

/// A region of the atlas: its label (the cell value in the mesh), name, part and material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionInfo {
    pub label: u16,
    pub name: String,
    pub part: Part,
    /// Key into the atlas's materials.
    pub material: String,
    /// Membrane thickness \[mm\]; present exactly for regions made of triangles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_mm: Option<f64>,
    /// Flexural thickness h_b \[mm\] of a membrane region that is a shell: bending rigidity
    /// E·h_b³/(12(1 − ν²)) on top of the in-plane stiffness. Absent: a bending-free membrane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bending_thickness_mm: Option<f64>,
    /// Volume \[mm³\] of a volumetric region in the shape its mesh was built from (the
    /// anatomy, or the surfaces); its material's density is scaled by this over the mesh's
    /// volume so that the region weighs what the shape does (`atlas::mass`). Absent: the
    /// density is the material's own (an imported mesh). A package keeps its atlas's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape_volume_mm3: Option<f64>,
}

/// The flexural thickness `bending` of a region with membrane thickness `thickness`, when it
/// is not acceptable: present but not finite and > 0, or on a region without a thickness
/// (a volume cannot be a shell).
pub(crate) fn bad_bending_thickness(bending: Option<f64>, thickness: Option<f64>) -> Option<f64> {
    bending.filter(|h| !(h.is_finite() && *h > 0.0 && thickness.is_some()))
}

/// An isotropic linear-elastic material as its source gives it (SI units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialInfo {
    pub density_kg_m3: f64,
    pub youngs_modulus_pa: f64,
    pub poisson_ratio: f64,
    /// Where the numbers come from.
    pub source: String,
}

/// Damping of the whole system: Rayleigh C = αM + βK and the cochlear input impedance that
/// loads the footplate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Damping {
    pub rayleigh_alpha_per_s: f64,
    pub rayleigh_beta_s: f64,
    pub cochlear_impedance_pa_s_per_m3: f64,
    pub source: String,
}

/// Elastic supports that are not meshed: the stapedial annular ligament, as isotropic
/// zero-rest-length springs on the footplate rim nodes (SOFA RestShapeSpringsForceField),
/// the total stiffness shared equally among them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Supports {
    pub annular_ligament_stiffness_n_per_m: f64,
    pub source: String,
}

/// A point tied to the mesh: barycentric coordinates in one tetrahedron, so it follows the
/// tetrahedron's deformation (coordinates outside [0, 1] extrapolate for a point just off
/// the surface).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshPoint {
    pub tet: u32,
    pub barycentric: [f64; 4],
}

impl MeshPoint {
    /// Ties `p` to the tetrahedron that contains it best (largest smallest barycentric
    /// coordinate), with its distance outside that tetrahedron (0 inside) \[mm\].
    pub fn locate(mesh: &TetMesh, p: &Point3<f64>) -> Option<(MeshPoint, f64)> {
        // (tet, barycentric, smallest coordinate) of the tet that contains p best
        let mut best: Option<(MeshPoint, f64)> = None;
        for (t, tet) in mesh.tets.iter().enumerate() {
            let Some(b) = barycentric(&tet.map(|v| mesh.nodes[v as usize]), p) else {
                continue;
            };
            let worst = b.iter().copied().fold(f64::INFINITY, f64::min);
            if best.is_none_or(|(_, w)| worst > w) {
                let point = MeshPoint {
                    tet: t as u32,
                    barycentric: b,
                };
                best = Some((point, worst));
            }
        }
        best.map(|(mp, _)| {
            let inside = MeshPoint {
                barycentric: clamp_barycentric(mp.barycentric),
                ..mp
            }
            .position(&mesh.tets, &mesh.nodes);
            (mp, (inside - p).norm())
        })
    }

    /// The point on the mesh with nodes at `nodes`.
    pub fn position(&self, tets: &[[u32; 4]], nodes: &[Point3<f64>]) -> Point3<f64> {
        let tet = tets[self.tet as usize];
        Point3::from(
            (0..4)
                .map(|k| nodes[tet[k] as usize].coords * self.barycentric[k])
                .sum::<nalgebra::Vector3<f64>>(),
        )
    }
}

/// Barycentric coordinates of `p` in the tetrahedron (None if degenerate).
fn barycentric(c: &[Point3<f64>; 4], p: &Point3<f64>) -> Option<[f64; 4]> {
    let m = nalgebra::Matrix3::from_columns(&[c[1] - c[0], c[2] - c[0], c[3] - c[0]]);
    let x = m.try_inverse()? * (p - c[0]);
    Some([1.0 - x.x - x.y - x.z, x.x, x.y, x.z])
}

/// The nearest point of the tetrahedron in barycentric terms (clip negatives, renormalise):
/// exact inside, a close upper bound of the distance outside.
fn clamp_barycentric(b: [f64; 4]) -> [f64; 4] {
    let c = b.map(|v| v.max(0.0));
    let s: f64 = c.iter().sum();
    if s > 0.0 { c.map(|v| v / s) } else { [0.25; 4] }
}

/// The three landmarks tied to the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiedLandmarks {
    pub umbo: MeshPoint,
    pub incudomalleolar: MeshPoint,
    pub incudostapedial: MeshPoint,
}

impl TiedLandmarks {
    pub fn get(&self, name: LandmarkName) -> MeshPoint {
        match name {
            LandmarkName::Umbo => self.umbo,
            LandmarkName::Incudomalleolar => self.incudomalleolar,
            LandmarkName::Incudostapedial => self.incudostapedial,
        }
    }
}

/// Names of the boundary-condition node sets and load surfaces every atlas carries.
pub mod sets {
    /// The eardrum's rim, clamped in the bony sulcus.
    pub const TYMPANIC_ANNULUS: &str = "tympanic_annulus";
    /// The stapes footplate's rim, held by the annular ligament in the oval window.
    pub const ANNULAR_LIGAMENT: &str = "stapedial_annular_ligament";
    /// Prefix of the wall end of each ligament and tendon: `anchor:<region name>`.
    pub const ANCHOR_PREFIX: &str = "anchor:";
    /// Footplate face toward the vestibule: where the cochlear load acts (normals medial).
    pub const FOOTPLATE_MEDIAL: &str = "footplate_medial";
    /// Eardrum face toward the ear canal: where sound pressure acts (normals lateral).
    pub const EARDRUM_LATERAL: &str = "eardrum_lateral";
}

/// The atlas: mesh, regions, materials, boundary sets, loads and landmarks.
#[derive(Debug, Clone, PartialEq)]
pub struct Atlas {
    pub name: String,
    pub side: Side,
    /// Tetrahedra (volumetric regions) and membrane triangles on one node set (mm).
    pub mesh: VolumeMesh,
    pub regions: Vec<RegionInfo>,
    pub materials: BTreeMap<String, MaterialInfo>,
    pub damping: Damping,
    pub supports: Supports,
    /// Node sets for fixed or spring-anchored boundary conditions.
    pub node_sets: BTreeMap<String, Vec<u32>>,
    /// Load surfaces: triangles over the mesh nodes, oriented as their set says.
    pub surfaces: BTreeMap<String, Vec<[u32; 3]>>,
    pub landmarks: TiedLandmarks,
    /// How the atlas was made (free-form key/value, deterministic).
    pub provenance: BTreeMap<String, String>,
}

/// Surface triangles over an atlas's mesh nodes, each with the region it bounds (a membrane
/// triangle's own region, or the tetrahedron's under a boundary triangle).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LabelledTriangles {
    pub triangles: Vec<[u32; 3]>,
    pub regions: Vec<u16>,
}

impl Atlas {
    pub fn nodes(&self) -> &[Point3<f64>] {
        &self.mesh.tets.nodes
    }

    pub fn region(&self, label: u16) -> Option<&RegionInfo> {
        self.regions.iter().find(|r| r.label == label)
    }

    /// Labels of the regions of `part`.
    pub fn labels_of(&self, part: Part) -> Vec<u16> {
        self.regions
            .iter()
            .filter(|r| r.part == part)
            .map(|r| r.label)
            .collect()
    }

    /// The landmark positions with the nodes at `nodes` (the atlas's own for its rest shape).
    pub fn landmark_positions(&self, nodes: &[Point3<f64>]) -> Landmarks {
        let at = |n: LandmarkName| self.landmarks.get(n).position(&self.mesh.tets.tets, nodes);
        Landmarks {
            umbo: at(LandmarkName::Umbo),
            incudomalleolar: at(LandmarkName::Incudomalleolar),
            incudostapedial: at(LandmarkName::Incudostapedial),
        }
    }

    /// The outward surface of a part, as triangles over the mesh nodes: the boundary of its
    /// tetrahedra for an ossicle, its membrane triangles (facing laterally) for the eardrum.
    pub fn part_triangles(&self, part: Part) -> Vec<[u32; 3]> {
        self.part_faces(part).triangles
    }

    /// [`Atlas::part_triangles`] with the region of each triangle.
    pub fn part_faces(&self, part: Part) -> LabelledTriangles {
        let labels = self.labels_of(part);
        let (triangles, regions): (Vec<[u32; 3]>, Vec<u16>) = self
            .mesh
            .triangles
            .iter()
            .zip(&self.mesh.triangle_regions)
            .filter(|(_, r)| labels.contains(r))
            .map(|(t, r)| (*t, *r))
            .unzip();
        if !triangles.is_empty() {
            return LabelledTriangles { triangles, regions };
        }
        self.boundary_faces(&labels)
    }

    /// The boundary of the tetrahedra of `labels`, each triangle with its tetrahedron's region.
    fn boundary_faces(&self, labels: &[u16]) -> LabelledTriangles {
        let tets = &self.mesh.tets;
        let boundary = tets.boundary(BoundaryOf::Regions(labels));
        LabelledTriangles {
            regions: boundary
                .triangle_tets
                .iter()
                .map(|&t| tets.regions[t as usize])
                .collect(),
            triangles: boundary.node_triangles(),
        }
    }

    /// The surface of a part with the nodes at `nodes`, as a compact triangle mesh.
    pub fn part_surface(&self, part: Part, nodes: &[Point3<f64>]) -> TriMesh {
        TriMesh::compacted(&self.part_triangles(part), nodes)
    }

    /// The outer surface of the ossicular chain as one solid, with the nodes at `nodes`: the
    /// boundary of the ossicles' tetrahedra together with their joints' (the regions named
    /// as [`Region::JOINTS`]). A segmentation that does not separate the ossicles (a CT's
    /// fused chain) is this surface; the ossicles' own surfaces would add the facets where
    /// each meets its joint, which lie inside such a solid. Empty when the atlas has no
    /// ossicle.
    pub fn chain_surface(&self, nodes: &[Point3<f64>]) -> TriMesh {
        TriMesh::compacted(&self.chain_faces().triangles, nodes)
    }

    /// The triangles of [`Atlas::chain_surface`] over the mesh nodes, each with its region.
    pub fn chain_faces(&self) -> LabelledTriangles {
        let joints: Vec<&str> = Region::JOINTS.iter().map(|r| r.name()).collect();
        let labels: Vec<u16> = self
            .regions
            .iter()
            .filter(|r| Part::BONES.contains(&r.part) || joints.contains(&r.name.as_str()))
            .map(|r| r.label)
            .collect();
        if labels.is_empty() {
            return LabelledTriangles::default();
        }
        self.boundary_faces(&labels)
    }

    /// The flexural rigidity D = E h_b³/(12(1 − ν²)) (µN·mm) of each membrane triangle, in
    /// mesh order: its region's material at the region's bending thickness; 0 for a
    /// bending-free triangle or one whose region or material is unknown.
    pub fn membrane_flexural_rigidity(&self) -> Vec<f64> {
        self.mesh
            .triangle_regions
            .iter()
            .map(|&label| {
                self.region(label)
                    .and_then(|r| {
                        let m = self.materials.get(&r.material)?;
                        membrane_material(r, m, m.youngs_modulus_pa)
                    })
                    .map_or(0.0, |m| m.flexural_rigidity())
            })
            .collect()
    }

    /// The FEM model with its rest shape at `nodes`. With `registration = (E, r)`, every
    /// modulus is scaled by the same factor so that the stiffest region (bone) gets E, and no
    /// region is softer than r·E: the atlas's stiffness ordering stays, its absolute level
    /// becomes a registration weight, and nearly free tissue (a ligament is 1e-6 of bone)
    /// cannot be crushed flat by its neighbours' motion.
    /// Without `membranes`, the eardrum's triangles are left out (its nodes then carry no
    /// element).
    pub fn fem_model(
        &self,
        nodes: &[Point3<f64>],
        registration: Option<(f64, f64)>,
        membranes: bool,
    ) -> Result<FemModel, FemError> {
        let mut tet_materials = Vec::new();
        let mut membrane_materials = Vec::new();
        // region label -> index into its material list
        let mut tet_index = BTreeMap::new();
        let mut membrane_index = BTreeMap::new();
        let stiffest = self
            .materials
            .values()
            .map(|m| m.youngs_modulus_pa)
            .fold(0.0, f64::max);
        let modulus = |e: f64| match registration {
            Some((bone, ratio)) => (e * bone / stiffest).max(ratio * bone),
            None => e,
        };
        for r in &self.regions {
            let Some(m) = self.materials.get(&r.material) else {
                continue;
            };
            let (e, nu, rho) = (
                modulus(m.youngs_modulus_pa),
                m.poisson_ratio,
                m.density_kg_m3 * KG_PER_M3_TO_G_PER_MM3,
            );
            match membrane_material(r, m, e) {
                Some(material) => {
                    membrane_index.insert(r.label, membrane_materials.len() as u32);
                    membrane_materials.push(material);
                }
                None => {
                    tet_index.insert(r.label, tet_materials.len() as u32);
                    tet_materials.push(TetMaterial {
                        youngs_modulus: e,
                        poisson_ratio: nu,
                        density: rho,
                    });
                }
            }
        }
        let lookup = |map: &BTreeMap<u16, u32>, labels: &[u16]| -> Vec<u32> {
            labels
                .iter()
                .map(|l| map.get(l).copied().unwrap_or(u32::MAX))
                .collect()
        };
        let tet_mi = lookup(&tet_index, &self.mesh.tets.regions);
        let tri_mi = lookup(&membrane_index, &self.mesh.triangle_regions);
        FemModel::new(
            nodes,
            TetElements {
                cells: &self.mesh.tets.tets,
                material_index: &tet_mi,
                materials: &tet_materials,
            },
            if membranes {
                MembraneElements {
                    cells: &self.mesh.triangles,
                    material_index: &tri_mi,
                    materials: &membrane_materials,
                }
            } else {
                MembraneElements::none()
            },
        )
    }

    /// The same atlas for the other ear: mirrored in the plane x = 0, with every element,
    /// surface and landmark re-oriented so that volumes stay positive and normals keep
    /// pointing the way their set says.
    pub fn mirrored(&self) -> Atlas {
        let mut a = self.clone();
        for p in &mut a.mesh.tets.nodes {
            p.x = -p.x;
        }
        for t in &mut a.mesh.tets.tets {
            t.swap(2, 3);
        }
        for t in a
            .mesh
            .triangles
            .iter_mut()
            .chain(a.surfaces.values_mut().flatten())
        {
            t.swap(1, 2);
        }
        let tied = &mut a.landmarks;
        for mp in [
            &mut tied.umbo,
            &mut tied.incudomalleolar,
            &mut tied.incudostapedial,
        ] {
            mp.barycentric.swap(2, 3);
        }
        a.side = self.side.other();
        a
    }
}

/// The FEM material of membrane region `r` made of `m` at Young's modulus `youngs_modulus`
/// (Pa); `None` for a volumetric region (no thickness).
fn membrane_material(
    r: &RegionInfo,
    m: &MaterialInfo,
    youngs_modulus: f64,
) -> Option<MembraneMaterial> {
    r.thickness_mm.map(|h| MembraneMaterial {
        youngs_modulus,
        poisson_ratio: m.poisson_ratio,
        thickness: h,
        bending_thickness: r.bending_thickness_mm,
        density: m.density_kg_m3 * KG_PER_M3_TO_G_PER_MM3,
    })
}
