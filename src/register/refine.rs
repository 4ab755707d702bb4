//! The last, finest level of the registration: the ossicles' surfaces onto the image's bone
//! edges, the rest of the mesh following.
//!
//! Why a level of its own: the FEM levels regularise by elastic energy, which is what keeps
//! the chain a chain, but it also holds shape detail back — on real people's chains the
//! springs and the FEM balance 0.1-0.2 mm from the edges the probes see, while the edges
//! themselves are within about 0.05 mm of the true surface. Here the regulariser is
//! only smoothness of the displacement:
//!
//! - every ossicle surface triangle probes the image along its normal for its bone edge (the
//!   deformable stage's probe and screening), and each surface node gets the area-weighted
//!   mean displacement its triangles found (the deformable stage's targets);
//! - the displacement u of all mesh nodes minimises
//!   Σ_found a_v |u_v − d_v|² + smoothness · Σ_edges |u_a − u_b|²
//!   (a_v the node's probed area over the mean, edges those of the tetrahedra), one numeric
//!   sparse Cholesky per solve on a symbolic analysis made once: found nodes move to their
//!   edges, nodes without a find (the faces on the joints, ligaments and tendons) and the
//!   interior follow harmonically;
//! - where a round's move would invert or flatten an element, the element's nodes give up
//!   their own offsets and their edges stiffen, and the round is solved again, up to
//!   `MAX_STIFFENINGS` times; after that the level stops at its last admissible shape. The next
//!   round starts from the stiffening the last one ended with, relaxed one step (divided by
//!   `STIFFEN`, never below 1): an element that needed it once usually needs it again, and
//!   each stiffening costs a solve, while a region whose elements no longer fail softens
//!   again round by round (docs/registration.md, "The surface level's stiffening carried
//!   from round to round", has the comparison with unstiffened rounds). Flat means a shape quality below `MIN_QUALITY`, or, for an element the level found below it,
//!   below nine tenths of what it had at the level's start; and never below the package's
//!   floors (`mesh::quality`: shape quality and volume against the placed atlas) unless the
//!   element started there, and then no lower.
//!
//! The level stops when the mean border offset no longer falls (by `PLATEAU`) or after
//! `rounds` rounds.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use super::DeformSettings;
use super::deform::{
    ProbeConfig, ProbeTriangle, kept_offsets, node_displacements, probe_borders, screen,
    triangle_neighbours,
};
use crate::fem::vector_state::DenseKernels;
use crate::image::Sampler;
use crate::mesh::quality::ElementFloors;
use crate::mesh::tet::TetMesh;

/// No move may leave an element's shape quality (its volume over the regular tetrahedron's
/// of its RMS edge; 1 regular, 0 flat) below this...
const MIN_QUALITY: f64 = 0.05;
/// Times a round is solved again with the nodes of the elements it would flatten stiffened,
/// before the level stops...
const MAX_STIFFENINGS: usize = 6;
/// ... each time multiplying the smoothness of their edges by this. The next round starts from
/// the stiffening the last one ended with, divided by this once (module documentation).
const STIFFEN: f64 = 10.0;
/// The mean border offset must fall by this fraction per round to go on.
const PLATEAU: f64 = 0.03;
/// Tikhonov term keeping the system definite on a part with no find [unitless].
const DEFINITE: f64 = 1e-9;

/// Knobs of the surface level (`[refine]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefineConfig {
    /// Run the surface level after the FEM levels [true/false].
    pub enabled: bool,
    /// Probe-and-move rounds at most \[count\].
    pub rounds: usize,
    /// Weight of the displacement's smoothness over each tetrahedron edge against a node's
    /// probed offset (a node of mean probed area weighs 1) \[unitless\].
    pub smoothness: f64,
    /// How far each triangle looks for its bone edge on either side \[mm\]: the FEM levels
    /// leave the surface within a few tenths of a millimetre of its edges.
    pub search_range_mm: f64,
}

/// What the surface level did (`refinement` in the deformable stage's record).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    /// Rounds whose move was kept.
    pub rounds: usize,
    /// Mean |offset| of the kept border points before the first round and in the last \[mm\]
    /// (absent when nothing was found).
    pub mean_offset_first_mm: Option<f64>,
    pub mean_offset_last_mm: Option<f64>,
    /// Fraction of the probed triangles with a kept border point in the last round.
    pub found_fraction: f64,
    /// Largest nodal move of the whole level \[mm\].
    pub max_move_mm: f64,
    /// Nodes whose edges were stiffer than the rest in the last kept round, to keep its
    /// elements from flattening (its own stiffening and what it started from).
    pub stiffened_nodes: usize,
    /// Why it stopped.
    pub stop: RefineStop,
}

