//! The deformable stage (the source study's method, section 3): from each atlas surface
//! triangle, probe the image along its normal for the bone boundary; spring each surface node
//! towards where its triangles found it; let the atlas FEM regularise; repeat, with new border
//! points each iteration, until the nodes stop moving.
//!
//! Where this departs from the study, and why:
//! - A node's target is its own position plus the area-weighted mean *displacement* its
//!   triangles found, not the barycentre of their border points: the barycentre of points near
//!   the triangles' centres pulls every node of a curved surface inwards by about the
//!   curvature times the squared edge length, a bias of the order of the accuracy sought.
//! - Border points are screened: the bone side of an edge must be bone-like, and a triangle
//!   whose offset disagrees with the median of its neighbours' by more than a tolerance (a
//!   cavity wall, the otic capsule, noise) is dropped for that iteration.
//! - The FEM keeps the atlas's stiffness ratios between regions but is scaled so that bone has
//!   the registration modulus `regularisation_modulus_pa`: with the real 1.41e10 Pa no spring
//!   of sensible stiffness could move anything. Springs have stiffness per unit surface area.
//! - The static solver never accepts an inverted element: if no admissible step exists the
//!   stage keeps the last valid state and goes on with the springs around the element that
//!   would invert (within `SOFTEN_RADIUS_MM`) half as stiff, so the FEM smooths more there
//!   while the rest of the chain keeps converging; after four halvings at one place it stops
//!   there and says so. A step that would flatten an element below its `floors`
//!   (`mesh::quality::ElementFloors`) is refused the same way, and so is the solver's last
//!   iterate when it refuses a step that would invert one (it inverts nothing, but may be
//!   flat). The FEM's own guard keeps a
//!   tenth of each element's volume at the level's rest shape, not its shape: on phantoms of
//!   real chains, springs on the bone around a soft tendon or joint element sheared it flat
//!   (shape quality 0.007-0.018, which `verify` refuses in a package).

mod probe;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::fem::{
    ElementId, FactorPrecision, FemError, FemModel, FixedDofs, Spring, StaticOptions, StaticSolver,
};
use crate::image::Sampler;
use crate::mesh::quality::ElementFloors;
use crate::progress::Reporter;
pub use probe::{Border, ProbeConfig, ProbeKind, probe};

/// The mean border offset has reached a plateau when it no longer falls below (1 − this)
/// times its best value so far...
const PLATEAU: f64 = 0.02;
/// ... for this many iterations in a row.
const PLATEAU_ITERATIONS: usize = 3;

/// Springs are halved when they would invert an element, down to this factor.
const MIN_SPRING_SCALE: f64 = 1.0 / 16.0;
/// ... those within this distance of the element's centroid [mm] (a bone's local shape
/// detail; the stapes is 3 mm long).
const SOFTEN_RADIUS_MM: f64 = 1.0;

/// Knobs of the deformable stage (`[deform]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformConfig {
    #[serde(flatten)]
    pub probe: ProbeConfig,
    /// Young's modulus given to bone during registration; other regions keep their ratio to
    /// bone \[Pa\].
    pub regularisation_modulus_pa: f64,
    /// No region is softer than this fraction of bone during registration \[fraction\].
    pub min_modulus_ratio: f64,
    /// Fit the eardrum to the soft-tissue ridge in the image (off: it only follows the
    /// manubrium).
    pub probe_eardrum: bool,
    /// Weight of each found eardrum offset against the smoothness of the offsets over each
    /// membrane edge (lower: smoother) \[unitless\].
    pub eardrum_offset_weight: f64,
    /// Spring stiffness per unit of surface area of a node [µN/mm per mm²].
    pub spring_stiffness_per_area: f64,
    /// A triangle's offset may differ from the median of its neighbours' by this much \[mm\].
    pub neighbour_tolerance_mm: f64,
    /// Converged when 99 % of the nodes moved less than this in an iteration, or when the
    /// mean border offset stopped falling by 2 % for 3 iterations (image noise makes the
    /// border points jitter by a fraction of a voxel between iterations) \[mm\].
    pub tolerance_mm: f64,
    /// Iteration limit of the outer loop \[count\].
    pub max_iterations: usize,
    /// Times the FEM's rest shape is reset to the registered shape once it settles, each
    /// followed by another round to equilibrium (0: one round from the articulated atlas)
    /// \[count\].
    pub rest_updates: usize,
    /// Registrations from which the atlas is placed again before the final one, each without
    /// the surface level (`placement::deform_placed_again`; 0: registered from the landmark
    /// placement) \[count\].
    #[serde(default = "default_placement_passes")]
    pub placement_passes: usize,
}

