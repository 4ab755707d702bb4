//! Multi-domain tetrahedral mesher over a [`LabelledDomain`]: a body-centred cubic lattice whose
//! tets are labelled by region, made manifold per region, and whose boundary nodes are snapped
//! onto the true interfaces under a dihedral-angle guard.
//!
//! Method, in the spirit of isosurface stuffing (Labelle & Shewchuk, SIGGRAPH 2007: BCC
//! lattice, warp boundary-near nodes onto the surface) and of multi-material lattice meshing
//! (Bronson, Levine & Whitaker, "Lattice cleaving", IMR 2012 / Cleaver). Unlike those we never
//! cut tets: every tet stays a (moved) lattice tet, so regions conform by construction (one
//! node set, shared interface faces) and quality is bounded by the guard instead of stencils.
//!
//! 1. [`lattice`]: BCC lattice over the padded domain bounds; grid spacing
//!    `h = target_edge / 0.911`, so the mean lattice edge equals the target edge length.
//! 2. `label`: each tet takes the label at its centroid; regions listed as thin win a tet if
//!    they own any of five sample points inside it.
//! 3. `repair`: tets are relabelled until every region's boundary is a 2-manifold; where
//!    groups of regions must stay apart ([`MesherParams::apart_groups`]), `separate` takes
//!    back the tets by which two of them share a node, and the repair runs again.
//! 4. `peel`: tets that would lie flat on the outer surface once snapped go to the outside
//!    (then `repair` runs again).
//! 5. `snap`: nodes on a region boundary move onto the interface (Newton projection on
//!    signed-distance differences), as far as keeping every dihedral angle ≥ the minimum and
//!    every edge ≥ 0.2 lattice spacings allows (a tiny tet among normal ones inverts under
//!    the smallest uneven motion).
//!
//! Measured (`examples/bench_mesher.rs`): 98–100 % of boundary nodes reach the interface, mean
//! offset < 0.001 mm; min dihedral ≥ the guard (10° by default), median of per-tet minimum 60°.
//!
//! Minimum feature size: a structure survives as a connected set of tets when it is at least
//! about `0.7 h` thick (centroid rule; thinner sheets get holes), or about `0.4 h` for a region
//! listed in [`MesherParams::thin_regions`] (measured on a tilted sheet; see the tests). For
//! the default edge length of 0.33 mm (`h` ≈ 0.36 mm) that is 0.25 mm, or 0.15 mm for thin
//! regions; stapes crura (~0.3 mm) and ligaments (0.3–0.5 mm) should be listed as thin (a thin
//! sheet is then one or two tets thick; mesh finer where bending through the thickness
//! matters).
//!
//! Deterministic: labels and interface targets are computed in parallel into index-ordered
//! vectors; repair and guarded moves run sequentially in node order.

mod cavity;
mod label;
pub mod lattice;
mod peel;
mod repair;
mod separate;
mod snap;
mod surface_domain;

pub use repair::RepairOutcome;
pub use snap::SnapOutcome;
pub use surface_domain::{SurfaceDomain, SurfaceDomainError};

use crate::mesh::{LabelledDomain, TetMesh};
use lattice::{Lattice, MEAN_EDGE_PER_SPACING, NodeTets};

/// Default target mean edge length (mm): the default atlas's, which
/// `atlas::volume::DEFAULT_EDGE_MM` takes from here (the reason for 0.33 mm is given there).
pub const DEFAULT_TARGET_EDGE_MM: f64 = 0.33;

/// Mesher settings.
#[derive(Debug, Clone, PartialEq)]
pub struct MesherParams {
    /// Target mean edge length (mm).
    pub target_edge_mm: f64,
    /// Snapping never makes a dihedral angle smaller than this (degrees; the lattice starts at
    /// 60°).
    pub min_dihedral_deg: f64,
    /// Guarded snapping sweeps over the boundary nodes.
    pub snap_sweeps: usize,
    /// Regions thinner than two lattice cells that must survive (see the module docs).
    pub thin_regions: Vec<u16>,
    /// Refuse lattices with more nodes than this (memory guard).
    pub max_lattice_nodes: usize,
    /// Unions of regions whose boundary must be a manifold too (the regions of one bone;
    /// all regions for the whole domain); repaired by adding to the union (see `repair`).
    pub manifold_groups: Vec<Vec<u16>>,
    /// Groups of regions that may share no node with one another (the regions of each bone:
    /// bones meet only through their joints); see `separate`.
    pub apart_groups: Vec<Vec<u16>>,
}

