//! The mechanical system of an atlas at given node positions: the FEM model with the atlas's
//! materials, its boundary conditions, loads and the points and axes the checks measure.
//!
//! Boundary conditions (the choice, stated once):
//! - the tympanic annulus and the wall end (`anchor:<ligament>`) of every ligament and tendon
//!   are **fixed** (all three DOFs): they sit in bone, which is rigid at these loads
//!   (SOFA FixedProjectiveConstraint);
//! - the stapedial annular ligament is **elastic**: isotropic zero-rest-length springs on the
//!   footplate rim nodes, the atlas's total stiffness shared equally (SOFA
//!   RestShapeSpringsForceField); fixing it would immobilise the stapes;
//! - the cochlear load is a dashpot Z_c·A² (A the area of the medial footplate face, Z_c the
//!   atlas's cochlear input impedance), spread over the footplate nodes in proportion to their
//!   area and acting along the footplate normal only: the cochlear fluid resists the piston
//!   motion, not the footplate's motion in its own plane. (The SOFA scene's
//!   DiagonalVelocityDampingForceField has one coefficient per axis, so the scene applies it
//!   on all three axes; docs/mechanics.md gives the difference.)
//!
//! Axes, built from the mesh so that they move with it (a rigidly moved atlas measures the
//! same): `medial` = minus the area-weighted mean normal of the lateral eardrum face;
//! `footplate_normal` = the area-weighted mean normal of the medial footplate face (into the
//! vestibule). Units mm-g-s (µN, Pa).

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use super::error::MechanicsError;
use crate::atlas::materials::cochlear_damping_for;
use crate::atlas::model::Part;
use crate::atlas::model::{Atlas, sets};
use crate::fem::{Dashpot, FemModel, FixedDofs, Rayleigh, RigidBodies, Spring};

/// 1 N/m in µN/mm.
const N_PER_M_TO_UN_PER_MM: f64 = 1e3;

/// A point on the mesh: four nodes and their barycentric weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiedPoint {
    pub nodes: [u32; 4],
    pub weights: [f64; 4],
}

impl TiedPoint {
    /// The point with the nodes at `x`.
    pub fn position(&self, x: &[Point3<f64>]) -> Point3<f64> {
        Point3::from(
            self.nodes
                .iter()
                .zip(&self.weights)
                .map(|(&v, &w)| x[v as usize].coords * w)
                .sum::<Vector3<f64>>(),
        )
    }
}

/// The atlas as a mechanical system at one set of node positions.
#[derive(Debug, Clone)]
pub struct MechanicalSystem {
    pub model: FemModel,
    pub fixed: FixedDofs,
    /// Annular ligament springs (zero rest length, anchored at the rest positions).
    pub springs: Vec<Spring>,
    /// Spring stiffness per node (µN/mm), zero off the footplate rim.
    pub node_stiffness: Vec<f64>,
    /// The cochlear dashpots: one per footplate node, along `footplate_normal`.
    pub dashpots: Vec<Dashpot>,
    pub rayleigh: Rayleigh,
    /// The eardrum's lateral face (normals toward the ear canal).
    pub eardrum: Vec<[u32; 3]>,
    /// Nodes of the medial footplate face with their area weights (summing to 1).
    pub footplate: Vec<(u32, f64)>,
    /// Unit normal of the footplate, into the vestibule.
    pub footplate_normal: Vector3<f64>,
    /// Unit medial axis (ear canal → middle ear).
    pub medial: Vector3<f64>,
    pub umbo: TiedPoint,
    /// Area of the lateral eardrum face (mm²) and of the medial footplate face (mm²).
    pub eardrum_area_mm2: f64,
    pub footplate_area_mm2: f64,
    /// The ossicles as rigid bodies, for the reduced model of the package check
    /// (`Ossicles::Rigid`): one body per bone of the nodes of its tetrahedra; a bone with a
    /// fixed node, and a node already on another bone, stay elastic.
    pub ossicles: RigidBodies,
}

fn set<'a, T>(
    map: &'a std::collections::BTreeMap<String, Vec<T>>,
    kind: &'static str,
    name: &str,
    purpose: &'static str,
) -> Result<&'a [T], MechanicsError> {
    match map.get(name) {
        Some(v) if !v.is_empty() => Ok(v),
        _ => Err(MechanicsError::MissingSet {
            kind,
            name: name.to_string(),
            purpose,
        }),
    }
}

