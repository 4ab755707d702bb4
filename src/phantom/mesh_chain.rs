//! A real ossicular chain as the phantom's patient: closed surfaces (one per ossicle, or one
//! fused chain) with the chain's three landmarks and side, read from a folder, and placed in
//! the atlas frame so that the rest of the scene (eardrum, canal, cavity, oval window,
//! ligaments and tendons, which real chain data lacks) comes from the atlas around it.
//!
//! Placement: the atlas landmarks are fitted onto the chain's (similarity, Umeyama), then the
//! rotation and translation are refined by trimmed point-to-surface ICP of the atlas's ossicle
//! surfaces onto the chain, with the scale kept from the landmarks (a CT-derived chain is
//! inflated by partial volume, which an ICP scale would absorb). The chain is then mapped into
//! the atlas frame by the inverse, and the phantom's warp restores its size. The oval window
//! follows the real stapes: the atlas footplate's disc is moved along its normal to the
//! chain's medial-most point within the disc's outline, and centred on that face.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Point3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::chain_articulation::{ChainArticulation, OssicleTurn};
use super::chain_landmarks::{self, LandmarksProposed, ProposedLandmarks};
use super::chain_variation::ChainVariation;
use super::patient::{Aabb, Chain, ChainDistances, PatientAnatomy};
use super::truth::{ChainPlacement, ossicle_surfaces};
use super::variability::Ossicle;
use crate::atlas::sdf::{Disc, Frame};
use crate::atlas::{Anatomy, Side};
use crate::ear::Landmarks;
use crate::ear::{file_stem, read_landmarks, structure_names};
use crate::mesh::TriMesh;
use crate::mesh::io::{read_surface, surface_extension, surface_files};
use crate::mesh::spatial::{Bvh, SignedSurface};
use crate::register::rigid::{SimilarityTransform, fit_similarity};

/// Surface file names per part, tried in this order (PLY, STL, OBJ).
const EXTENSIONS: [&str; 3] = ["ply", "stl", "obj"];
/// Names a fused chain surface may have.
const FUSED_STEMS: [&str; 2] = ["chain", "ossicles"];
/// The structure names a chain folder's files may have ([`structure_names`]).
const KNOWN_NAMES: [&str; 6] = ["malleus", "incus", "stapes", "chain", "ossicles", "eardrum"];
/// Landmark files, tried in this order.
const LANDMARK_FILES: [&str; 4] = [
    "landmarks.json",
    "landmarks.mrk.json",
    "landmarks.fcsv",
    "landmarks.csv",
];
/// ICP: iterations, and pairs farther apart than this are trimmed [mm].
const ICP_ITERATIONS: usize = 40;
const ICP_TRIM_MM: f64 = 1.0;

/// What one surface of the chain is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PartKind {
    Ossicle(Ossicle),
    /// Malleus, incus and stapes in one closed surface.
    Chain,
}

impl PartKind {
    pub fn name(self) -> &'static str {
        match self {
            PartKind::Ossicle(o) => o.name(),
            PartKind::Chain => "chain",
        }
    }
}

/// A real chain as read from its folder (the chain's own frame, mm).
#[derive(Debug, Clone)]
pub struct ChainAnatomy {
    /// The folder's name (never its path: it goes into truth.json).
    pub name: String,
    pub parts: Vec<(PartKind, TriMesh)>,
    pub landmarks: Landmarks,
    pub side: Side,
    /// The shape variation applied to the chain as read, if any.
    pub variation: Option<ChainVariation>,
    /// The articulation applied to the chain as read, if any.
    pub articulation: Option<ChainArticulation>,
    /// How the landmarks and side were proposed, when the folder had no landmark file.
    pub proposed: Option<LandmarksProposed>,
    /// How the folder was read, for the user: a surface taken by a name other than the
    /// part's own, a surface turned outward, an eardrum surface not used.
    pub notes: Vec<String>,
}

/// Landmarks and side for a chain without a landmark file, from the phantom's atlas anatomy.
fn propose_landmarks(parts: &[(PartKind, TriMesh)]) -> Option<ProposedLandmarks> {
    let atlas = Anatomy::default_right().ok()?;
    let surfaces = ossicle_surfaces(&PatientAnatomy::plain(atlas.clone()));
    let chain: Vec<&TriMesh> = parts.iter().map(|(_, m)| m).collect();
    chain_landmarks::propose(&chain, &surfaces, &atlas)
}

fn point_text(p: &Point3<f64>) -> String {
    format!("({:.3}, {:.3}, {:.3})", p.x, p.y, p.z)
}