fn default_placement_passes() -> usize {
    1
}

/// How each outer iteration's FEM solve steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Steps {
    /// A tangent assembled and factorised at every Newton iteration.
    Newton,
    /// The last factorisation kept while each iteration takes the residual to 60 % of the last
    /// or less (chord steps; `StaticOptions::reuse_tangent_below`): the same equilibrium but another path,
    /// and the solves are stopped short of it, so the registration differs by a few
    /// thousandths of a millimetre; a level costs about half. For registrations used only to
    /// place the atlas (`placement::deform_placed_again`).
    Chord,
}

/// A surface triangle to probe: three FEM nodes (counter-clockwise seen from outside).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeTriangle {
    pub nodes: [u32; 3],
    pub kind: ProbeKind,
}

/// One outer iteration, for the convergence history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IterationStats {
    pub iteration: usize,
    /// Triangles whose probe found a boundary.
    pub borders_found: usize,
    /// Of those, kept after screening.
    pub borders_used: usize,
    /// Mean |offset| of the kept border points \[mm\].
    pub mean_offset_mm: f64,
    /// Largest nodal update of the FEM solve \[mm\].
    pub max_update_mm: f64,
    /// 99th percentile of the nodal updates \[mm\]: the convergence measure.
    pub p99_update_mm: f64,
    /// Smallest factor on a node's spring stiffness (halved around an element each time a
    /// step would invert it).
    pub spring_scale: f64,
}

/// Why a converged stage stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The mean border offset stopped falling (by 2 % over 3 iterations): the borders the
    /// probes find jitter by a fraction of a voxel, so the surface is as close as it gets.
    Plateau,
    /// The nodes stopped moving (99 % under the tolerance) while the mean border offset was
    /// still falling: the FEM and the springs balance (see `mean_offset_mm` for how far from
    /// the image).
    Balance,
}

impl StopReason {
    /// The name `metrics.json` records.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Plateau => "plateau",
            StopReason::Balance => "balance",
        }
    }
}

/// How the stage ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum DeformStatus {
    Converged {
        reason: StopReason,
        /// Mean border offset of the last iteration \[mm\].
        mean_offset_mm: f64,
    },
    MaxIterations,
    /// No admissible step (one that inverts or flattens no element) existed; the last valid
    /// state is returned.
    InversionGuard {
        message: String,
    },
}

impl DeformStatus {
    /// The name the records use ("converged", "max_iterations", "inversion_guard").
    pub fn name(&self) -> &'static str {
        match self {
            DeformStatus::Converged { .. } => "converged",
            DeformStatus::MaxIterations => "max_iterations",
            DeformStatus::InversionGuard { .. } => "inversion_guard",
        }
    }

    /// How the FEM levels ended after `iterations`, for people (the progress line, `run`'s
    /// summary): the iteration limit is the designed end when the surface level follows.
    pub fn describe(&self, iterations: usize) -> String {
        match self {
            DeformStatus::Converged { reason, .. } => {
                format!(
                    "converged ({}) after {iterations} iterations",
                    reason.name()
                )
            }
            DeformStatus::MaxIterations => format!("{iterations} iterations (their limit)"),
            DeformStatus::InversionGuard { .. } => {
                format!("stopped by the inversion guard after {iterations} iterations")
            }
        }
    }
}

/// The result of the deformable stage.
#[derive(Debug, Clone)]
pub struct DeformResult {
    pub positions: Vec<Point3<f64>>,
    pub history: Vec<IterationStats>,
    pub status: DeformStatus,
}

