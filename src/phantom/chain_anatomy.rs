//! A real ossicular chain as read from its folder: closed surfaces (one per ossicle, or one
//! fused chain) recognised by the structure their file names name, with the chain's three
//! landmarks and side (proposed from the atlas when the folder has no landmark file), and the
//! maps the phantom applies to it (shape variation, articulation, mirroring). Placing it in
//! the atlas frame is `mesh_chain`'s.

use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};
use serde::Serialize;

use super::chain_articulation::ChainArticulation;
use super::chain_landmarks::{self, LandmarksProposed, ProposedLandmarks};
use super::chain_variation::ChainVariation;
use super::patient::PatientAnatomy;
use super::truth::ossicle_surfaces;
use super::variability::Ossicle;
use crate::atlas::{Anatomy, Side};
use crate::ear::Landmarks;
use crate::ear::{
    CHAIN_SPAN_MM, file_stem, is_chain_span, read_landmarks, span_mm, structure_names,
};
use crate::mesh::TriMesh;
use crate::mesh::io::{SURFACE_EXTENSIONS, read_surface, surface_extension, surface_files};
use crate::mesh::surface_repair::{RepairOptions, repair_closed_surface};

/// Names a fused chain surface may have.
const FUSED_STEMS: [&str; 2] = ["chain", "ossicles"];
/// The structure names a chain folder's files may have ([`structure_names`]).
const KNOWN_NAMES: [&str; 6] = ["malleus", "incus", "stapes", "chain", "ossicles", "eardrum"];
/// How far apart the chain's landmarks may lie, relative to the atlas's (the landmark fit's
/// scale; SOFA's chain 1.03, the CT chain 1.19, their random variations 0.94-1.37): beyond it
/// the landmarks are in other units than the surfaces, or another chain's, and the scene
/// around the chain would be drawn at that scale.
pub const LANDMARK_SCALE: (f64, f64) = (0.5, 2.0);
/// Landmark files, tried in this order.
const LANDMARK_FILES: [&str; 4] = [
    "landmarks.json",
    "landmarks.mrk.json",
    "landmarks.fcsv",
    "landmarks.csv",
];

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
    /// part's own, a surface mended, an eardrum surface not used.
    pub notes: Vec<String>,
    /// What was mended in the surfaces as read, each as `FILE NAME: change` (no path: it goes
    /// into truth.json).
    pub mended: Vec<String>,
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
        "--anatomy {dir}: no chain surfaces{found}; expected malleus, incus and stapes (or one fused chain or ossicles) as .ply, .stl, .obj or .vtu files whose names say which (malleus.ply, 01_Malleus.stl, Segmentation_Stapes.obj), in the folder or in its surfaces/"
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
    #[error(
        "--anatomy {dir}: the chain's surfaces span {span_mm:.4} (their bounding box's diagonal); an ossicular chain spans about 13 mm, so expected {} to {}: are the coordinates in mm (not µm, cm, m or voxel indices)?",
        CHAIN_SPAN_MM.0, CHAIN_SPAN_MM.1
    )]
    Span { dir: PathBuf, span_mm: f64 },
    #[error(
        "--anatomy {name}: the chain's landmarks lie {scale:.4} times as far apart as the atlas's; expected {} to {}: are the landmarks and the surfaces in the same units (mm), and the landmarks this chain's?",
        LANDMARK_SCALE.0, LANDMARK_SCALE.1
    )]
    LandmarkScale { name: String, scale: f64 },
    #[error("{0}")]
    Read(String),
    #[error("{path}: {what}")]
    Surface { path: PathBuf, what: String },
}

/// The chain folder's surface files by the structure their names name
/// ([`structure_names`]): the folder's own before its `surfaces/`, and in one folder in the
/// order of [`SURFACE_EXTENSIONS`] (PLY, STL, OBJ, VTU) for the same name.
fn named_files(dirs: &[PathBuf]) -> Result<Vec<(String, PathBuf)>, ChainError> {
    // `surface_files` lists only the readable extensions
    let rank = |p: &PathBuf| {
        let ext = surface_extension(p).unwrap_or_default();
        SURFACE_EXTENSIONS.iter().position(|e| *e == ext)
    };
    let mut named: Vec<(String, PathBuf)> = Vec::new();
    for dir in dirs {
        let mut files = surface_files(dir).map_err(|e| ChainError::Read(e.to_string()))?;
        files.sort_by_key(rank);
        for (name, path) in structure_names(&files).into_iter().zip(files) {
            if !named.iter().any(|(n, _)| *n == name) {
                named.push((name, path));
            }
        }
    }
    Ok(named)
}