/// Why the surface level stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RefineStop {
    /// The mean border offset stopped falling.
    Plateau,
    /// The round limit.
    Rounds,
    /// A round's move would flatten an element however stiff its surroundings.
    ElementGuard,
    /// The probes found no edge.
    NothingFound,
    /// The smoothing system could not be factorised (out of memory).
    Factorisation,
}

impl RefineStop {
    /// The name used in the record (`plateau`, `rounds`, ...).
    pub fn name(self) -> &'static str {
        match self {
            RefineStop::Plateau => "plateau",
            RefineStop::Rounds => "rounds",
            RefineStop::ElementGuard => "element_guard",
            RefineStop::NothingFound => "nothing_found",
            RefineStop::Factorisation => "factorisation",
        }
    }
}

/// Moves `x` (all atlas nodes; those of no tetrahedron are left alone) onto the bone edges
/// probed from `probes` (with the deformable stage's probe and screening, `settings.deform`;
/// the level's knobs `settings.refine`). Element volumes are held against `reference` (the
/// placed atlas).
pub fn refine(
    mesh: &TetMesh,
    reference: &[Point3<f64>],
    probes: &[ProbeTriangle],
    x: &mut [Point3<f64>],
    sampler: &Sampler,
    step: f64,
    settings: DeformSettings,
) -> Refinement {
    let (deform, cfg) = (settings.deform, settings.refine);
    let n = x.len();
    let probe_cfg = ProbeConfig {
        search_range_mm: cfg.search_range_mm,
        ..deform.probe.clone()
    };
    let neighbours = triangle_neighbours(probes, n);
    let start: Vec<Point3<f64>> = x.to_vec();
    let floors = ElementFloors::new(&mesh.tets, reference, &start, MIN_QUALITY);
    let mut record = Refinement {
        rounds: 0,
        mean_offset_first_mm: None,
        mean_offset_last_mm: None,
        found_fraction: 0.0,
        max_move_mm: 0.0,
        stiffened_nodes: 0,
        stop: RefineStop::Rounds,
    };
    let Some(system) = Smoothing::new(mesh, n, cfg.smoothness) else {
        record.stop = RefineStop::Factorisation;
        return record;
    };
    let mut best = f64::INFINITY;
    let mut stiffness = vec![1.0f64; n];
    for round in 0..=cfg.rounds {
        let borders = probe_borders(probes, x, sampler, step, &probe_cfg);
        let kept = screen(&borders, &neighbours, deform.neighbour_tolerance_mm);
        let (used, mean_offset) = kept_offsets(&borders, &kept);
        if used == 0 {
            record.stop = RefineStop::NothingFound;
            break;
        }
        if round == 0 {
            record.mean_offset_first_mm = Some(mean_offset);
        }
        record.mean_offset_last_mm = Some(mean_offset);
        record.found_fraction = used as f64 / probes.len().max(1) as f64;
        if round == cfg.rounds {
            break;
        }
        if mean_offset > (1.0 - PLATEAU) * best {
            record.stop = RefineStop::Plateau;
            break;
        }
        best = mean_offset;
        let (data, area) = node_displacements(probes, &borders, &kept, x);
        let weight = relative(&area);
        for s in &mut stiffness {
            *s = (*s / STIFFEN).max(1.0);
        }
        match admissible_move(mesh, &floors, &system, x, &data, weight, &mut stiffness) {
            Ok(moved) => {
                x.copy_from_slice(&moved);
                record.stiffened_nodes = stiffness.iter().filter(|s| **s > 1.0).count();
                record.rounds += 1;
            }
            Err(stop) => {
                record.stop = stop;
                break;
            }
        }
    }
    record.max_move_mm = x
        .iter()
        .zip(&start)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max);
    record
}