/// Area-weighted normal sum (not normalised) and total area of `triangles` at `x`.
fn weighted_normal(triangles: &[[u32; 3]], x: &[Point3<f64>]) -> (Vector3<f64>, f64) {
    triangles.iter().fold((Vector3::zeros(), 0.0), |(n, a), t| {
        let [p, q, r] = t.map(|v| x[v as usize]);
        let c = (q - p).cross(&(r - p));
        (n + c * 0.5, a + 0.5 * c.norm())
    })
}

/// Triangles of a surface, as node indices.
type Triangles<'a> = &'a [[u32; 3]];

/// The eardrum's lateral face and the footplate's medial face of `atlas`, each triangle
/// checked against the `n` nodes.
fn load_surfaces(
    atlas: &Atlas,
    n: usize,
) -> Result<(Triangles<'_>, Triangles<'_>), MechanicsError> {
    let eardrum = set(
        &atlas.surfaces,
        "surface",
        sets::EARDRUM_LATERAL,
        "sound and static pressure",
    )?;
    let footplate = set(
        &atlas.surfaces,
        "surface",
        sets::FOOTPLATE_MEDIAL,
        "cochlear load and stapes velocity",
    )?;
    if let Some(t) = eardrum
        .iter()
        .chain(footplate)
        .find(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(MechanicsError::BadAtlas {
            what: format!("a load surface triangle {t:?} refers to a node >= {n}"),
        });
    }
    Ok((eardrum, footplate))
}

/// The area (mm²) of `atlas`'s medial footplate face with its nodes at `nodes`: what the
/// stapes's piston velocity times gives its volume velocity.
pub fn footplate_area_mm2(atlas: &Atlas, nodes: &[Point3<f64>]) -> Result<f64, MechanicsError> {
    let (_, footplate) = load_surfaces(atlas, nodes.len())?;
    Ok(weighted_normal(footplate, nodes).1)
}

impl MechanicalSystem {
    /// The mechanical system of `atlas` with its rest shape at `nodes` (the atlas's own
    /// positions, or a package's registered ones).
    pub fn new(atlas: &Atlas, nodes: &[Point3<f64>]) -> Result<Self, MechanicsError> {
        let n = nodes.len();
        if n != atlas.nodes().len() {
            return Err(MechanicsError::BadAtlas {
                what: format!(
                    "{} node positions given for an atlas of {} nodes",
                    n,
                    atlas.nodes().len()
                ),
            });
        }
        let model = atlas
            .fem_model(nodes, None, true)
            .map_err(MechanicsError::solve("building the FEM model"))?;
        let mut fixed_nodes: Vec<u32> = set(
            &atlas.node_sets,
            "node set",
            sets::TYMPANIC_ANNULUS,
            "fixed eardrum rim",
        )?
        .to_vec();
        for (name, nodes) in &atlas.node_sets {
            if name.starts_with(sets::ANCHOR_PREFIX) {
                fixed_nodes.extend_from_slice(nodes);
            }
        }
        let fixed = FixedDofs::from_nodes(n, &fixed_nodes)
            .map_err(MechanicsError::solve("fixed boundary nodes"))?;
        let rim = set(
            &atlas.node_sets,
            "node set",
            sets::ANNULAR_LIGAMENT,
            "annular ligament springs",
        )?;
        let k_total = atlas.supports.annular_ligament_stiffness_n_per_m * N_PER_M_TO_UN_PER_MM;
        if !(k_total.is_finite() && k_total >= 0.0) {
            return Err(MechanicsError::BadAtlas {
                what: format!(
                    "annular ligament stiffness {} N/m: expected finite and >= 0",
                    atlas.supports.annular_ligament_stiffness_n_per_m
                ),
            });
        }
        let mut node_stiffness = vec![0.0; n];
        let springs: Vec<Spring> = rim
            .iter()
            .map(|&v| {
                let k = k_total / rim.len() as f64;
                if let Some(s) = node_stiffness.get_mut(v as usize) {
                    *s += k;
                }
                Spring {
                    node: v,
                    target: nodes.get(v as usize).copied().unwrap_or_default(),
                    stiffness: k,
                }
            })
            .collect();
        let (eardrum, footplate_tris) = load_surfaces(atlas, n)?;
        let eardrum = eardrum.to_vec();
        let (drum_normal, eardrum_area) = weighted_normal(&eardrum, nodes);
        let (fp_normal, fp_area) = weighted_normal(footplate_tris, nodes);
        let (medial, footplate_normal) = match (
            (-drum_normal).try_normalize(1e-12),
            fp_normal.try_normalize(1e-12),
        ) {
            (Some(m), Some(f)) => (m, f),
            _ => {
                return Err(MechanicsError::BadAtlas {
                    what: "the eardrum or footplate surface has no mean normal".into(),
                });
            }
        };
        let mut weight = vec![0.0; n];
        for t in footplate_tris {
            let [p, q, r] = t.map(|v| nodes[v as usize]);
            let a = 0.5 * (q - p).cross(&(r - p)).norm();
            t.iter()
                .for_each(|&v| weight[v as usize] += a / (3.0 * fp_area));
        }
        let footplate: Vec<(u32, f64)> = weight
            .iter()
            .enumerate()
            .filter(|(_, w)| **w > 0.0)
            .map(|(v, w)| (v as u32, *w))
            .collect();
        let c_total = cochlear_damping_for(atlas.damping.cochlear_impedance_pa_s_per_m3, fp_area);
        let dashpots = footplate
            .iter()
            .map(|&(node, w)| Dashpot {
                node,
                coefficient: w * c_total,
                direction: footplate_normal,
            })
            .collect();
        let ossicles = ossicle_bodies(atlas, nodes, &fixed)?;
        let tied = atlas.landmarks.umbo;
        let cell = atlas.mesh.tets.tets.get(tied.tet as usize).ok_or_else(|| {
            MechanicsError::BadAtlas {
                what: format!("the umbo is tied to tetrahedron {}, out of range", tied.tet),
            }
        })?;
        Ok(MechanicalSystem {
            model,
            fixed,
            springs,
            node_stiffness,
            dashpots,
            rayleigh: Rayleigh {
                mass: atlas.damping.rayleigh_alpha_per_s,
                stiffness: atlas.damping.rayleigh_beta_s,
            },
            eardrum,
            footplate,
            footplate_normal,
            medial,
            umbo: TiedPoint {
                nodes: *cell,
                weights: tied.barycentric,
            },
            eardrum_area_mm2: eardrum_area,
            footplate_area_mm2: fp_area,
            ossicles,
        })
    }
}

