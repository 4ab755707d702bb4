//! The package's SOFA scene (`scene.scn`, SOFA v23.12 to v24.12: `sofa::SOFA_VERSIONS`): it loads `mesh.msh` beside
//! it with MeshGmshLoader and simulates the registered atlas as otoatlas's own mechanics does
//! (`mechanics::MechanicalSystem`: the same lumped masses, fixed nodes, annular-ligament
//! springs, cochlear dashpots and Rayleigh damping; the eardrum's bending as linear bending
//! springs about the rest shape, `scene_bending`).
//!
//! What it relies on in SOFA (checked in the sofa-framework/sofa sources of v23.06–v24.12;
//! docs/package-format.md, "The SOFA scene"): per-element `youngModulus` vectors are written
//! full length in topology order (valid in every version); TriangularFEMForceField has no
//! thickness, so membranes get E·h; DiagonalMass takes one `vertexMass` per point, computed
//! here as Σ ρV/4 + Σ ρhA/3; `FixedConstraint` is the v23 name of FixedProjectiveConstraint;
//! MeshGmshLoader gets `createSubelements="false"` (it defaults to true for Gmsh files and
//! would add every tetrahedron face to the loader's triangles: MeshGmshLoader.cpp,
//! MeshLoader.cpp in sofa-framework/sofa); the child node "Eardrum" has a triangle topology
//! and no MechanicalObject, so its force fields act on the parent's DOFs. Units mm-g-s: force
//! µN, modulus and pressure Pa, mass g, stiffness µN/mm, damping g/s.

use std::fmt::Write as _;

use nalgebra::Point3;

use super::ExportError;
use super::scene_bending::{self, BendingLayer};
use super::sofa::{SOFA_VERSIONS, plugins_for};
use crate::atlas::Atlas;
use crate::atlas::export::material_arrays;
use crate::mechanics::MechanicalSystem;

/// The file name of the scene in a package.
pub const SCENE: &str = "scene.scn";
/// The mesh the scene loads (Gmsh MSH 2.2, beside the scene).
pub const SCENE_MESH: &str = "mesh.msh";
/// Time step \[s\]: 100 kHz, ten steps per period at the top of the 250–8000 Hz band.
pub const DT_S: f64 = 1e-5;

/// Numbers as Rust prints them for round-trip (shortest exact form), space separated.
fn join(values: impl IntoIterator<Item = f64>) -> String {
    let mut s = String::new();
    for (k, v) in values.into_iter().enumerate() {
        if k > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{v:?}");
    }
    s
}

fn join_indices(values: impl IntoIterator<Item = u32>) -> String {
    values
        .into_iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(" ")
}

/// The per-element material vectors of the scene, in topology order.
struct ElementMaterials {
    /// Young's modulus per tetrahedron [Pa].
    tet_modulus: Vec<f64>,
    /// The one Poisson's ratio of every tetrahedron (SOFA ≤ v24.06 takes a scalar).
    tet_poisson: f64,
    /// E·h per membrane triangle [Pa·mm].
    tri_modulus_thickness: Vec<f64>,
    /// Poisson's ratio per membrane triangle.
    tri_poisson: Vec<f64>,
}

/// The atlas's material per cell (tetrahedra, then triangles), as `material_arrays` gives it
/// (SI; NaN for a cell without a known material): E [Pa], density [kg/m³], ν, thickness [mm].
pub(super) struct CellMaterials {
    pub modulus: Vec<f64>,
    pub density: Vec<f64>,
    pub poisson: Vec<f64>,
    pub thickness: Vec<f64>,
}

impl CellMaterials {
    pub(super) fn of(atlas: &Atlas) -> CellMaterials {
        let mut arrays = material_arrays(atlas);
        let mut take = |name: &str| {
            arrays
                .iter_mut()
                .find(|a| a.name == name)
                .map(|a| std::mem::take(&mut a.values))
                .unwrap_or_default()
        };
        CellMaterials {
            modulus: take("youngs_modulus_pa"),
            density: take("density_kg_m3"),
            poisson: take("poisson_ratio"),
            thickness: take("thickness_mm"),
        }
    }
}

fn element_materials(atlas: &Atlas) -> Result<ElementMaterials, ExportError> {
    let cells = CellMaterials::of(atlas);
    let (e, nu, h) = (&cells.modulus, &cells.poisson, &cells.thickness);
    let n_tets = atlas.mesh.tets.tets.len();
    let n_cells = n_tets + atlas.mesh.triangles.len();
    if [e, nu, h].iter().any(|c| c.len() != n_cells)
        || e.iter().chain(nu).chain(h).any(|v| !v.is_finite())
    {
        return Err(ExportError::Materials {
            atlas: atlas.name.clone(),
            message: "a cell without a known region or material; the scene needs one material \
                      per element"
                .into(),
        });
    }
    let tet_poisson = nu.first().copied().unwrap_or(0.3);
    if let Some(other) = nu[..n_tets].iter().find(|&&v| v != tet_poisson) {
        return Err(ExportError::Materials {
            atlas: atlas.name.clone(),
            message: format!(
                "the tetrahedra have Poisson's ratios {tet_poisson} and {other}; SOFA's \
                 TetrahedronFEMForceField takes one ratio before v24.12"
            ),
        });
    }
    Ok(ElementMaterials {
        tet_modulus: e[..n_tets].to_vec(),
        tet_poisson,
        tri_modulus_thickness: (n_tets..n_cells).map(|c| e[c] * h[c]).collect(),
        tri_poisson: nu[n_tets..].to_vec(),
    })
}

