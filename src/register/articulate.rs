//! Each ossicle's own pose, fitted to the image before the FEM: people differ most in how
//! their chain is articulated (the malleus turned on the incus, the stapes on the lenticular
//! process), which one similarity of the whole atlas cannot follow and an elastic FEM only
//! follows by bending bone.
//!
//! Method: a rigid motion per ossicle (rotation about its centroid, translation), fitted by
//! Gauss-Newton to point-to-plane residuals: each outer surface triangle of the ossicle probes
//! the image along its normal for its bone edge (the deformable stage's probe and screening),
//! and its centre should move by the offset found, along the normal. The ossicles stay
//! articulated: the joint points (the IMJ landmark for malleus and incus, the ISJ landmark for
//! incus and stapes) are tied between the two bones by a weighted residual, and a small
//! Levenberg damping keeps each step within what one probe round can see. Residuals are
//! weighted by triangle area and a Cauchy weight of the offset, so a wrong border found on a
//! wall moves little.
//!
//! The atlas is then carried to those poses through its own FEM: each bone node is pulled to
//! where its ossicle's motion puts it by a stiff spring, the joints, ligaments and tendons
//! follow elastically, and no element is ever inverted. That shape is the FEM's rest shape for
//! the deformable stage, so the FEM regularises the bones' shape, not their articulation.

use nalgebra::{DMatrix, DVector, Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

use super::deform::{
    DeformConfig, ProbeConfig, ProbeTriangle, probe_surface, screen, triangle_neighbours,
};
use super::probes::probe_triangles_by_part;
use super::stapes_turn::{self, StapesTurn};
use crate::atlas::{Atlas, Part};
use crate::ear::LandmarkName;
use crate::fem::{
    FactorPrecision, FemError, FemModel, FixedDofs, Spring, StaticOptions, StaticSolver,
};
use crate::image::Sampler;

/// Stiffness of the springs carrying the bones to their poses, per Pa of the registration
/// modulus [mm]: a hundred times a bone element's of 1 mm.
const TARGET_STIFFNESS_MM: f64 = 100.0;
/// Cauchy scale of the offsets [mm]: an offset of this size weighs half.
const CAUCHY_MM: f64 = 0.3;
/// Index of the stapes in `Part::BONES`.
const STAPES: usize = 2;
/// Lever arm at which the prior weighs a rotation like a translation [mm] (half an ossicle).
const PRIOR_ARM_MM: f64 = 2.0;

/// Knobs of the articulation stage (`[articulate]` in pipeline.toml).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArticulateConfig {
    /// Fit each ossicle's pose before the FEM [true/false].
    pub enabled: bool,
    /// Probe-and-fit rounds \[count\].
    pub iterations: usize,
    /// Weight of a joint tie per mm of separation against the surface residuals, as a
    /// fraction of the ossicles' total probed area [1/mm²].
    pub joint_weight: f64,
    /// Levenberg damping of each step, as a fraction of the ossicle's probed area \[unitless\].
    pub damping: f64,
    /// Weight of the whole motion of each ossicle from its landmark placement (a rotation
    /// counted at a 2 mm lever arm), as a fraction of the ossicle's probed area [1/mm²].
    pub prior: f64,
    /// Stop when no surface point moved more than this in a round \[mm\].
    pub tolerance_mm: f64,
    /// How far each triangle looks for its bone edge on either side \[mm\]: longer than the
    /// deformable stage's, since a whole bone's pose averages out the wrong finds.
    pub search_range_mm: f64,
    /// Largest tilt of the stapes about its head searched before the fit (`stapes_turn`)
    /// \[deg\]; 0 starts from the landmark placement's direction.
    pub stapes_turn_max_deg: f64,
}

/// One ossicle's motion from the landmark placement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OssiclePose {
    pub part: Part,
    pub rotation_deg: f64,
    pub translation_mm: f64,
}

