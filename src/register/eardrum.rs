//! The eardrum after the ossicles: its membrane has no bending stiffness, so during
//! registration it is not part of the FEM (a sheet in compression has no equilibrium, it
//! wrinkles). Instead its free nodes follow the registered manubrium smoothly — the
//! displacement of the nodes it shares with the manubrium, spread over the membrane by a
//! discrete Laplace equation with the rim held where the rigid fit put it — and then, where the
//! image shows the sheet, each node moves along its normal to the intensity ridge, the offsets
//! screened against their neighbours and smoothed over the membrane.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::deform::{DeformConfig, ProbeKind, probe};
use crate::atlas::{Atlas, Part};
use crate::image::Sampler;

/// Gauss-Seidel sweeps of the Laplace interpolation and of the offset smoothing.
const LAPLACE_SWEEPS: usize = 200;
const SMOOTHING_SWEEPS: usize = 3;
/// Probe-and-move rounds on the image.
const ROUNDS: usize = 3;

/// What the eardrum fit did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EardrumFit {
    /// Membrane nodes that belong to no tetrahedron (moved here).
    pub free_nodes: usize,
    /// Of those, nodes whose probe found the sheet in the last round (after screening).
    pub found_last_round: usize,
    /// Mean |offset| to the sheet in the last round [mm].
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
    let free_neighbours: Vec<Vec<u32>> = free
        .iter()
        .map(|&v| {
            let nb = neighbours[v].iter().copied();
            nb.filter(|&w| !in_tet[w as usize]).collect()
        })
        .collect();
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
        let mut smooth: Vec<f64> = vec![0.0; n];
        let mut known = vec![false; n];
        for (&v, k) in free.iter().zip(&kept) {
            if let Some(o) = k {
                smooth[v] = *o;
                known[v] = true;
            }
        }
        fit.found_last_round = known.iter().filter(|k| **k).count();
        fit.mean_offset_mm = free
            .iter()
            .filter(|&&v| known[v])
            .map(|&v| smooth[v].abs())
            .sum::<f64>()
            / fit.found_last_round.max(1) as f64;
        // smooth: average each free node with its free neighbours (unknown ones count 0)
        for _ in 0..SMOOTHING_SWEEPS {
            let previous = smooth.clone();
            for (&v, nb) in free.iter().zip(&free_neighbours) {
                let own = if known[v] { previous[v] } else { 0.0 };
                smooth[v] = (own + nb.iter().map(|&w| previous[w as usize]).sum::<f64>())
                    / (1 + nb.len()) as f64;
            }
        }
        for &v in &free {
            x[v] += normals[v] * smooth[v];
        }
    }
    fit
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
