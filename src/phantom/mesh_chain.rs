//! A real ossicular chain (`chain_anatomy`) as the phantom's patient: placed in the atlas
//! frame so that the rest of the scene (eardrum, canal, cavity, oval window, ligaments and
//! tendons, which real chain data lacks) comes from the atlas around it.
//!
//! Placement: the atlas landmarks are fitted onto the chain's (similarity, Umeyama), then the
//! rotation and translation are refined by trimmed point-to-surface ICP of the atlas's ossicle
//! surfaces onto the chain, with the scale kept from the landmarks (a CT-derived chain is
//! inflated by partial volume, which an ICP scale would absorb). The chain is then mapped into
//! the atlas frame by the inverse, and the phantom's warp restores its size. The oval window
//! follows the real stapes: the atlas footplate's disc is moved along its normal to the
//! chain's medial-most point within the disc's outline, and centred on that face.

use std::path::PathBuf;

use nalgebra::{Matrix3, Point3, Vector3};

use super::chain_anatomy::{ChainAnatomy, ChainError, LANDMARK_SCALE, PartKind};
use super::chain_articulation::OssicleTurn;
use super::patient::{Aabb, Chain, ChainDistances, PatientAnatomy};
use super::truth::{ChainPlacement, ossicle_surfaces};
use super::variability::Ossicle;
use crate::atlas::Anatomy;
use crate::atlas::sdf::{Disc, Frame};
use crate::ear::Landmarks;
use crate::mesh::TriMesh;
use crate::mesh::spatial::{Bvh, SignedSurface};
use crate::register::icp::{IcpFit, IcpOptions, Trim, trimmed_icp};
use crate::register::rigid::{SimilarityTransform, fit_similarity};

/// The ICP refining the landmark fit: rotation and translation only, pairs farther apart than
/// 1 mm trimmed.
const ICP: IcpOptions = IcpOptions {
    iterations: 40,
    trim: Trim::Distance(1.0),
    with_scale: false,
    check_stride: 97,
    tolerance_mm: 1e-4,
};

/// A real chain in the atlas frame, with the atlas around it.
pub struct MeshChain {
    atlas: PatientAnatomy,
    parts: Vec<(PartKind, SignedSurface, Aabb)>,
    /// The parts in the atlas frame (truth surfaces).
    meshes: Vec<(PartKind, TriMesh)>,
    landmarks: Landmarks,
    footplate: Disc,
    placement: ChainPlacement,
}

impl MeshChain {
    /// Places `chain` (already on `atlas`'s side) in the atlas frame.
    pub fn place(chain: &ChainAnatomy, atlas: Anatomy, mirrored: bool) -> Result<Self, ChainError> {
        let surface_error = |what: String| ChainError::Surface {
            path: PathBuf::from(&chain.name),
            what,
        };
        let fit = fit_similarity(&atlas.landmarks().points(), &chain.landmarks.points(), true)
            .ok_or_else(|| surface_error("the chain's landmarks are collinear".into()))?;
        let scale = fit.transform.scale;
        if !(LANDMARK_SCALE.0..=LANDMARK_SCALE.1).contains(&scale) {
            return Err(ChainError::LandmarkScale {
                name: chain.name.clone(),
                scale,
            });
        }
        let union = TriMesh::concatenated(&chain.parts.iter().map(|(_, m)| m).collect::<Vec<_>>());
        let bvh = Bvh::new(&union, "chain").map_err(|e| surface_error(e.to_string()))?;
        let plain = PatientAnatomy::plain(atlas);
        let samples: Vec<Point3<f64>> = ossicle_surfaces(&plain)
            .iter()
            .flat_map(|m| m.vertices.iter().copied())
            .collect();
        let IcpFit {
            transform: atlas_to_chain,
            mean_kept_mm: icp_mean_mm,
        } = trimmed_icp(&samples, &bvh, fit.transform, &ICP);
        let to_atlas = atlas_to_chain.inverse();
        let meshes: Vec<(PartKind, TriMesh)> = chain
            .parts
            .iter()
            .map(|(k, m)| {
                (
                    *k,
                    TriMesh {
                        vertices: m.vertices.iter().map(|p| to_atlas.apply(p)).collect(),
                        triangles: m.triangles.clone(),
                    },
                )
            })
            .collect();
        let parts = meshes
            .iter()
            .map(|(k, m)| {
                let surface =
                    SignedSurface::new(m, "chain").map_err(|e| surface_error(e.to_string()))?;
                let mut b = Aabb::empty();
                m.vertices.iter().for_each(|p| b.add(&p.coords, 0.0));
                Ok((*k, surface, b))
            })
            .collect::<Result<Vec<_>, ChainError>>()?;
        let atlas_fp = plain.anatomy().footplate().clone();
        let turned_fp = match &chain.articulation {
            Some(a) => turned_disc(&atlas_fp, &a.stapes, mirrored, &to_atlas),
            None => atlas_fp.clone(),
        };
        let footplate = oval_window(&turned_fp, &meshes);
        let placement = ChainPlacement {
            name: chain.name.clone(),
            parts: chain.parts.iter().map(|(k, _)| k.name()).collect(),
            mirrored,
            atlas_to_chain,
            landmark_rms_mm: fit.rms_mm,
            icp_mean_mm,
            footplate_shift_mm: (footplate.center - atlas_fp.center).norm(),
            variation: chain.variation.clone(),
            articulation: chain.articulation.clone(),
            landmarks_proposed: chain.proposed,
            mended: chain.mended.clone(),
        };
        Ok(MeshChain {
            atlas: plain,
            parts,
            meshes,
            landmarks: Landmarks::from_points(chain.landmarks.points().map(|p| to_atlas.apply(&p))),
            footplate,
            placement,
        })
    }

