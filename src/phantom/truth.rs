//! A phantom's ground truth: the true surfaces (each ossicle's detailed region by marching
//! tetrahedra on a fine lattice of the atlas frame, and the eardrum cone finely triangulated,
//! all mapped forward into patient space) and the record written as `truth.json`.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::chain_articulation::ChainArticulation;
use super::chain_landmarks::LandmarksProposed;
use super::chain_variation::ChainVariation;
use super::imaging::ImagingParams;
use super::patient::PatientAnatomy;
use super::scene::{CavityParams, TissueLevels};
use super::variability::{OssicleMotion, ShapeDetail};
use super::warp::{Deformation, PatientWarp};
use crate::atlas::{Eardrum, Side};
use crate::ear::Landmarks;
use crate::mesh::isosurface::{SampledField, isosurface};
use crate::mesh::{LabelledDomain, TriMesh};
use crate::register::rigid::SimilarityTransform;

/// Lattice step of the ossicle surfaces in the atlas frame \[mm\].
pub const SURFACE_STEP_MM: f64 = 0.1;
/// Rings (umbo to annulus) and sectors of the eardrum triangulation.
const DRUM_RINGS: usize = 24;
const DRUM_SECTORS: usize = 120;

/// The closed, outward surfaces of the three ossicles (atlas frame), in `Ossicle::ALL` order.
pub fn ossicle_surfaces(patient: &PatientAnatomy) -> [TriMesh; 3] {
    let (lo, hi) = patient.anatomy().bounds();
    // a coarse pass finds the box of the bones (a lattice cell within reach of a surface)
    let coarse = 0.3;
    let n = |c: usize| ((hi[c] - lo[c]) / coarse).ceil() as usize + 1;
    let (mut blo, mut bhi) = (hi, lo);
    for k in 0..n(2) {
        for j in 0..n(1) {
            for i in 0..n(0) {
                let p = lo + Vector3::new(i as f64, j as f64, k as f64) * coarse;
                if patient.regions(&p).iter().any(|d| *d < 0.6) {
                    blo = blo.inf(&p);
                    bhi = bhi.sup(&p);
                }
            }
        }
    }
    let h = SURFACE_STEP_MM;
    let origin = blo - Vector3::from_element(coarse + 2.0 * h);
    let dims = [0, 1, 2].map(|c| ((bhi[c] - blo[c] + 2.0 * coarse) / h).ceil() as usize + 5);
    let plane = dims[0] * dims[1];
    let mut values = vec![[0f32; 3]; plane * dims[2]];
    values
        .par_chunks_mut(plane)
        .enumerate()
        .for_each(|(k, out)| {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = origin + Vector3::new(i as f64, j as f64, k as f64) * h;
                    // the isosurface's inside is where values exceed the level
                    out[i + dims[0] * j] = patient.regions(&p).map(|d| -d as f32);
                }
            }
        });
    [0, 1, 2].map(|b| {
        let field: Vec<f32> = values.iter().map(|v| v[b]).collect();
        isosurface(
            &SampledField {
                dims,
                values: &field,
                origin: origin.coords,
                axes: Matrix3::from_diagonal_element(h),
            },
            0.0,
        )
    })
}

/// The eardrum cone as a triangulated open surface (atlas frame), normals pointing medially.
pub fn eardrum_surface(drum: &Eardrum) -> TriMesh {
    let mut mesh = TriMesh::default();
    mesh.vertices.push(drum.apex);
    for r in 1..=DRUM_RINGS {
        let s = r as f64 / DRUM_RINGS as f64;
        for t in 0..DRUM_SECTORS {
            let theta = std::f64::consts::TAU * t as f64 / DRUM_SECTORS as f64;
            mesh.vertices.push(drum.point(s, theta));
        }
    }
    let at = |r: usize, t: usize| (1 + (r - 1) * DRUM_SECTORS + t % DRUM_SECTORS) as u32;
    for t in 0..DRUM_SECTORS {
        mesh.triangles.push([0, at(1, t), at(1, t + 1)]);
        for r in 1..DRUM_RINGS {
            let (a, b, c, d) = (at(r, t), at(r, t + 1), at(r + 1, t + 1), at(r + 1, t));
            mesh.triangles.push([a, d, c]);
            mesh.triangles.push([a, c, b]);
        }
    }
    // orient medially: the summed area normal against the membrane's medial normal
    let total: Vector3<f64> = (0..mesh.triangles.len())
        .map(|t| mesh.area_normal2(t))
        .sum();
    if total.dot(&drum.medial_normal) < 0.0 {
        for t in &mut mesh.triangles {
            t.swap(1, 2);
        }
    }
    mesh
}

/// `mesh` with every vertex mapped from the atlas frame into patient space.
pub fn to_patient(mesh: &TriMesh, warp: &PatientWarp) -> TriMesh {
    TriMesh {
        vertices: mesh
            .vertices
            .par_iter()
            .map(|p| warp.to_patient(p))
            .collect(),
        triangles: mesh.triangles.clone(),
    }
}

/// The three landmarks in LPS mm.
#[derive(Debug, Clone, Serialize)]
pub struct LandmarkRecord {
    pub umbo: [f64; 3],
    pub incudomalleolar: [f64; 3],
    pub incudostapedial: [f64; 3],
}

impl From<&Landmarks> for LandmarkRecord {
    fn from(l: &Landmarks) -> Self {
        LandmarkRecord {
            umbo: l.umbo.into(),
            incudomalleolar: l.incudomalleolar.into(),
            incudostapedial: l.incudostapedial.into(),
        }
    }
}