/// What the stage did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Articulation {
    pub rounds: usize,
    /// Mean |offset| of the kept border points in the first and in the last round \[mm\].
    pub mean_offset_first_mm: f64,
    pub mean_offset_last_mm: f64,
    pub poses: Vec<OssiclePose>,
    /// Largest separation of a joint's two ends at the end \[mm\].
    pub joint_gap_mm: f64,
    /// Largest distance of a bone node from its target once the FEM carried the atlas there
    /// (where the bones touch, the atlas cannot follow the motions exactly) \[mm\].
    pub target_gap_mm: f64,
    /// The stapes's turn about its head searched before the fit (absent when not searched).
    pub stapes_turn: Option<StapesTurn>,
    /// Why the atlas was carried only part of the way to the poses (all the way would have
    /// left an element below the registration's floors, `mesh::quality`), and how far.
    /// Absent when it was carried all the way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shortened: Option<String>,
}

/// A rigid motion about a pivot: x ↦ R (x − pivot) + pivot + t.
#[derive(Debug, Clone, Copy)]
struct Motion {
    rotation: Rotation3<f64>,
    translation: Vector3<f64>,
    pivot: Point3<f64>,
}

impl Motion {
    fn apply(&self, p: &Point3<f64>) -> Point3<f64> {
        self.pivot + self.rotation * (p - self.pivot) + self.translation
    }
}