/// Errors that stop the deformable stage before it starts.
#[derive(Debug, thiserror::Error)]
pub enum DeformError {
    #[error("deformable registration: {0}")]
    Fem(#[from] FemError),
    #[error(
        "deformable registration: no boundary found in the image around the atlas surface (is the image of the same ear, and are the landmarks right?)"
    )]
    NothingFound,
    #[error(
        "deformable registration: tetrahedron {tetrahedron} ({region}) would be left at shape quality {shape_quality:.3} (floor {}) and {volume_ratio:.3} of its atlas volume (floor {}); no package is written, as its stiffness would ill-condition a simulation (check the landmarks and the image)",
        crate::mesh::quality::MIN_SHAPE_QUALITY,
        crate::mesh::quality::MIN_VOLUME_RATIO
    )]
    FlatElement {
        tetrahedron: usize,
        region: String,
        shape_quality: f64,
        volume_ratio: f64,
    },
}

/// Runs the stage on `model`, whose rest shape is the rigidly placed atlas; returns the
/// registered node positions. `step` is the probe step (the smallest voxel spacing, mm); no
/// step leaves a tetrahedron below its `floors`.
#[allow(clippy::too_many_arguments)]
pub fn deform(
    model: &FemModel,
    floors: &ElementFloors,
    probes: &[ProbeTriangle],
    sampler: &Sampler,
    step: f64,
    cfg: &DeformConfig,
    steps: Steps,
    progress: &dyn Reporter,
) -> Result<DeformResult, DeformError> {
    let n = model.node_count();
    let mut x: Vec<Point3<f64>> = model.rest_positions().to_vec();
    let mut solver = StaticSolver::new(model, FixedDofs::from_nodes(n, &[])?)?;
    let neighbours = triangle_neighbours(probes, n);
    let mut history = Vec::new();
    let bar = progress.task("deform", cfg.max_iterations as u64);
    let options = StaticOptions {
        tolerance_mm: cfg.tolerance_mm * 0.5,
        // each outer iteration probes anew, so its solve need not be exact: three Newton
        // iterations (four cost a third more per iteration for the same registration)
        max_iterations: 3,
        max_halvings: 12,
        // keeps each linear solve definite where no spring acts (see StaticOptions)
        tangent_shift: 1e-6 * cfg.regularisation_modulus_pa,
        reuse_tangent_below: match steps {
            Steps::Newton => 0.0,
            Steps::Chord => 0.6,
        },
        // a few inexact Newton steps towards springs probed anew: a single-precision tangent
        // reaches the same shape to micrometres, the level a tenth faster (docs/fem.md)
        tangent_precision: FactorPrecision::Single,
        ..StaticOptions::default()
    };
    let mut status = DeformStatus::MaxIterations;
    let (mut best_offset, mut stalled) = (f64::INFINITY, 0usize);
    let mut spring_scale = vec![1.0f64; n];
    for iteration in 1..=cfg.max_iterations {
        let borders = probe_borders(probes, &x, sampler, step, &cfg.probe);
        let found = borders.iter().filter(|b| b.is_some()).count();
        if iteration == 1 && found == 0 {
            return Err(DeformError::NothingFound);
        }
        let kept = screen(&borders, &neighbours, cfg.neighbour_tolerance_mm);
        let springs = node_springs(
            probes,
            &borders,
            &kept,
            &x,
            cfg.spring_stiffness_per_area,
            &spring_scale,
        );
        let (used, mean_offset) = kept_offsets(&borders, &kept);
        let before = x.clone();
        let outcome = solver.solve_with_springs(&mut x, &springs, &options);
        let mut updates: Vec<f64> = x.iter().zip(&before).map(|(p, q)| (p - q).norm()).collect();
        updates.sort_by(f64::total_cmp);
        let max_update = updates.last().copied().unwrap_or(0.0);
        let p99_update = updates
            .get(updates.len() * 99 / 100)
            .copied()
            .unwrap_or(0.0);
        history.push(IterationStats {
            iteration,
            borders_found: found,
            borders_used: used,
            mean_offset_mm: mean_offset,
            max_update_mm: max_update,
            p99_update_mm: p99_update,
            spring_scale: spring_scale.iter().copied().fold(1.0, f64::min),
        });
        bar.inc(1);
        // the springs pull some element inside out, or flat: keep the last admissible state
        // and go on with softer springs around it (the FEM then smooths more there); give up
        // when they are too soft to register anything
        let rejected = match outcome {
            Ok(_) | Err(FemError::NotConverged { .. }) => {
                floors.failing(&x).first().map(|&(element, quality)| {
                    x = before;
                    (
                        ElementId::Tet(element),
                        format!(
                            "a step would flatten tetrahedron {element} (shape quality \
                             {quality:.3}, or its volume)"
                        ),
                    )
                })
            }
            Err(e @ FemError::StepRejected { element, .. }) => {
                // the solver stopped at its last iterate that inverts nothing, which may
                // still be flat
                if !floors.failing(&x).is_empty() {
                    x = before;
                }
                Some((element, e.to_string()))
            }
            Err(e) => return Err(e.into()),
        };
        if let Some((element, message)) = rejected {
            if soften_around(model, element, &x, &mut spring_scale) < MIN_SPRING_SCALE {
                status = DeformStatus::InversionGuard { message };
                break;
            }
            stalled = 0;
            continue;
        }
        // equilibrium: the nodes stopped moving, or the borders stopped getting closer (in a
        // noisy image the border points jitter by a fraction of a voxel from one iteration
        // to the next, so the nodes never stop exactly)
        stalled = if mean_offset > (1.0 - PLATEAU) * best_offset {
            stalled + 1
        } else {
            0
        };
        best_offset = best_offset.min(mean_offset);
        let reason = if stalled >= PLATEAU_ITERATIONS {
            Some(StopReason::Plateau)
        } else if p99_update < cfg.tolerance_mm {
            Some(StopReason::Balance)
        } else {
            None
        };
        if let Some(reason) = reason {
            status = DeformStatus::Converged {
                reason,
                mean_offset_mm: mean_offset,
            };
            break;
        }
    }
    bar.finish(&status.describe(history.len()));
    Ok(DeformResult {
        positions: x,
        history,
        status,
    })
}