    /// The chain's landmarks in the atlas frame.
    pub fn landmarks(&self) -> Landmarks {
        self.landmarks
    }

    /// The oval window the scene puts around the real stapes.
    pub fn footplate(&self) -> &Disc {
        &self.footplate
    }

    /// The chain's surfaces in the atlas frame.
    pub fn meshes(&self) -> &[(PartKind, TriMesh)] {
        &self.meshes
    }

    pub fn placement(&self) -> &ChainPlacement {
        &self.placement
    }

    /// Whether the chain is one fused surface.
    pub fn is_fused(&self) -> bool {
        self.parts.iter().any(|(k, _, _)| *k == PartKind::Chain)
    }
}

impl Chain for MeshChain {
    /// Bones from the chain's surfaces (a fused chain stands in the malleus's slot), the atlas's
    /// ligaments and tendons; a real chain has no separate joint tissue.
    fn distances(&self, p: &Point3<f64>, far_mm: f64) -> ChainDistances {
        let mut bones = [f64::INFINITY; 3];
        for (kind, surface, b) in &self.parts {
            let k = match kind {
                PartKind::Ossicle(o) => *o as usize,
                PartKind::Chain => 0,
            };
            let d = b.distance(p);
            bones[k] = if d > far_mm {
                d
            } else {
                surface.signed_distance(p)
            };
        }
        ChainDistances {
            bones,
            joints: f64::INFINITY,
            bands: self.atlas.bands_distance(p, far_mm),
        }
    }

    fn anatomy(&self) -> &Anatomy {
        self.atlas.anatomy()
    }
}

/// The atlas's footplate disc `fp` turned as the chain's stapes was (`turn`, in the chain's
/// own frame, mirrored in x = 0 when the chain was), so that the oval window keeps its place
/// around the turned footplate; `to_atlas` maps the chain's frame into the atlas's.
fn turned_disc(
    fp: &Disc,
    turn: &OssicleTurn,
    mirrored: bool,
    to_atlas: &SimilarityTransform,
) -> Disc {
    let mirror = Matrix3::from_diagonal(&Vector3::new(if mirrored { -1.0 } else { 1.0 }, 1.0, 1.0));
    let q = to_atlas.rotation_matrix();
    let rotation = q * mirror * turn.rotation().matrix() * mirror * q.transpose();
    let pivot = to_atlas.apply(&Point3::from(mirror * Vector3::from(turn.pivot)));
    Disc {
        center: pivot + rotation * (fp.center - pivot),
        frame: Frame {
            e1: rotation * fp.frame.e1,
            e2: rotation * fp.frame.e2,
            e3: rotation * fp.frame.e3,
        },
        ..fp.clone()
    }
}