/// Fits each ossicle's pose from `placed`; returns where each node of exactly one bone goes
/// (`None` for the others) with the stage's record.
pub fn articulate(
    atlas: &Atlas,
    placed: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    deform: &DeformConfig,
    cfg: &ArticulateConfig,
) -> (Vec<Option<Point3<f64>>>, Articulation) {
    let n = placed.len();
    let probes: Vec<(usize, ProbeTriangle)> = probe_triangles_by_part(atlas)
        .into_iter()
        .filter_map(|(part, t)| Part::BONES.iter().position(|b| *b == part).map(|k| (k, t)))
        .collect();
    let triangles: Vec<ProbeTriangle> = probes.iter().map(|(_, t)| *t).collect();
    let neighbours = triangle_neighbours(&triangles, n);
    // the bone each node moves with
    // (a node of two bones, where the atlas's bones touch, belongs to neither: it follows
    // like the connective tissue)
    let mut owners: Vec<u8> = vec![0; n];
    for (k, part) in Part::BONES.iter().enumerate() {
        let labels = atlas.labels_of(*part);
        for (t, r) in atlas.mesh.tets.tets.iter().zip(&atlas.mesh.tets.regions) {
            if labels.contains(r) {
                t.iter().for_each(|&v| owners[v as usize] |= 1 << k);
            }
        }
    }
    let owner: Vec<Option<usize>> = owners
        .iter()
        .map(|&m| (m.count_ones() == 1).then(|| m.trailing_zeros() as usize))
        .collect();
    let pivots: Vec<Point3<f64>> = (0..3)
        .map(|k| {
            let pts: Vec<&Point3<f64>> = (0..n)
                .filter(|&v| owner[v] == Some(k))
                .map(|v| &placed[v])
                .collect();
            let c = pts.iter().fold(Vector3::zeros(), |s, p| s + p.coords);
            Point3::from(c / pts.len().max(1) as f64)
        })
        .collect();
    let landmarks = atlas.landmark_positions(placed);
    // (bone a, bone b, joint point)
    let joints = [
        (0usize, 1usize, landmarks.get(LandmarkName::Incudomalleolar)),
        (1, 2, landmarks.get(LandmarkName::Incudostapedial)),
    ];
    let mut motions: Vec<Motion> = pivots
        .iter()
        .map(|p| Motion {
            rotation: Rotation3::identity(),
            translation: Vector3::zeros(),
            pivot: *p,
        })
        .collect();
    // the stapes's direction is the atlas's (only its head is a landmark): search it widely
    let stapes_turn = (cfg.stapes_turn_max_deg > 0.0).then(|| {
        let stapes: Vec<ProbeTriangle> = probes
            .iter()
            .filter(|(k, _)| *k == STAPES)
            .map(|(_, t)| *t)
            .collect();
        let head = landmarks.get(LandmarkName::Incudostapedial);
        let (turn, shift, record) =
            stapes_turn::search(&stapes, placed, &head, sampler, cfg.stapes_turn_max_deg);
        // a turn about the head: x ↦ R (x − c) + c + (R − I)(c − head), c the pivot
        let m = &mut motions[STAPES];
        let lever = m.pivot - head;
        m.rotation = turn;
        m.translation = turn * lever - lever + shift;
        record
    });
    // the prior holds each bone near where the search left it
    let start = motions.clone();
    let probe_cfg = ProbeConfig {
        search_range_mm: cfg.search_range_mm,
        ..deform.probe.clone()
    };
    let mut bone_area = [0.0f64; 3];
    for (k, t) in &probes {
        let [a, b, c] = t.nodes.map(|v| placed[v as usize]);
        bone_area[*k] += 0.5 * (b - a).cross(&(c - a)).norm();
    }
    let total_area: f64 = bone_area.iter().sum();
    let (mut first, mut last, mut rounds) = (f64::NAN, f64::NAN, 0);
    for _ in 0..cfg.iterations {
        rounds += 1;
        let x: Vec<Point3<f64>> = (0..n)
            .map(|v| owner[v].map_or(placed[v], |k| motions[k].apply(&placed[v])))
            .collect();
        let found = probe_surface(&triangles, &x, sampler, step, &probe_cfg);
        let borders: Vec<_> = found
            .iter()
            .map(|f| f.map(|p| (p.border, p.area)))
            .collect();
        let kept = screen(&borders, &neighbours, deform.neighbour_tolerance_mm);
        // normal equations of the 18 unknowns (ω, v per bone)
        let mut h = DMatrix::<f64>::zeros(18, 18);
        let mut g = DVector::<f64>::zeros(18);
        let (mut sum_offset, mut used) = (0.0, 0usize);
        for ((bone, _), (f, k)) in probes.iter().zip(found.iter().zip(&kept)) {
            let (Some(p), true) = (f, *k) else {
                continue;
            };
            let (o, area, centre, normal) = (p.border.offset_mm, p.area, p.centre, p.normal);
            sum_offset += o.abs();
            used += 1;
            let w = area / (1.0 + (o / CAUCHY_MM).powi(2));
            // d(n·Δ)/dω = (r × n), d/dv = n, with r from the bone's current pivot
            let r = centre - (motions[*bone].pivot + motions[*bone].translation);
            let mut j = [0.0; 6];
            let rn = r.cross(&normal);
            j[..3].copy_from_slice(rn.as_slice());
            j[3..].copy_from_slice(normal.as_slice());
            let base = 6 * bone;
            for a in 0..6 {
                g[base + a] += w * j[a] * o;
                for b in 0..6 {
                    h[(base + a, base + b)] += w * j[a] * j[b];
                }
            }
        }
        if used == 0 {
            break;
        }
        let mean = sum_offset / used as f64;
        if first.is_nan() {
            first = mean;
        }
        last = mean;
        // joint ties: the joint point carried by bone a and by bone b should coincide
        let lambda = cfg.joint_weight * total_area;
        for (a, b, j) in joints {
            let pa = motions[a].apply(&j);
            let pb = motions[b].apply(&j);
            let gap = pa - pb;
            let ra = pa - (motions[a].pivot + motions[a].translation);
            let rb = pb - (motions[b].pivot + motions[b].translation);
            for axis in 0..3 {
                let e = Vector3::ith(axis, 1.0);
                // d(gap·e) = (ω_a × r_a + v_a − ω_b × r_b − v_b)·e
                let mut jac = [0.0; 12];
                jac[..3].copy_from_slice(ra.cross(&e).as_slice());
                jac[3..6].copy_from_slice(e.as_slice());
                let nb = -rb.cross(&e);
                jac[6..9].copy_from_slice(nb.as_slice());
                jac[9..].copy_from_slice((-e).as_slice());
                let idx = |q: usize| if q < 6 { 6 * a + q } else { 6 * b + q - 6 };
                for p in 0..12 {
                    g[idx(p)] -= lambda * jac[p] * gap[axis];
                    for q in 0..12 {
                        h[(idx(p), idx(q))] += lambda * jac[p] * jac[q];
                    }
                }
            }
        }
        // Levenberg damping of the step, and a prior on the whole motion (rotations weighed
        // at the lever arm PRIOR_ARM_MM) that holds the directions the borders leave free
        for (k, (m, s)) in motions.iter().zip(&start).enumerate() {
            let (mu, prior) = (cfg.damping * bone_area[k], cfg.prior * bone_area[k]);
            let theta = (m.rotation * s.rotation.inverse()).scaled_axis();
            let shift = m.translation - s.translation;
            let arm2 = PRIOR_ARM_MM * PRIOR_ARM_MM;
            for a in 0..3 {
                let (r, t) = (6 * k + a, 6 * k + 3 + a);
                h[(r, r)] += mu + prior * arm2;
                g[r] -= prior * arm2 * theta[a];
                h[(t, t)] += mu + prior;
                g[t] -= prior * shift[a];
            }
        }
        let Some(delta) = h.cholesky().map(|c| c.solve(&g)) else {
            break;
        };
        let mut moved: f64 = 0.0;
        for (k, m) in motions.iter_mut().enumerate() {
            let omega = Vector3::new(delta[6 * k], delta[6 * k + 1], delta[6 * k + 2]);
            let v = Vector3::new(delta[6 * k + 3], delta[6 * k + 4], delta[6 * k + 5]);
            // x ↦ dR (x − c) + c + v with c the pivot's current place, after the current
            // motion: the rotation composes, the translation adds
            m.rotation = Rotation3::new(omega) * m.rotation;
            m.translation += v;
            // the largest displacement of a node of this bone within 5 mm of its centre
            moved = moved.max(v.norm() + omega.norm() * 5.0);
        }
        if moved < cfg.tolerance_mm {
            break;
        }
    }
    let targets: Vec<Option<Point3<f64>>> = (0..n)
        .map(|v| owner[v].map(|k| motions[k].apply(&placed[v])))
        .collect();
    let joint_gap_mm = joints
        .iter()
        .map(|(a, b, j)| (motions[*a].apply(j) - motions[*b].apply(j)).norm())
        .fold(0.0, f64::max);
    let poses = Part::BONES
        .iter()
        .zip(&motions)
        .map(|(part, m)| OssiclePose {
            part: *part,
            rotation_deg: m.rotation.angle().to_degrees(),
            translation_mm: m.translation.norm(),
        })
        .collect();
    let record = Articulation {
        rounds,
        mean_offset_first_mm: first,
        mean_offset_last_mm: last,
        poses,
        joint_gap_mm,
        target_gap_mm: 0.0,
        stapes_turn,
        shortened: None,
    };
    (targets, record)
}