/// A border found from one surface triangle: the border, the triangle's area, centre and
/// outward unit normal (with the nodes where they were probed from).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Probed {
    pub border: Border,
    pub area: f64,
    pub centre: Point3<f64>,
    pub normal: Vector3<f64>,
}

/// Probes the image from the centre of every triangle of `probes` (nodes at `x`) along its
/// outward normal; `None` where nothing was found or the triangle is degenerate.
pub(crate) fn probe_surface(
    probes: &[ProbeTriangle],
    x: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    cfg: &ProbeConfig,
) -> Vec<Option<Probed>> {
    probes
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.nodes.map(|k| x[k as usize]);
            let cross = (b - a).cross(&(c - a));
            let area = 0.5 * cross.norm();
            if area <= 0.0 {
                return None;
            }
            let centre = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let normal = cross / (2.0 * area);
            probe(sampler, &centre, &normal, t.kind, step, cfg).map(|border| Probed {
                border,
                area,
                centre,
                normal,
            })
        })
        .collect()
}

/// Halves the springs of the nodes within [`SOFTEN_RADIUS_MM`] of `element` (a membrane
/// element too: the eardrum's nodes have no springs, but the stage must still end); returns
/// the smallest factor now left on the element's own nodes.
fn soften_around(
    model: &FemModel,
    element: ElementId,
    x: &[Point3<f64>],
    scale: &mut [f64],
) -> f64 {
    let nodes: Vec<u32> = match element {
        ElementId::Tet(e) => model.tets.get(e).map(|t| t.nodes.to_vec()),
        ElementId::Membrane(e) => model.membranes.get(e).map(|t| t.nodes.to_vec()),
    }
    .unwrap_or_default();
    if nodes.is_empty() {
        // not an element of this model: soften everywhere
        scale.iter_mut().for_each(|s| *s *= 0.5);
        return scale.iter().copied().fold(1.0, f64::min);
    }
    let centre = nodes
        .iter()
        .map(|&k| x[k as usize].coords)
        .sum::<Vector3<f64>>()
        / nodes.len() as f64;
    for (s, p) in scale.iter_mut().zip(x) {
        if (p.coords - centre).norm() <= SOFTEN_RADIUS_MM {
            *s *= 0.5;
        }
    }
    nodes.iter().map(|&k| scale[k as usize]).fold(1.0, f64::min)
}