/// The scene for `atlas` with its nodes at `nodes` (the registered positions).
pub fn scene_string(atlas: &Atlas, nodes: &[Point3<f64>]) -> Result<String, ExportError> {
    let system = MechanicalSystem::new(atlas, nodes)?;
    let materials = element_materials(atlas)?;
    let n = nodes.len();
    let fixed: Vec<u32> = (0..n as u32)
        .filter(|&v| system.fixed.is_fixed(3 * v as usize))
        .collect();
    let springs: Vec<(u32, f64)> = (0..n as u32)
        .zip(&system.node_stiffness)
        .filter(|(_, k)| **k > 0.0)
        .map(|(v, k)| (v, *k))
        .collect();
    let membranes = !atlas.mesh.triangles.is_empty();
    let bending = scene_bending::layers(&atlas.membrane_flexural_rigidity());

    let mut used = vec![
        "DefaultAnimationLoop",
        "MeshGmshLoader",
        "EulerImplicitSolver",
        "SparseLDLSolver",
        "MechanicalObject",
        "TetrahedronSetTopologyContainer",
        "DiagonalMass",
        "TetrahedronFEMForceField",
        "FixedConstraint",
        "RestShapeSpringsForceField",
        "DiagonalVelocityDampingForceField",
    ];
    if membranes {
        used.extend([
            "TriangleSetTopologyContainer",
            "TriangularFEMForceField",
            "SurfacePressureForceField",
        ]);
    }
    if !bending.is_empty() {
        used.extend(["FastTriangularBendingSprings", "ConstantForceField"]);
    }
    let mut s = String::from("<?xml version=\"1.0\"?>\n");
    let _ = write!(
        s,
        "<!-- otoatlas patient package: SOFA scene for {SOFA_VERSIONS} (runSofa scene.scn) -->\n\
         <!-- units mm, g, s: force uN, Young's modulus and pressure Pa, mass g, spring \
         stiffness uN/mm, damping g/s; positions in DICOM patient space (LPS) -->\n",
    );
    let _ = writeln!(s, "<Node name=\"root\" dt=\"{DT_S:?}\" gravity=\"0 0 0\">");
    for plugin in plugins_for(used.iter().copied()) {
        let _ = writeln!(s, "    <RequiredPlugin name=\"{plugin}\"/>");
    }
    s.push_str("    <DefaultAnimationLoop/>\n");
    let _ = writeln!(
        s,
        "    <!-- tetrahedra (ossicles, joints, ligaments, tendons) and eardrum triangles on one \
         node set; physical tag = region label (atlas.json). createSubelements defaults to true \
         for Gmsh files and would add every tetrahedron face to the triangles -->\n    \
         <MeshGmshLoader name=\"loader\" filename=\"{SCENE_MESH}\" createSubelements=\"false\"/>"
    );
    s.push_str("    <Node name=\"MiddleEar\">\n");
    let _ = writeln!(
        s,
        "        <!-- Rayleigh damping C = alpha M + beta K (atlas damping) -->\n        \
         <EulerImplicitSolver name=\"ode\" rayleighMass=\"{:?}\" rayleighStiffness=\"{:?}\"/>",
        system.rayleigh.mass, system.rayleigh.stiffness
    );
    s.push_str(
        "        <SparseLDLSolver name=\"ldl\" template=\"CompressedRowSparseMatrixMat3x3\"/>\n\
         \x20       <MechanicalObject name=\"dofs\" template=\"Vec3\" position=\"@../loader.position\"/>\n\
         \x20       <TetrahedronSetTopologyContainer name=\"tetras\" position=\"@../loader.position\" \
         tetrahedra=\"@../loader.tetrahedra\"/>\n",
    );
    let _ = writeln!(
        s,
        "        <!-- lumped mass per point (g): sum of rho V/4 over tetrahedra and rho h A/3 over \
         triangles -->\n        <DiagonalMass name=\"mass\" vertexMass=\"{}\"/>",
        join(system.model.lumped_masses().iter().copied())
    );
    let _ = writeln!(
        s,
        "        <!-- Young's modulus per tetrahedron (Pa), in mesh order -->\n        \
         <TetrahedronFEMForceField name=\"chainFEM\" topology=\"@tetras\" method=\"large\" \
         poissonRatio=\"{:?}\" youngModulus=\"{}\"/>",
        materials.tet_poisson,
        join(materials.tet_modulus.iter().copied())
    );
    let _ = writeln!(
        s,
        "        <!-- tympanic annulus and the wall ends of the ligaments and tendons; named \
         FixedProjectiveConstraint from SOFA v24.06 (the old name loads until v25.06) -->\n        \
         <FixedConstraint name=\"fixed\" indices=\"{}\"/>",
        join_indices(fixed)
    );
    let _ = writeln!(
        s,
        "        <!-- stapedial annular ligament: zero-rest-length springs (uN/mm) on the footplate \
         rim -->\n        <RestShapeSpringsForceField name=\"annularLigament\" points=\"{}\" \
         stiffness=\"{}\"/>",
        join_indices(springs.iter().map(|(v, _)| *v)),
        join(springs.iter().map(|(_, k)| *k))
    );
    let _ = writeln!(
        s,
        "        <!-- cochlear load: dashpot (g/s) per point and axis, nonzero on the footplate -->\n        \
         <DiagonalVelocityDampingForceField name=\"cochlearLoad\" dampingCoefficient=\"{}\"/>",
        join(system.node_dashpot().iter().flat_map(|&c| [c, c, c]))
    );
    if membranes {
        s.push_str(
            "        <Node name=\"Eardrum\">\n\
             \x20           <TriangleSetTopologyContainer name=\"drum\" \
             position=\"@../../loader.position\" triangles=\"@../../loader.triangles\"/>\n",
        );
        let _ = writeln!(
            s,
            "            <!-- E x thickness per triangle (Pa mm): the triangle has no thickness of \
             its own -->\n            <TriangularFEMForceField name=\"drumFEM\" topology=\"@drum\" \
             method=\"large\" poissonRatio=\"{}\" youngModulus=\"{}\"/>",
            join(materials.tri_poisson.iter().copied()),
            join(materials.tri_modulus_thickness.iter().copied())
        );
        s.push_str(
            "            <!-- follower pressure (Pa) on the eardrum: the triangles face the ear \
             canal, so an ear-canal pressure p is pressure=\"-p\" -->\n\
             \x20           <SurfacePressureForceField name=\"earCanalPressure\" topology=\"@drum\" \
             pressure=\"0\"/>\n",
        );
        write_bending(&mut s, &atlas.mesh.triangles, nodes, &bending);
        s.push_str("        </Node>\n");
    }
    s.push_str("    </Node>\n</Node>\n");
    Ok(s)
}