/// Errors reading a chain folder.
#[derive(Debug, thiserror::Error)]
pub enum ChainError {
    #[error(
        "--anatomy {dir}: no chain surfaces{found}; expected malleus, incus and stapes (or one fused chain or ossicles) as .ply, .stl or .obj files whose names say which (malleus.ply, 01_Malleus.stl, Segmentation_Stapes.obj), in the folder or in its surfaces/"
    )]
    NoSurfaces {
        dir: PathBuf,
        /// The surface files found that name no ossicle (", found a.stl, b.stl"), if any.
        found: String,
    },
    #[error(
        "--anatomy {dir}: found {found} but not {missing}{others}; expected all three ossicles or one fused chain, each in one file whose name says which"
    )]
    MissingOssicle {
        dir: PathBuf,
        found: String,
        missing: String,
        /// The surface files whose names name no structure (" (other surface files: ...)").
        others: String,
    },
    #[error(
        "--anatomy {dir}: no landmark file (expected one of {}), and none could be proposed: a chain surface is empty",
        LANDMARK_FILES.join(", ")
    )]
    NoLandmarks { dir: PathBuf },
    #[error(
        "{path}: the file does not say the ear's side; expected \"side\": \"left\" or \"right\""
    )]
    NoSide { path: PathBuf },
    #[error(
        "--anatomy {name}: the chain is one fused surface, so its ossicles cannot be turned apart; --vary-articulation expects malleus, incus and stapes surfaces"
    )]
    FusedArticulation { name: String },
    #[error("{0}")]
    Read(String),
    #[error("{path}: {what}")]
    Surface { path: PathBuf, what: String },
}

/// The chain folder's surface files by the structure their names name
/// ([`structure_names`]): the folder's own before its `surfaces/`, and in one folder PLY
/// before STL before OBJ for the same name.
fn named_files(dirs: &[PathBuf]) -> Result<Vec<(String, PathBuf)>, ChainError> {
    let rank = |p: &PathBuf| {
        let ext = surface_extension(p).unwrap_or_default();
        EXTENSIONS.iter().position(|e| *e == ext)
    };
    let mut named: Vec<(String, PathBuf)> = Vec::new();
    for dir in dirs {
        let mut files = surface_files(dir).map_err(|e| ChainError::Read(e.to_string()))?;
        files.retain(|p| rank(p).is_some());
        files.sort_by_key(rank);
        for (name, path) in structure_names(&files).into_iter().zip(files) {
            if !named.iter().any(|(n, _)| *n == name) {
                named.push((name, path));
            }
        }
    }
    Ok(named)
}

/// Reads one closed surface; one whose triangles all face inward (a negative enclosed
/// volume) is turned outward, with a note.
fn read_part(path: &Path, notes: &mut Vec<String>) -> Result<TriMesh, ChainError> {
    let mut mesh = read_surface(path).map_err(|e| ChainError::Read(e.to_string()))?;
    let volume = mesh.signed_volume();
    if volume < 0.0 {
        mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        notes.push(format!(
            "{}: its triangles face inward (enclosed volume {volume:.3} mm³); read turned outward",
            path.display()
        ));
    }
    if mesh.triangles.is_empty() || mesh.signed_volume() <= 0.0 {
        return Err(ChainError::Surface {
            path: path.to_path_buf(),
            what: format!(
                "expected a closed surface (enclosed volume {:.3} mm³)",
                mesh.signed_volume()
            ),
        });
    }
    Ok(mesh)
}