impl Default for MesherParams {
    fn default() -> Self {
        Self {
            target_edge_mm: DEFAULT_TARGET_EDGE_MM,
            min_dihedral_deg: 10.0,
            snap_sweeps: 4,
            thin_regions: Vec::new(),
            max_lattice_nodes: 20_000_000,
            manifold_groups: Vec::new(),
            apart_groups: Vec::new(),
        }
    }
}

/// What the mesher did, for logs and reports.
#[derive(Debug, Clone, PartialEq)]
pub struct MesherReport {
    /// BCC grid spacing (mm).
    pub spacing_mm: f64,
    pub lattice_tets: usize,
    pub repair: RepairOutcome,
    /// Tets handed to the outside because they would lie flat on the surface.
    pub peeled: usize,
    pub snap: SnapOutcome,
}

/// A mesh and the report of how it was made.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshOutput {
    pub mesh: TetMesh,
    pub report: MesherReport,
}

/// Why meshing failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MesherError {
    #[error("mesher parameter {name} = {value}: expected {expected}")]
    Parameter {
        name: &'static str,
        value: f64,
        expected: &'static str,
    },
    #[error("domain bounds {lo:?}..{hi:?} are not a finite box with positive extent")]
    Bounds { lo: [f64; 3], hi: [f64; 3] },
    #[error(
        "a lattice of edge {target_edge_mm} mm over the domain needs {nodes:.0} nodes, above the limit of {max}; use a larger target edge length"
    )]
    TooFine {
        target_edge_mm: f64,
        nodes: f64,
        max: usize,
    },
    #[error(
        "no lattice tet fell inside any region at edge {target_edge_mm} mm; is the domain empty or thinner than the lattice?"
    )]
    Empty { target_edge_mm: f64 },
}

fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), MesherError> {
    if ok {
        Ok(())
    } else {
        Err(MesherError::Parameter {
            name,
            value,
            expected,
        })
    }
}

/// Repairs the labels into manifold regions and groups and fills the small cavities, until
/// neither changes anything (at most a few rounds).
fn settle(
    lattice: &Lattice,
    adj: &NodeTets,
    labels: &mut [u16],
    params: &MesherParams,
) -> RepairOutcome {
    let (thin, groups) = (&params.thin_regions, &params.manifold_groups);
    let mut out = RepairOutcome::default();
    for _ in 0..4 {
        let r = repair::make_manifold(lattice, adj, labels, thin, groups, 50);
        out.relabelled += r.relabelled;
        out.sweeps += r.sweeps;
        out.defects_left = r.defects_left;
        let filled = cavity::fill_cavities(lattice, adj, labels);
        out.cavities_filled += filled;
        if filled == 0 {
            break;
        }
    }
    out
}

/// Keeps the apart groups apart (`separate`) on the settled labels, settling again after each
/// separation, until no node is shared (at most a few rounds); adds what it did to `repair`.
fn keep_apart(
    lattice: &Lattice,
    adj: &NodeTets,
    labels: &mut [u16],
    params: &MesherParams,
    repair: &mut RepairOutcome,
) {
    // fewer than two groups: nothing to keep apart, and no pass over the lattice
    if params.apart_groups.len() < 2 {
        return;
    }
    let n_nodes = lattice.nodes.len();
    for _ in 0..4 {
        let separated = separate::separate(adj, n_nodes, labels, &params.apart_groups);
        if separated == 0 {
            break;
        }
        repair.separated += separated;
        repair.absorb(settle(lattice, adj, labels, params));
    }
    repair.shared_nodes_left = separate::shared_nodes(adj, n_nodes, labels, &params.apart_groups);
}