/// Reads one closed surface, mended where another tool left it unfit for inside tests
/// (`mesh::surface_repair`: faces turned, specks dropped, small holes closed), each change a
/// note; a surface that cannot be mended is refused.
fn read_part(
    path: &Path,
    notes: &mut Vec<String>,
    mended: &mut Vec<String>,
) -> Result<TriMesh, ChainError> {
    let mesh = read_surface(path).map_err(|e| ChainError::Read(e.to_string()))?;
    let refused = |what: String| ChainError::Surface {
        path: path.to_path_buf(),
        what,
    };
    let (mesh, repair) = repair_closed_surface(&mesh, RepairOptions::default())
        .map_err(|e| refused(e.to_string()))?;
    let file = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    for change in repair.describe() {
        notes.push(format!("{}: {change}", path.display()));
        mended.push(format!("{file}: {change}"));
    }
    let volume = mesh.signed_volume();
    if volume.is_nan() || volume <= 0.0 {
        return Err(refused(format!(
            "expected a closed surface (enclosed volume {volume:.3} mm³)"
        )));
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
        let missing: Vec<&str> = Ossicle::ALL
            .iter()
            .map(|o| o.name())
            .filter(|n| !found.contains(n))
            .collect();
        let fused = FUSED_STEMS.iter().find_map(|s| file(s));
        let mut notes = Vec::new();
        let mut mended = Vec::new();
        let chosen: Vec<(PartKind, PathBuf)> = if found.len() == 3 {
            ossicles
                .into_iter()
                .filter_map(|(o, p)| p.map(|p| (PartKind::Ossicle(o), p)))
                .collect()
        } else if let Some(p) = fused {
            for single in ossicles.iter().filter_map(|(_, single)| single.as_ref()) {
                notes.push(format!(
                    "{}: not used; the chain is read whole from {} (no {} surface)",
                    single.display(),
                    p.display(),
                    missing.join(" or "),
                ));
            }
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
            parts.push((kind, read_part(&path, &mut notes, &mut mended)?));
        }
        let span_mm = span_mm(parts.iter().flat_map(|(_, m)| &m.vertices));
        if !is_chain_span(span_mm) {
            return Err(ChainError::Span {
                dir: dir.to_path_buf(),
                span_mm,
            });
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
            mended,
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
            mended: self.mended.clone(),
        }
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
            notes.contains("stapes.obj: triangles facing inward"),
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

    /// A chain whose coordinates are in other units than mm (µm, cm) is refused with its
    /// span and the question of units, before any image is sized by it.
    #[test]
    fn a_chain_in_other_units_is_refused() {
        for (factor, span) in [(1000.0, "8485.2814"), (0.1, "0.8485")] {
            let tmp = tempfile::tempdir().unwrap();
            for (name, mut ball) in ["malleus", "incus", "stapes"].into_iter().zip(balls()) {
                ball.vertices.iter_mut().for_each(|p| *p *= factor);
                ply::write_ply(
                    &tmp.path().join(format!("{name}.ply")),
                    &ball,
                    &Default::default(),
                )
                .unwrap();
            }
            write_landmarks(tmp.path());
            let err = ChainAnatomy::load(tmp.path()).unwrap_err().to_string();
            assert!(
                err.contains(&format!("the chain's surfaces span {span} "))
                    && err.contains("expected 4 to 40: are the coordinates in mm"),
                "{err}"
            );
        }
    }

    /// A fused chain exported with a fifth of its triangles flipped and a speck of
    /// segmentation noise beside it is read as the clean chain, each change a note and a
    /// record for truth.json (by file name, not path); one with
    /// a cap cut away is refused with the opening's size, not rendered around a hole.
    #[test]
    fn a_defective_chain_export_is_mended_or_refused() {
        let [malleus, incus, stapes] = balls();
        let clean = TriMesh::concatenated(&[&malleus, &incus, &stapes]);
        let read = |mesh: &TriMesh| {
            let tmp = tempfile::tempdir().unwrap();
            obj::write_obj(&tmp.path().join("Ossicular chain.obj"), mesh).unwrap();
            write_landmarks(tmp.path());
            ChainAnatomy::load(tmp.path())
        };
        let mut flipped = clean.clone();
        flipped
            .triangles
            .iter_mut()
            .step_by(5)
            .for_each(|t| t.swap(0, 2));
        let speck = icosphere(Point3::new(6.0, 1.0, 0.0), 0.1, 1);
        let defective = TriMesh::concatenated(&[&flipped, &speck]);
        let chain = read(&defective).unwrap();
        let [(kind, mended)] = chain.parts.as_slice() else {
            panic!("{} parts", chain.parts.len());
        };
        assert_eq!(*kind, PartKind::Chain);
        assert_eq!(mended.triangles.len(), clean.triangles.len());
        assert!((mended.signed_volume() - clean.signed_volume()).abs() < 1e-9);
        let notes = chain.notes.join("\n");
        assert!(
            notes.contains(&format!(
                "{} triangles turned to agree with their neighbours",
                clean.triangles.len().div_ceil(5)
            )) && notes.contains(&format!(
                "1 separate piece(s) of {:.4} mm³ dropped as specks",
                speck.signed_volume()
            )),
            "{notes}"
        );
        assert_eq!(chain.mended.len(), 2, "{:?}", chain.mended);
        assert!(
            chain
                .mended
                .iter()
                .all(|m| m.starts_with("Ossicular chain.obj: ")),
            "{:?}",
            chain.mended
        );
        let mut cut = clean.clone();
        cut.triangles
            .retain(|t| t.iter().all(|&v| clean.vertices[v as usize].z < 0.3));
        let err = read(&cut).unwrap_err().to_string();
        assert!(
            err.contains("Ossicular chain.obj")
                && err.contains("an opening")
                && err.contains("mm around")
                && err.contains("expected a closed surface"),
            "{err}"
        );
    }
}