/// How the ossicles move in the checks' solves.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum Ossicles {
    /// Elastic bone, every node its own three unknowns: the full model (`validate`).
    #[default]
    Elastic,
    /// Each ossicle one rigid body of six unknowns (`MechanicalSystem::ossicles`,
    /// `fem::RigidBodies`; in the static curve its rotation taken exactly); joints,
    /// ligaments, tendons and eardrum stay elastic. A model of about half the unknowns, for
    /// the package check (docs/mechanics.md).
    Rigid,
}

/// The rigid bodies of `atlas`'s ossicles at `nodes` (`MechanicalSystem::ossicles`).
fn ossicle_bodies(
    atlas: &Atlas,
    nodes: &[Point3<f64>],
    fixed: &FixedDofs,
) -> Result<RigidBodies, MechanicsError> {
    let mut body_of: Vec<Option<u32>> = vec![None; nodes.len()];
    let mut count = 0;
    for part in Part::BONES {
        let labels = atlas.labels_of(part);
        let mut members = Vec::new();
        for (cell, region) in atlas.mesh.tets.tets.iter().zip(&atlas.mesh.tets.regions) {
            if labels.contains(region) {
                members.extend(cell.iter().map(|&v| v as usize));
            }
        }
        members.sort_unstable();
        members.dedup();
        let free = members
            .iter()
            .all(|&v| body_of.get(v) == Some(&None) && !fixed.is_fixed(3 * v));
        if free && !members.is_empty() {
            members.iter().for_each(|&v| body_of[v] = Some(count));
            count += 1;
        }
    }
    RigidBodies::new(nodes, &body_of).map_err(MechanicsError::solve("the ossicles' rigid bodies"))
}

impl MechanicalSystem {
    /// The cochlear dashpot of each node (g/s, zero off the footplate), for a component that
    /// damps every axis alike (the SOFA scene's DiagonalVelocityDampingForceField).
    pub fn node_dashpot(&self) -> Vec<f64> {
        let mut c = vec![0.0; self.model.node_count()];
        for d in &self.dashpots {
            c[d.node as usize] += d.coefficient;
        }
        c
    }

    /// The same system with the whole eardrum bending at one flexural thickness: discrete-
    /// shell hinges on its membrane with the flexural rigidity of each region's material at
    /// `thickness_mm` (`FemModel::with_membrane_bending`), in place of the atlas's own
    /// `bending_thickness_mm`; the what-if of docs/mechanics.md.
    pub fn with_eardrum_bending(mut self, thickness_mm: f64) -> Result<Self, MechanicsError> {
        self.model = self
            .model
            .with_membrane_bending(thickness_mm)
            .map_err(MechanicsError::solve("eardrum bending"))?;
        Ok(self)
    }
}