/// The atlas carried to the ossicles' poses through its own FEM (`model`, at rest in the
/// placed atlas): every bone node pulled to its target by a stiff spring, the connective
/// tissue following elastically, and no element ever inverted (where a joint would be crushed
/// the solver stops at the last admissible state). Records the largest gap left to a target.
///
/// The solve ends once the residual is a thousandth of its first (parts that no spring holds
/// would otherwise drift by 0.05-0.1 mm per iteration at a residual 1e-5 of the first, until
/// the iteration limit), or when the residual falls by less than 5 % in an iteration (a joint
/// the targets would crush halves every step). On the
/// development phantoms this takes the carry from 8 factorisations to 1-5, 0.15 s to
/// 0.02-0.08 s, and moves no chain MASD by more than 0.001 mm.
pub fn articulated_shape(
    model: &FemModel,
    targets: &[Option<Point3<f64>>],
    modulus_pa: f64,
    record: &mut Articulation,
) -> Result<Vec<Point3<f64>>, FemError> {
    let mut x = model.rest_positions().to_vec();
    let mut solver = StaticSolver::new(model, FixedDofs::from_nodes(x.len(), &[])?)?;
    let springs: Vec<Spring> = targets
        .iter()
        .enumerate()
        .filter_map(|(k, t)| {
            t.map(|target| Spring {
                node: k as u32,
                target,
                stiffness: TARGET_STIFFNESS_MM * modulus_pa,
            })
        })
        .collect();
    let options = StaticOptions {
        tolerance_mm: 1e-3,
        max_iterations: 8,
        max_halvings: 12,
        tangent_shift: 1e-6 * modulus_pa,
        balanced_below: 1e-3,
        stalled_below: 0.05,
        // as the deformable stage's FEM levels (docs/fem.md, "A single-precision tangent")
        tangent_precision: FactorPrecision::Single,
        ..StaticOptions::default()
    };
    match solver.solve_with_springs(&mut x, &springs, &options) {
        Ok(_) | Err(FemError::NotConverged { .. }) | Err(FemError::StepRejected { .. }) => {}
        Err(e) => return Err(e),
    }
    record.target_gap_mm = springs
        .iter()
        .map(|s| (x[s.node as usize] - s.target).norm())
        .fold(0.0, f64::max);
    Ok(x)
}