/// The eardrum's bending inside the "Eardrum" node (`scene_bending`): the layer on every
/// triangle uses the node's topology, the others a child node with their triangles, and one
/// ConstantForceField cancels the springs' force at the rest positions `nodes`.
fn write_bending(
    s: &mut String,
    triangles: &[[u32; 3]],
    nodes: &[Point3<f64>],
    layers: &[BendingLayer],
) {
    if layers.is_empty() {
        return;
    }
    s.push_str(
        "            <!-- eardrum bending (a shell: bending_thickness_mm in atlas.json): Volino's \
         linear bending springs, bendingStiffness 3 x the flexural rigidity E h^3/(12(1 - nu^2)) \
         (uN mm), which gives otoatlas's discrete-shell hinges on a flat hinge; stacked layers \
         where the rigidity differs (each triangle's layers sum to 3 x its own). The springs \
         rest flat, so bendingRestForce cancels their push at this curved rest shape: linear \
         bending about it, exact for small rotations (docs/mechanics.md, SOFA scene) -->\n",
    );
    let cancel = scene_bending::rest_force_cancellation(nodes, triangles, layers);
    let loaded: Vec<u32> = (0..nodes.len() as u32)
        .filter(|&v| cancel[v as usize] != nalgebra::Vector3::zeros())
        .collect();
    let mut children = String::new();
    for (k, layer) in layers.iter().enumerate() {
        if layer.triangles.len() == triangles.len() {
            let _ = writeln!(
                s,
                "            <FastTriangularBendingSprings name=\"bending\" topology=\"@drum\" \
                 bendingStiffness=\"{:?}\"/>",
                layer.stiffness
            );
        } else {
            let _ = writeln!(
                children,
                "            <Node name=\"BendingLayer{k}\">\n\
                 \x20               <TriangleSetTopologyContainer name=\"layer\" \
                 position=\"@../../../loader.position\" triangles=\"{}\"/>\n\
                 \x20               <FastTriangularBendingSprings name=\"bending\" \
                 topology=\"@layer\" bendingStiffness=\"{:?}\"/>\n            </Node>",
                join_indices(layer.triangles.iter().flat_map(|&t| triangles[t])),
                layer.stiffness
            );
        }
    }
    let _ = writeln!(
        s,
        "            <ConstantForceField name=\"bendingRestForce\" topology=\"@drum\" \
         indices=\"{}\" forces=\"{}\"/>",
        join_indices(loaded.iter().copied()),
        join(loaded.iter().flat_map(|&v| {
            let f = cancel[v as usize];
            [f.x, f.y, f.z]
        }))
    );
    s.push_str(&children);
}
