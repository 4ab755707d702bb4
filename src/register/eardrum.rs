//! The eardrum after the ossicles: it is not part of the registration's FEM (a thin sheet,
//! whose out-of-plane stiffness is mostly its tension, wrinkles in compression). Instead its
//! free nodes follow the registered manubrium smoothly — the
//! displacement of the nodes it shares with the manubrium, spread over the membrane by a
//! discrete Laplace equation with the rim held where the rigid fit put it — and then, where the
//! image shows the sheet, each node moves along its normal to the intensity ridge, the offsets
//! screened against their neighbours and smoothed over the membrane.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::deform::{DeformConfig, ProbeKind, probe};
use crate::atlas::{Atlas, Part};
use crate::image::Sampler;

/// Gauss-Seidel sweeps of the Laplace interpolation and of the offset smoothing.
const LAPLACE_SWEEPS: usize = 200;
const SMOOTHING_SWEEPS: usize = 600;
/// Probe-and-move rounds on the image.
const ROUNDS: usize = 3;

/// What the eardrum fit did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EardrumFit {
    /// Membrane nodes that belong to no tetrahedron (moved here).
    pub free_nodes: usize,
    /// Of those, nodes whose probe found the sheet in the last round (after screening).
    pub found_last_round: usize,
    /// Mean |offset| to the sheet in the last round \[mm\].
    pub mean_offset_mm: f64,
}

/// Moves the eardrum's free nodes in `x` (all atlas nodes; the tetrahedra's nodes already
/// registered), from `placed` (the rigidly placed atlas).
pub fn fit_eardrum(
    atlas: &Atlas,
    placed: &[Point3<f64>],
    x: &mut [Point3<f64>],
    sampler: &Sampler,
    step: f64,
    cfg: &DeformConfig,
) -> EardrumFit {
    let (probe_cfg, neighbour_tolerance_mm) = (&cfg.probe, cfg.neighbour_tolerance_mm);
    let triangles = atlas.part_triangles(Part::Eardrum);
    let n = x.len();
    let mut in_tet = vec![false; n];
    for t in &atlas.mesh.tets.tets {
        t.iter().for_each(|&v| in_tet[v as usize] = true);
    }
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    neighbours.iter_mut().for_each(|l| {
        l.sort_unstable();
        l.dedup();
    });
    let rim: std::collections::HashSet<u32> = atlas
        .node_sets
        .get(crate::atlas::model::sets::TYMPANIC_ANNULUS)
        .map(|s| s.iter().copied().collect())
        .unwrap_or_default();
    let free: Vec<usize> = (0..n)
        .filter(|&v| !neighbours[v].is_empty() && !in_tet[v])
        .collect();
    // follow the manubrium: harmonic displacement, attachment and rim prescribed
    let mut u: Vec<Vector3<f64>> = (0..n).map(|v| x[v] - placed[v]).collect();
    let interior: Vec<usize> = free
        .iter()
        .copied()
        .filter(|v| !rim.contains(&(*v as u32)))
        .collect();
    interior.iter().for_each(|&v| u[v] = Vector3::zeros());
    for _ in 0..LAPLACE_SWEEPS {
        for &v in &interior {
            let nb = &neighbours[v];
            u[v] = nb.iter().map(|&w| u[w as usize]).sum::<Vector3<f64>>() / nb.len() as f64;
        }
    }
    free.iter().for_each(|&v| x[v] = placed[v] + u[v]);
    let mut fit = EardrumFit {
        free_nodes: free.len(),
        found_last_round: 0,
        mean_offset_mm: 0.0,
    };
    if !cfg.probe_eardrum {
        return fit;
    }
    for _ in 0..ROUNDS {
        let normals = node_normals(&triangles, x);
        let found: Vec<Option<f64>> = free
            .par_iter()
            .map(|&v| {
                probe(
                    sampler,
                    &x[v],
                    &normals[v],
                    ProbeKind::Sheet,
                    step,
                    probe_cfg,
                )
                .map(|b| b.offset_mm)
            })
            .collect();
        let mut offset: Vec<Option<f64>> = vec![None; n];
        free.iter().zip(&found).for_each(|(&v, o)| offset[v] = *o);
        // screen against the neighbours' median
        let kept: Vec<Option<f64>> = free
            .iter()
            .map(|&v| {
                let o = offset[v]?;
                let mut around: Vec<f64> = neighbours[v]
                    .iter()
                    .filter_map(|&w| offset[w as usize])
                    .collect();
                if around.is_empty() {
                    return Some(o);
                }
                around.sort_by(f64::total_cmp);
                let median = around[around.len() / 2];
                ((o - median).abs() <= neighbour_tolerance_mm).then_some(o)
            })
            .collect();
        let mut target: Vec<Option<f64>> = vec![None; n];
        free.iter().zip(&kept).for_each(|(&v, k)| target[v] = *k);
        fit.found_last_round = kept.iter().flatten().count();
        fit.mean_offset_mm = kept.iter().flatten().map(|o| o.abs()).sum::<f64>()
            / fit.found_last_round.max(1) as f64;
        let smooth = smooth_offsets(
            &free,
            &neighbours,
            &in_tet,
            &target,
            cfg.eardrum_offset_weight,
        );
        for &v in &free {
            x[v] += normals[v] * smooth[v];
        }
    }
    fit
}

/// The offsets to apply: the smooth field s minimising
/// Σ_found weight (s_v − o_v)² + Σ_edges (s_v − s_w)² over the free nodes, with
/// s = 0 on the nodes the tetrahedra hold (the manubrium attachment). Node-to-node noise of
/// the probes is damped about 1 + 2·degree/weight times (`eardrum_offset_weight`) while the sheet's broad shape passes:
/// a rough registered eardrum has facets that move with little stretching, so it goes slack
/// and its mechanics leave the atlas's (docs/mechanics.md, "Packages: the registered eardrum
/// must stay smooth"). Gauss-Seidel sweeps.
fn smooth_offsets(
    free: &[usize],
    neighbours: &[Vec<u32>],
    in_tet: &[bool],
    target: &[Option<f64>],
    weight: f64,
) -> Vec<f64> {
    let mut s: Vec<f64> = target.iter().map(|o| o.unwrap_or(0.0)).collect();
    for _ in 0..SMOOTHING_SWEEPS {
        for &v in free {
            let (mut sum, mut weight) = match target[v] {
                Some(o) => (weight * o, weight),
                None => (0.0, 0.0),
            };
            for &w in &neighbours[v] {
                // the attachment's nodes have moved with the manubrium already: offset 0
                sum += if in_tet[w as usize] {
                    0.0
                } else {
                    s[w as usize]
                };
                weight += 1.0;
            }
            if weight > 0.0 {
                s[v] = sum / weight;
            }
        }
    }
    s
}

/// Area-weighted unit normals at the nodes of `triangles`.
fn node_normals(triangles: &[[u32; 3]], x: &[Point3<f64>]) -> Vec<Vector3<f64>> {
    let mut normals = vec![Vector3::zeros(); x.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| x[v as usize]);
        let n = (b - a).cross(&(c - a));
        t.iter().for_each(|&v| normals[v as usize] += n);
    }
    normals
        .into_iter()
        .map(|n| n.try_normalize(1e-12).unwrap_or_else(Vector3::zeros))
        .collect()
}