/// Meshes every region of `domain` into one conforming, region-labelled tet mesh.
pub fn mesh_domain<D: LabelledDomain + ?Sized>(
    domain: &D,
    params: &MesherParams,
) -> Result<MeshOutput, MesherError> {
    let edge = params.target_edge_mm;
    check(
        "target_edge_mm",
        edge,
        edge.is_finite() && edge > 0.0,
        "a positive length in mm",
    )?;
    let angle = params.min_dihedral_deg;
    check(
        "min_dihedral_deg",
        angle,
        (0.0..60.0).contains(&angle),
        "an angle in [0, 60) degrees",
    )?;
    let (lo, hi) = domain.bounds();
    if !(0..3).all(|a| lo[a].is_finite() && hi[a].is_finite() && hi[a] > lo[a]) {
        return Err(MesherError::Bounds {
            lo: [lo.x, lo.y, lo.z],
            hi: [hi.x, hi.y, hi.z],
        });
    }
    let h = edge / MEAN_EDGE_PER_SPACING;
    // Two cells of padding: every tet touching the outer shell lies outside the bounds.
    let pad = 2;
    let nodes = Lattice::node_count(&lo, &hi, h, pad);
    if nodes > params.max_lattice_nodes as f64 {
        return Err(MesherError::TooFine {
            target_edge_mm: edge,
            nodes,
            max: params.max_lattice_nodes,
        });
    }
    let lattice = Lattice::new(&lo, &hi, h, pad);
    let mut labels = label::label_tets(domain, &lattice, &params.thin_regions);
    let adj = NodeTets::new(lattice.nodes.len(), &lattice.tets);
    let thin = &params.thin_regions;
    let mut repair = settle(&lattice, &adj, &mut labels, params);
    let mut targets = snap::interface_targets(domain, &lattice.nodes, &labels, &adj, h);
    let peeled = peel::peel_flat_caps(
        &lattice.nodes,
        &lattice.tets,
        &mut labels,
        &adj,
        &targets,
        params.min_dihedral_deg,
        thin,
    );
    if peeled > 0 {
        repair.absorb(settle(&lattice, &adj, &mut labels, params));
        targets = snap::interface_targets(domain, &lattice.nodes, &labels, &adj, h);
    }
    // after the peel, which only takes tets away, so that a mesh with no shared node is the
    // one it would be without the groups
    keep_apart(&lattice, &adj, &mut labels, params, &mut repair);
    if repair.separated > 0 {
        targets = snap::interface_targets(domain, &lattice.nodes, &labels, &adj, h);
    }
    let mut positions = lattice.nodes.clone();
    let snap = snap::snap_to_interfaces(
        &mut positions,
        &lattice.tets,
        &labels,
        &adj,
        &targets,
        h,
        params,
    );

    // Keep the labelled tets; renumber their nodes in lattice order.
    let mut new_index = vec![u32::MAX; positions.len()];
    for (t, tet) in lattice.tets.iter().enumerate() {
        if labels[t] != 0 {
            for &v in tet {
                new_index[v as usize] = 0;
            }
        }
    }
    let mut mesh = TetMesh::default();
    for (v, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = mesh.nodes.len() as u32;
            mesh.nodes.push(positions[v]);
        }
    }
    for (t, tet) in lattice.tets.iter().enumerate() {
        if labels[t] != 0 {
            mesh.tets.push(tet.map(|v| new_index[v as usize]));
            mesh.regions.push(labels[t]);
        }
    }
    if mesh.tets.is_empty() {
        return Err(MesherError::Empty {
            target_edge_mm: edge,
        });
    }
    Ok(MeshOutput {
        mesh,
        report: MesherReport {
            spacing_mm: h,
            lattice_tets: lattice.tets.len(),
            repair,
            peeled,
            snap,
        },
    })
}

#[cfg(test)]
pub(crate) mod tests;