impl ChainAnatomy {
    /// Reads `dir`: `malleus`, `incus` and `stapes` surfaces, or one fused `chain` (also
    /// `ossicles`), each a file whose name names it ([`structure_names`]: `01_Malleus.stl`),
    /// in the folder or its `surfaces/` (as `otoatlas atlas export` writes them), and a
    /// landmark file that says the side.
    pub fn load(dir: &Path) -> Result<ChainAnatomy, ChainError> {
        let dirs = [dir.to_path_buf(), dir.join("surfaces")];
        let files = named_files(&dirs)?;
        let file = |name: &str| {
            files
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, p)| p.clone())
        };
        let ossicles: Vec<(Ossicle, Option<PathBuf>)> =
            Ossicle::ALL.iter().map(|o| (*o, file(o.name()))).collect();
        let found: Vec<&str> = ossicles
            .iter()
            .filter(|(_, p)| p.is_some())
            .map(|(o, _)| o.name())
            .collect();
        let fused = FUSED_STEMS.iter().find_map(|s| file(s));
        let mut notes = Vec::new();
        let chosen: Vec<(PartKind, PathBuf)> = if found.len() == 3 {
            ossicles
                .into_iter()
                .filter_map(|(o, p)| p.map(|p| (PartKind::Ossicle(o), p)))
                .collect()
        } else if let Some(p) = fused {
            vec![(PartKind::Chain, p)]
        } else if found.is_empty() {
            let names: Vec<String> = files
                .iter()
                .filter_map(|(_, p)| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect();
            return Err(ChainError::NoSurfaces {
                dir: dir.to_path_buf(),
                found: if names.is_empty() {
                    String::new()
                } else {
                    format!(" (found {}, none named for an ossicle)", names.join(", "))
                },
            });
        } else {
            let missing: Vec<&str> = Ossicle::ALL
                .iter()
                .map(|o| o.name())
                .filter(|n| !found.contains(n))
                .collect();
            let others: Vec<String> = files
                .iter()
                .filter(|(n, _)| !KNOWN_NAMES.contains(&n.as_str()))
                .filter_map(|(_, p)| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect();
            return Err(ChainError::MissingOssicle {
                dir: dir.to_path_buf(),
                found: found.join(", "),
                missing: missing.join(", "),
                others: if others.is_empty() {
                    String::new()
                } else {
                    format!(" (other surface files: {})", others.join(", "))
                },
            });
        };
        if let Some(drum) = file("eardrum") {
            notes.push(format!(
                "{}: not used; the phantom's eardrum, canal and cavity are the atlas's, placed around the chain",
                drum.display()
            ));
        }
        let mut parts = Vec::new();
        for (kind, path) in chosen {
            let stem = file_stem(&path);
            if !stem.eq_ignore_ascii_case(kind.name())
                && !FUSED_STEMS.iter().any(|f| stem.eq_ignore_ascii_case(f))
            {
                notes.push(format!("{}: read as the {}", path.display(), kind.name()));
            }
            parts.push((kind, read_part(&path, &mut notes)?));
        }
        let landmark_file = dirs
            .iter()
            .flat_map(|d| LANDMARK_FILES.iter().map(move |f| d.join(f)))
            .find(|p| p.is_file());
        let (landmarks, side, proposed) = match landmark_file {
            Some(path) => {
                let file = read_landmarks(&path).map_err(|e| ChainError::Read(e.to_string()))?;
                let side = file.side.ok_or(ChainError::NoSide { path })?;
                (file.landmarks, side, None)
            }
            None => {
                let p = propose_landmarks(&parts).ok_or_else(|| ChainError::NoLandmarks {
                    dir: dir.to_path_buf(),
                })?;
                notes.push(format!(
                    "no landmark file ({}): landmarks and side proposed by fitting the atlas's ossicles to the chain: a {} ear (surfaces {:.3} mm apart; as the other side {:.3} mm), umbo {}, IMJ {}, ISJ {} mm (the atlas's, carried; then the umbo moved {:.2} mm onto the manubrium's tip and the ISJ {:.2} mm to its interface's bone); check them, and write them to landmarks.json to keep them",
                    LANDMARK_FILES.join(", "),
                    p.side.as_str(),
                    p.mean_distance_mm,
                    p.other_side_mm,
                    point_text(&p.landmarks.umbo),
                    point_text(&p.landmarks.incudomalleolar),
                    point_text(&p.landmarks.incudostapedial),
                    p.umbo_moved_mm,
                    p.isj_moved_mm,
                ));
                (p.landmarks, p.side, Some(LandmarksProposed::from(&p)))
            }
        };
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "anatomy".into());
        Ok(ChainAnatomy {
            name,
            parts,
            landmarks,
            side,
            variation: None,
            articulation: None,
            proposed,
            notes,
        })
    }

    /// The centroid of the chain's surface vertices.
    pub fn centroid(&self) -> Point3<f64> {
        let (sum, n) = self
            .parts
            .iter()
            .flat_map(|(_, m)| &m.vertices)
            .fold((Vector3::zeros(), 0usize), |(s, n), p| {
                (s + p.coords, n + 1)
            });
        Point3::from(sum / n.max(1) as f64)
    }

    /// The chain with `variation` applied to its surfaces and landmarks (a map of positive
    /// determinant: the triangles stay outward).
    pub fn varied(&self, variation: ChainVariation) -> ChainAnatomy {
        let mut varied = self.mapped(variation.mapping(), false);
        varied.variation = Some(variation);
        varied
    }

    /// Whether the chain is one fused surface, its ossicles not told apart.
    pub fn is_fused(&self) -> bool {
        self.parts.iter().any(|(k, _)| *k == PartKind::Chain)
    }

    /// Refuses a fused chain, whose ossicles cannot be turned apart
    /// ([`ChainAnatomy::articulated`]).
    pub fn check_articulable(&self) -> Result<(), ChainError> {
        if self.is_fused() {
            return Err(ChainError::FusedArticulation {
                name: self.name.clone(),
            });
        }
        Ok(())
    }

    /// The chain with the malleus and the stapes turned by `articulation` about their joints'
    /// landmarks (the umbo landmark with the malleus); a fused chain cannot be.
    pub fn articulated(&self, articulation: ChainArticulation) -> Result<ChainAnatomy, ChainError> {
        self.check_articulable()?;
        let mut turned = self.clone();
        for (kind, mesh) in &mut turned.parts {
            let turn = match kind {
                PartKind::Ossicle(Ossicle::Malleus) => &articulation.malleus,
                PartKind::Ossicle(Ossicle::Stapes) => &articulation.stapes,
                PartKind::Ossicle(Ossicle::Incus) | PartKind::Chain => continue,
            };
            let map = turn.mapping();
            mesh.vertices.iter_mut().for_each(|p| *p = map(p));
        }
        turned.landmarks.umbo = articulation.malleus.mapping()(&self.landmarks.umbo);
        turned.articulation = Some(articulation);
        Ok(turned)
    }

    /// The same chain as the other ear: mirrored in x = 0 (triangles turned to stay outward).
    pub fn mirrored(&self) -> ChainAnatomy {
        let mut mirrored = self.mapped(|p| Point3::new(-p.x, p.y, p.z), true);
        mirrored.side = self.side.other();
        mirrored
    }

    /// The chain with `map` applied to its vertices and landmarks, its triangles turned when
    /// the map reverses orientation (`reverses`).
    fn mapped(&self, map: impl Fn(&Point3<f64>) -> Point3<f64>, reverses: bool) -> ChainAnatomy {
        let triangle = |t: &[u32; 3]| if reverses { [t[0], t[2], t[1]] } else { *t };
        ChainAnatomy {
            name: self.name.clone(),
            parts: self
                .parts
                .iter()
                .map(|(k, m)| {
                    (
                        *k,
                        TriMesh {
                            vertices: m.vertices.iter().map(&map).collect(),
                            triangles: m.triangles.iter().map(triangle).collect(),
                        },
                    )
                })
                .collect(),
            landmarks: Landmarks::from_points(self.landmarks.points().map(|p| map(&p))),
            side: self.side,
            variation: self.variation.clone(),
            articulation: self.articulation.clone(),
            proposed: self.proposed,
            notes: self.notes.clone(),
        }
    }
}

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
        let union = TriMesh::concatenated(&chain.parts.iter().map(|(_, m)| m).collect::<Vec<_>>());
        let bvh = Bvh::new(&union, "chain").map_err(|e| surface_error(e.to_string()))?;
        let plain = PatientAnatomy::plain(atlas);
        let samples: Vec<Point3<f64>> = ossicle_surfaces(&plain)
            .iter()
            .flat_map(|m| m.vertices.iter().copied())
            .collect();
        let (atlas_to_chain, icp_mean_mm) = icp(&samples, &bvh, fit.transform);
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