/// For each probe triangle, the probe triangles sharing a node with it.
pub(crate) fn triangle_neighbours(probes: &[ProbeTriangle], node_count: usize) -> Vec<Vec<u32>> {
    let mut by_node: Vec<Vec<u32>> = vec![Vec::new(); node_count];
    for (t, tri) in probes.iter().enumerate() {
        for k in tri.nodes {
            by_node[k as usize].push(t as u32);
        }
    }
    probes
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let mut nb: Vec<u32> = tri
                .nodes
                .iter()
                .flat_map(|k| by_node[*k as usize].iter().copied())
                .filter(|&o| o as usize != t)
                .collect();
            nb.sort_unstable();
            nb.dedup();
            nb
        })
        .collect()
}

/// Keeps a border point when its offset is within `tolerance` of the median offset of the
/// neighbours that found one (isolated finds, with no neighbour to agree, are kept).
pub(crate) fn screen(
    borders: &[Option<(Border, f64)>],
    neighbours: &[Vec<u32>],
    tolerance: f64,
) -> Vec<bool> {
    borders
        .par_iter()
        .enumerate()
        .map(|(t, b)| {
            let Some((bd, _)) = b else { return false };
            let mut offs: Vec<f64> = neighbours[t]
                .iter()
                .filter_map(|&o| borders[o as usize].map(|(nb, _)| nb.offset_mm))
                .collect();
            if offs.is_empty() {
                return true;
            }
            offs.sort_by(f64::total_cmp);
            let median = offs[offs.len() / 2];
            (bd.offset_mm - median).abs() <= tolerance
        })
        .collect()
}

/// One spring per node that has kept border points around it: target = position + the
/// area-weighted mean displacement of its triangles; stiffness = per-area stiffness x the
/// node's factor `scale` x a third of the area of those triangles.
fn node_springs(
    probes: &[ProbeTriangle],
    borders: &[Option<(Border, f64)>],
    kept: &[bool],
    x: &[Point3<f64>],
    stiffness_per_area: f64,
    scale: &[f64],
) -> Vec<Spring> {
    let (displacement, area) = node_displacements(probes, borders, kept, x);
    (0..x.len())
        .filter(|&k| area[k] > 0.0)
        .map(|k| Spring {
            node: k as u32,
            target: x[k] + displacement[k],
            stiffness: stiffness_per_area * scale[k] * area[k] / 3.0,
        })
        .collect()
}

/// Per node, the area-weighted mean displacement its kept triangles found (from each
/// triangle's centre to its border point) and the area of those triangles (0, and no
/// displacement, where none was kept). The targets of the FEM levels' springs and of the
/// surface level.
pub(crate) fn node_displacements(
    probes: &[ProbeTriangle],
    borders: &[Option<(Border, f64)>],
    kept: &[bool],
    x: &[Point3<f64>],
) -> (Vec<Vector3<f64>>, Vec<f64>) {
    let n = x.len();
    let mut sum = vec![Vector3::zeros(); n];
    let mut area = vec![0.0f64; n];
    for ((tri, b), k) in probes.iter().zip(borders).zip(kept) {
        let (Some((bd, a)), true) = (b, *k) else {
            continue;
        };
        let [p, q, r] = tri.nodes.map(|i| x[i as usize]);
        let centre = (p.coords + q.coords + r.coords) / 3.0;
        let displacement = bd.point.coords - centre;
        for node in tri.nodes {
            sum[node as usize] += displacement * *a;
            area[node as usize] += *a;
        }
    }
    let mean = sum
        .iter()
        .zip(&area)
        .map(|(s, a)| if *a > 0.0 { s / *a } else { Vector3::zeros() })
        .collect();
    (mean, area)
}

/// The borders found from every triangle of `probes` (nodes at `x`) with the triangle's area.
pub(crate) fn probe_borders(
    probes: &[ProbeTriangle],
    x: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    cfg: &ProbeConfig,
) -> Vec<Option<(Border, f64)>> {
    probe_surface(probes, x, sampler, step, cfg)
        .into_iter()
        .map(|f| f.map(|p| (p.border, p.area)))
        .collect()
}

/// How many border points were kept, and their mean |offset| [mm] (0 when none was).
pub(crate) fn kept_offsets(borders: &[Option<(Border, f64)>], kept: &[bool]) -> (usize, f64) {
    let used = kept.iter().filter(|k| **k).count();
    let sum: f64 = borders
        .iter()
        .zip(kept)
        .filter_map(|(b, k)| b.filter(|_| *k).map(|(bd, _)| bd.offset_mm.abs()))
        .sum();
    (used, sum / used.max(1) as f64)
}