/// The pose: `atlas_to_patient` is the similarity part of the map (row-major 4x4,
/// `x ≈ scale · rotation · a + translation`); the exact map also applies the deformation:
/// `scale · a = w + d(w)`, `x = rotation · w + translation`.
#[derive(Debug, Clone, Serialize)]
pub struct PoseRecord {
    pub atlas_to_patient: [[f64; 4]; 4],
    pub rotation: [[f64; 3]; 3],
    pub translation_mm: [f64; 3],
    pub scale: f64,
}

impl From<&PatientWarp> for PoseRecord {
    fn from(w: &PatientWarp) -> Self {
        let m = w.atlas_to_patient_similarity();
        let r = w.rotation.matrix();
        PoseRecord {
            atlas_to_patient: [0, 1, 2, 3].map(|i| [0, 1, 2, 3].map(|j| m[(i, j)])),
            rotation: [0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)])),
            translation_mm: w.translation.into(),
            scale: w.scale,
        }
    }
}

/// The deformation and what it does over the field of view.
#[derive(Debug, Clone, Serialize)]
pub struct DeformationRecord {
    #[serde(flatten)]
    pub field: Deformation,
    /// `Σ |A_k|`: no displacement exceeds it \[mm\].
    pub displacement_bound_mm: f64,
    /// `Σ |A_k| |κ_k|`: below 1, the map is invertible everywhere.
    pub gradient_bound: f64,
    /// Largest displacement and smallest Jacobian determinant of `w ↦ w + d(w)` over the
    /// field of view, sampled every 0.5 mm.
    pub max_displacement_mm: f64,
    pub min_jacobian_determinant: f64,
}

/// The image grid (LPS mm).
#[derive(Debug, Clone, Serialize)]
pub struct GridRecord {
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    pub origin: [f64; 3],
    /// Row-major; columns are the voxel axes in LPS.
    pub direction: [f64; 9],
}

/// `truth.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Truth {
    pub generator: String,
    pub seed: u64,
    pub side: Side,
    /// The real chain the case was made from, and how the atlas was placed around it (absent
    /// for a case made from the atlas anatomy).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub anatomy: Option<ChainPlacement>,
    /// Exact landmarks on the true anatomy (the landmark files carry them with pick noise).
    pub landmarks: LandmarkRecord,
    pub landmarks_picked: LandmarkRecord,
    pub pick_noise_sd_mm: f64,
    pub pose: PoseRecord,
    pub ossicle_motions: Vec<OssicleMotion>,
    pub deformation: DeformationRecord,
    pub shape_detail: ShapeDetail,
    pub image: GridRecord,
    pub imaging: ImagingParams,
    pub tissue_levels: TissueLevels,
    pub cavity: CavityParams,
    /// Label values of `segmentation/labels.nii.gz`.
    pub labels: Vec<(u16, String)>,
}

/// How the atlas was placed on the chain (truth.json's `anatomy` record).
#[derive(Debug, Clone, Serialize)]
pub struct ChainPlacement {
    /// The chain folder's name.
    pub name: String,
    /// The parts, by name.
    pub parts: Vec<&'static str>,
    /// The chain was mirrored to the requested side.
    pub mirrored: bool,
    /// Atlas frame to the chain's frame (after mirroring).
    pub atlas_to_chain: SimilarityTransform,
    /// RMS of the atlas landmarks against the chain's after the landmark fit \[mm\].
    pub landmark_rms_mm: f64,
    /// Mean distance of the atlas ossicle surfaces to the chain after ICP \[mm\].
    pub icp_mean_mm: f64,
    /// How far the oval window was moved from the atlas's footplate \[mm\].
    pub footplate_shift_mm: f64,
    /// The chain's shape variation (`phantom --vary-shape`), in the chain's own frame before
    /// mirroring; absent when the chain was imaged as it is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variation: Option<ChainVariation>,
    /// The chain's articulation (`phantom --vary-articulation`), in the chain's own frame
    /// before mirroring; absent when the ossicles were imaged as they are.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub articulation: Option<ChainArticulation>,
    /// How the chain's landmarks and side were proposed, when its folder had no landmark file;
    /// absent when they were read from one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub landmarks_proposed: Option<LandmarksProposed>,
    /// What was mended in the chain's surfaces as read (`FILE: change`: faces turned, specks
    /// dropped, holes closed; docs/phantom.md); absent when they were used as they came.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub mended: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::Anatomy;
    use crate::mesh::topology::surface_topology;

    #[test]
    fn atlas_ossicle_surfaces_are_closed_outward_and_of_atlas_volume() {
        let a = Anatomy::default_right().unwrap();
        let p = PatientAnatomy::plain(a);
        let [m, i, s] = ossicle_surfaces(&p);
        for (name, mesh) in [("malleus", &m), ("incus", &i), ("stapes", &s)] {
            let topo = surface_topology(mesh);
            assert!(topo.is_closed_oriented_manifold(), "{name} {topo:?}");
            assert!(mesh.signed_volume() > 0.0, "{name}");
        }
        // the malleus volume of the atlas is about 10.25 mm³ (tests/atlas_anatomy.rs)
        assert!(
            (m.signed_volume() - 10.25).abs() < 0.5,
            "{}",
            m.signed_volume()
        );
    }

    #[test]
    fn eardrum_surface_runs_from_the_umbo_to_the_annulus() {
        let a = Anatomy::default_right().unwrap();
        let d = eardrum_surface(a.eardrum());
        assert_eq!(d.vertices[0], a.landmarks().umbo);
        let topo = surface_topology(&d);
        assert_eq!(topo.components, 1);
        assert_eq!(topo.border_edges, DRUM_SECTORS);
        let total: Vector3<f64> = (0..d.triangles.len()).map(|t| d.area_normal2(t)).sum();
        assert!(total.dot(&a.eardrum().medial_normal) > 0.0);
    }
}