/// The unique edges of the tetrahedra.
fn tet_edges(mesh: &TetMesh, n: usize) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = mesh
        .tets
        .iter()
        .flat_map(|t| {
            [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                .map(|(i, j)| (t[i].min(t[j]), t[i].max(t[j])))
        })
        .filter(|&(a, b)| (b as usize) < n && a != b)
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Each node's probed area relative to the mean over the nodes that have one.
fn relative(area: &[f64]) -> Vec<f64> {
    let found = area.iter().filter(|a| **a > 0.0).count().max(1);
    let mean = area.iter().sum::<f64>() / found as f64;
    area.iter()
        .map(|a| a / mean.max(f64::MIN_POSITIVE))
        .collect()
}

/// One round's move from `x` towards the displacements `data` (weighed by `weight`), each
/// node's edges as stiff as `stiffness` says: where it would flatten an element, that
/// element's nodes give up their own offsets and their edges stiffen, and the round is solved
/// again, up to [`MAX_STIFFENINGS`] times. Returns the moved nodes; `stiffness` is left as the
/// admissible move had it.
fn admissible_move(
    mesh: &TetMesh,
    floors: &ElementFloors,
    system: &Smoothing,
    x: &[Point3<f64>],
    data: &[Vector3<f64>],
    mut weight: Vec<f64>,
    stiffness: &mut [f64],
) -> Result<Vec<Point3<f64>>, RefineStop> {
    for _ in 0..=MAX_STIFFENINGS {
        let u = system
            .solve(data, &weight, stiffness)
            .ok_or(RefineStop::Factorisation)?;
        let trial: Vec<Point3<f64>> = x.iter().zip(&u).map(|(p, d)| p + d).collect();
        let failing = floors.failing(&trial);
        if failing.is_empty() {
            return Ok(trial);
        }
        for (t, _) in failing {
            for k in mesh.tets[t] {
                weight[k as usize] = 0.0;
                stiffness[k as usize] *= STIFFEN;
            }
        }
    }
    Err(RefineStop::ElementGuard)
}

/// The smoothing system of one mesh: its edges, the level's smoothness weight and the
/// symbolic Cholesky factorisation of their pattern, computed once and reused by every solve
/// of the level.
struct Smoothing {
    edges: Vec<(u32, u32)>,
    smoothness: f64,
    symbolic: SymbolicLlt<usize>,
}

impl Smoothing {
    /// `None` if the pattern cannot be analysed.
    fn new(mesh: &TetMesh, n: usize, smoothness: f64) -> Option<Smoothing> {
        let edges = tet_edges(mesh, n);
        let matrix = Self::matrix(&edges, &vec![1.0; n], &vec![1.0; n], smoothness)?;
        let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower).ok()?;
        Some(Smoothing {
            edges,
            smoothness,
            symbolic,
        })
    }

    /// The lower triangle of diag(w) + smoothness · L, L the graph Laplacian of the edges
    /// weighted by the larger `stiffness` of each edge's nodes (the same pattern whatever the
    /// values).
    fn matrix(
        edges: &[(u32, u32)],
        weight: &[f64],
        stiffness: &[f64],
        smoothness: f64,
    ) -> Option<SparseColMat<usize, f64>> {
        let n = weight.len();
        let mut diagonal: Vec<f64> = weight.iter().map(|w| w + DEFINITE).collect();
        let mut triplets = Vec::with_capacity(n + edges.len());
        for &(a, b) in edges {
            let w = smoothness * stiffness[a as usize].max(stiffness[b as usize]);
            diagonal[a as usize] += w;
            diagonal[b as usize] += w;
            // b > a: the lower triangle
            triplets.push(Triplet::new(b as usize, a as usize, -w));
        }
        triplets.extend(
            diagonal
                .iter()
                .enumerate()
                .map(|(v, d)| Triplet::new(v, v, *d)),
        );
        SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).ok()
    }

    /// The displacement minimising Σ w_v |u_v − d_v|² + smoothness Σ_edges s_ab |u_a − u_b|²
    /// (s_ab the larger `stiffness` of the edge's nodes; the same scalar system for each
    /// coordinate); nodes on no edge keep u = 0. `None` if the factorisation fails.
    fn solve(
        &self,
        data: &[Vector3<f64>],
        weight: &[f64],
        stiffness: &[f64],
    ) -> Option<Vec<Vector3<f64>>> {
        let n = data.len();
        let matrix = Self::matrix(&self.edges, weight, stiffness, self.smoothness)?;
        let mut rhs = Mat::<f64>::from_fn(n, 3, |v, c| weight[v] * data[v][c]);
        {
            let _clean = DenseKernels::parallel();
            let llt =
                Llt::try_new_with_symbolic(self.symbolic.clone(), matrix.as_ref(), Side::Lower)
                    .ok()?;
            llt.solve_in_place(rhs.as_mut());
        }
        Some(
            (0..n)
                .map(|v| Vector3::new(rhs[(v, 0)], rhs[(v, 1)], rhs[(v, 2)]))
                .collect(),
        )
    }
}