/// The atlas's footplate disc moved onto the chain's stapes: along its normal to the chain's
/// medial-most vertex within its outline (within 1 mm of the disc), and in its plane to the
/// centroid of the chain's vertices on that medial face (within 0.2 mm of it). The atlas's
/// disc when the chain has no vertex there.
fn oval_window(fp: &Disc, meshes: &[(PartKind, TriMesh)]) -> Disc {
    let local: Vec<Vector3<f64>> = meshes
        .iter()
        .filter(|(k, _)| matches!(k, PartKind::Chain | PartKind::Ossicle(Ossicle::Stapes)))
        .flat_map(|(_, m)| m.vertices.iter())
        .map(|p| fp.frame.local(&(p - fp.center)))
        .filter(|q| {
            (q.x / fp.semi_axes[0]).powi(2) + (q.y / fp.semi_axes[1]).powi(2) <= 1.0
                && q.z.abs() <= 1.0
        })
        .collect();
    let Some(deepest) = local.iter().map(|q| q.z).reduce(f64::max) else {
        return fp.clone();
    };
    let face: Vec<&Vector3<f64>> = local.iter().filter(|q| q.z >= deepest - 0.2).collect();
    let centre = face.iter().fold(Vector3::zeros(), |s, q| s + **q) / face.len() as f64;
    let shift = fp.frame.e1 * centre.x
        + fp.frame.e2 * centre.y
        + fp.frame.e3 * (deepest - 0.5 * fp.thickness);
    Disc {
        center: fp.center + shift,
        ..fp.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The turned disc is where the atlas's disc is carried by the chain's turn seen in the
    /// atlas frame: for any chain point x, the turned disc's distance at the atlas image of the
    /// turned x is the disc's at the atlas image of x, mirrored or not.
    #[test]
    fn the_oval_window_turns_with_the_stapes() {
        let fp = Disc {
            center: Point3::new(0.5, -1.0, 2.0),
            frame: Frame::from_axes(Vector3::new(1.0, 0.2, 0.0), Vector3::new(0.0, 1.0, 0.3))
                .unwrap(),
            semi_axes: [1.4, 0.6],
            thickness: 0.3,
        };
        let turn = OssicleTurn {
            axis: Vector3::new(0.3, -0.5, 0.8).normalize().into(),
            angle_deg: 23.0,
            pivot: [1.0, 2.0, -1.5],
        };
        let rotation = nalgebra::Rotation3::from_euler_angles(0.4, -0.7, 1.1);
        let to_atlas =
            SimilarityTransform::new(*rotation.matrix(), Vector3::new(3.0, -2.0, 0.5), 0.9);
        for mirrored in [false, true] {
            let turned = turned_disc(&fp, &turn, mirrored, &to_atlas);
            let mirror = |p: Point3<f64>| {
                if mirrored {
                    Point3::new(-p.x, p.y, p.z)
                } else {
                    p
                }
            };
            let own_frame = |p: Point3<f64>| mirror(p); // the mirror is its own inverse
            for k in 0..40 {
                let t = k as f64;
                // chain points near the disc, in the (possibly mirrored) chain frame
                let atlas_point = fp.center
                    + Vector3::new((0.7 * t).sin(), (1.3 * t).cos(), (0.37 * t).sin()) * 1.5;
                let chain_point = to_atlas.inverse().apply(&atlas_point);
                let turned_chain = mirror(turn.mapping()(&own_frame(chain_point)));
                let turned_atlas = to_atlas.apply(&turned_chain);
                let (before, after) = (fp.distance(&atlas_point), turned.distance(&turned_atlas));
                assert!(
                    (before - after).abs() < 1e-9,
                    "mirrored {mirrored}, point {k}: {before} -> {after}"
                );
            }
        }
    }

    /// Landmarks in other units than the chain's surfaces (µm, m) are refused before the
    /// scene is drawn at their scale; the atlas's own landmarks around the same surfaces are
    /// placed.
    #[test]
    fn landmarks_in_other_units_than_the_surfaces_are_refused() {
        let atlas = Anatomy::default_right().unwrap();
        let own = atlas.landmarks();
        let parts: Vec<(PartKind, TriMesh)> =
            ossicle_surfaces(&PatientAnatomy::plain(atlas.clone()))
                .into_iter()
                .zip(Ossicle::ALL)
                .map(|(m, o)| (PartKind::Ossicle(o), m))
                .collect();
        for factor in [1.0, 1000.0, 0.001] {
            let chain = ChainAnatomy {
                name: "chain".into(),
                parts: parts.clone(),
                landmarks: Landmarks::from_points(own.points().map(|p| p * factor)),
                side: crate::atlas::Side::Right,
                variation: None,
                articulation: None,
                proposed: None,
                notes: Vec::new(),
                mended: Vec::new(),
            };
            let placed = MeshChain::place(&chain, atlas.clone(), false);
            if factor == 1.0 {
                assert!(placed.is_ok());
            } else {
                let err = placed.err().map(|e| e.to_string()).unwrap_or_default();
                assert!(
                    err.contains("times as far apart as the atlas's; expected 0.5 to 2"),
                    "{factor}: {err}"
                );
            }
        }
    }
}