/// Trimmed point-to-surface ICP of `samples` (atlas frame) onto the chain, refining rotation
/// and translation from `start` with its scale fixed; returns the transform and the mean
/// distance of the kept pairs.
fn icp(
    samples: &[Point3<f64>],
    chain: &Bvh,
    start: SimilarityTransform,
) -> (SimilarityTransform, f64) {
    let mut t = start;
    let mut mean = f64::INFINITY;
    for _ in 0..ICP_ITERATIONS {
        let pairs: Vec<(Point3<f64>, Point3<f64>, f64)> = samples
            .par_iter()
            .map(|a| {
                let x = t.apply(a);
                let hit = chain.closest(&x);
                (*a, hit.point, (hit.point - x).norm())
            })
            .collect();
        let kept: Vec<&(Point3<f64>, Point3<f64>, f64)> =
            pairs.iter().filter(|(_, _, d)| *d < ICP_TRIM_MM).collect();
        if kept.len() < 3 {
            break;
        }
        mean = kept.iter().map(|(_, _, d)| d).sum::<f64>() / kept.len() as f64;
        // rigid fit on the atlas points scaled by the landmark scale
        let source: Vec<Point3<f64>> = kept.iter().map(|(a, _, _)| a * t.scale).collect();
        let target: Vec<Point3<f64>> = kept.iter().map(|(_, c, _)| *c).collect();
        let Some(fit) = fit_similarity(&source, &target, false) else {
            break;
        };
        let next = SimilarityTransform::new(
            fit.transform.rotation_matrix(),
            Vector3::from(fit.transform.translation),
            t.scale,
        );
        let moved = samples
            .iter()
            .step_by(97)
            .map(|a| (next.apply(a) - t.apply(a)).norm())
            .fold(0.0, f64::max);
        t = next;
        if moved < 1e-4 {
            break;
        }
    }
    (t, mean)
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
    use crate::mesh::io::{obj, ply, stl};
    use crate::mesh::shapes::icosphere;

    /// Three balls as the malleus, incus and stapes, and landmarks on them.
    fn balls() -> [TriMesh; 3] {
        [-3.0, 0.0, 3.0].map(|x| icosphere(Point3::new(x, 0.0, 0.0), 1.0, 2))
    }

    fn write_landmarks(dir: &Path) {
        let landmarks = Landmarks::from_points([
            Point3::new(-3.0, 0.0, 0.0),
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(3.0, 0.0, 0.0),
        ]);
        let text = crate::ear::write_json(&landmarks, Some(Side::Right));
        std::fs::write(dir.join("landmarks.json"), text).unwrap();
    }

    /// A chain exported by other tools: names that only contain the ossicle's, three formats,
    /// one surface facing inward. Each is read as its ossicle, outward, with a note saying so;
    /// a folder whose files name no ossicle is refused with the files it has.
    #[test]
    fn a_chain_folder_is_read_by_the_names_its_files_say() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let [malleus, incus, stapes] = balls();
        stl::write_stl(
            &dir.join("01_Malleus.stl"),
            &malleus,
            stl::StlEncoding::Binary,
        )
        .unwrap();
        ply::write_ply(
            &dir.join("Segmentation_Incus.ply"),
            &incus,
            &Default::default(),
        )
        .unwrap();
        let inward = TriMesh {
            vertices: stapes.vertices.clone(),
            triangles: stapes
                .triangles
                .iter()
                .map(|t| [t[0], t[2], t[1]])
                .collect(),
        };
        obj::write_obj(&dir.join("stapes.obj"), &inward).unwrap();
        let drum = icosphere(Point3::new(0.0, 5.0, 0.0), 2.0, 1);
        obj::write_obj(&dir.join("09_Tympanic Membrane.obj"), &drum).unwrap();
        write_landmarks(dir);
        let chain = ChainAnatomy::load(dir).unwrap();
        let kinds: Vec<&str> = chain.parts.iter().map(|(k, _)| k.name()).collect();
        assert_eq!(kinds, ["malleus", "incus", "stapes"]);
        for ((_, read), given) in chain.parts.iter().zip([&malleus, &incus, &stapes]) {
            let (v, expected) = (read.signed_volume(), given.signed_volume());
            assert!(
                expected > 4.0 && (v - expected).abs() < 1e-3 * expected,
                "{v} vs {expected}"
            );
            assert!((read.vertices[0] - given.vertices[0]).norm() < 1e-5);
        }
        let notes = chain.notes.join("\n");
        assert!(
            notes.contains("01_Malleus.stl: read as the malleus"),
            "{notes}"
        );
        assert!(
            notes.contains("Segmentation_Incus.ply: read as the incus"),
            "{notes}"
        );
        assert!(
            notes.contains("stapes.obj: its triangles face inward"),
            "{notes}"
        );
        assert!(notes.contains("Tympanic Membrane.obj: not used"), "{notes}");
        assert_eq!(chain.notes.len(), 4, "{notes}");

        let other = tmp.path().join("other");
        std::fs::create_dir(&other).unwrap();
        stl::write_stl(
            &other.join("Segment_1.stl"),
            &malleus,
            stl::StlEncoding::Binary,
        )
        .unwrap();
        write_landmarks(&other);
        let err = ChainAnatomy::load(&other).unwrap_err().to_string();
        assert!(
            err.contains("no chain surfaces (found Segment_1.stl, none named for an ossicle)"),
            "{err}"
        );
        // two files that would both be the incus: neither is guessed, and the refusal names them
        for file in [
            "malleus.stl",
            "incus_left.stl",
            "incus_right.stl",
            "stapes.stl",
        ] {
            stl::write_stl(&other.join(file), &malleus, stl::StlEncoding::Binary).unwrap();
        }
        let err = ChainAnatomy::load(&other).unwrap_err().to_string();
        assert!(
            err.contains(
                "found malleus, stapes but not incus (other surface files: Segment_1.stl, incus_left.stl, incus_right.stl)"
            ),
            "{err}"
        );
    }

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
}
