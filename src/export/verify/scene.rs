//! The scene part of `verify`: `scene.scn` parsed as XML; every element a known SOFA
//! component (`sofa::COMPONENTS`) whose plugin the scene requires; the loader's file in the
//! package, read without sub-elements (so its triangles are the membrane's); and every vector
//! against the mesh it loads — one positive mass per point (summing to the mass of the
//! elements, Σ ρV + Σ ρhA, computed here from the geometry), one Young's modulus per
//! tetrahedron and E·h per triangle equal to the atlas's material of the element, fixed and
//! spring indices in range, one damping Vec3 per point.

use std::collections::{BTreeMap, BTreeSet};

use roxmltree::{Document, Node};

use super::bending::check_bending;
use super::faults::Faults;
use super::xml::{Scene, close, numbers};
use crate::atlas::Atlas;
use crate::atlas::materials::KG_PER_M3_TO_G_PER_MM3;
use crate::export::scene::{CellMaterials, SCENE};
use crate::export::sofa::{STRUCTURAL, plugin_of};
use crate::mesh::io::VolumeMesh;
use crate::mesh::tet::signed_volume;

fn check_len(node: Node, attr: &str, values: &[f64], want: usize, what: &str, faults: &mut Faults) {
    if values.len() != want {
        faults.add(
            "scene",
            SCENE,
            format!(
                "{}.{attr} has {} values, the mesh has {want} {what}",
                node.tag_name().name(),
                values.len()
            ),
        );
    }
}

/// Indices (given as numbers) that are whole and below `n`.
fn check_indices(node: Node, attr: &str, values: &[f64], n: usize, faults: &mut Faults) {
    if let Some(bad) = values
        .iter()
        .find(|&&v| v < 0.0 || v.fract() != 0.0 || v >= n as f64)
    {
        faults.add(
            "scene",
            SCENE,
            format!(
                "{}.{attr}: {bad} is not a point index below {n}",
                node.tag_name().name()
            ),
        );
    }
    if values.is_empty() {
        faults.add(
            "scene",
            SCENE,
            format!("{}.{attr} is empty", node.tag_name().name()),
        );
    }
}

/// Checks the scene `text` (see the module doc). `mesh`: what the loader reads (mesh.msh);
/// `atlas`: the package's atlas.json; `files`: the package's listed files.
pub(super) fn check_scene(
    text: &str,
    mesh: Option<&VolumeMesh>,
    atlas: Option<&Atlas>,
    files: &BTreeMap<String, String>,
    faults: &mut Faults,
) {
    let doc = match Document::parse(text) {
        Ok(d) => d,
        Err(e) => return faults.add("scene", SCENE, format!("not XML: {e}")),
    };
    let root = doc.root_element();
    if root.tag_name().name() != "Node" {
        faults.add("scene", SCENE, "the root element is not a Node");
    }
    let mut scene = Scene::default();
    let mut required = BTreeSet::new();
    let mut needed = BTreeSet::new();
    for node in root.descendants().filter(Node::is_element) {
        let tag = node.tag_name().name();
        if tag == "RequiredPlugin" {
            required.insert(node.attribute("name").unwrap_or(""));
        } else if !STRUCTURAL.contains(&tag) {
            match plugin_of(tag) {
                None => faults.add("scene", SCENE, format!("unknown SOFA component <{tag}>")),
                Some(plugin) => needed.extend(plugin),
            }
        }
        scene.add(tag, node);
    }
    for plugin in needed.difference(&required) {
        faults.add(
            "scene",
            SCENE,
            format!("a component needs plugin {plugin}, which no RequiredPlugin loads"),
        );
    }
    if let Some(loader) = scene.one("MeshGmshLoader", faults) {
        if loader.attribute("createSubelements") != Some("false") {
            faults.add(
                "scene",
                SCENE,
                "MeshGmshLoader without createSubelements=\"false\": for Gmsh files it adds every \
                 tetrahedron face to the triangles the membrane force field acts on",
            );
        }
        let file = loader.attribute("filename").unwrap_or("");
        if !files.contains_key(file) {
            faults.add(
                "scene",
                SCENE,
                format!("the loader reads '{file}', which is not a file of the package"),
            );
        }
    }
    for tag in ["MechanicalObject", "EulerImplicitSolver", "SparseLDLSolver"] {
        scene.one(tag, faults);
    }
    if let Some(mesh) = mesh {
        check_vectors(&scene, mesh, atlas, faults);
        check_bending(&scene, mesh, atlas, faults);
    }
}

fn check_vectors(scene: &Scene, mesh: &VolumeMesh, atlas: Option<&Atlas>, faults: &mut Faults) {
    let (n, n_tets, n_tris) = (
        mesh.tets.nodes.len(),
        mesh.tets.tets.len(),
        mesh.triangles.len(),
    );
    // per cell (tetrahedra, then triangles): E [Pa], density [kg/m^3], thickness [mm]
    let materials = atlas
        .map(CellMaterials::of)
        .filter(|c| c.modulus.len() == n_tets + n_tris)
        .map(|c| (c.modulus, c.density, c.thickness));
    if let Some(node) = scene.one("DiagonalMass", faults)
        && let Some(m) = numbers(node, "vertexMass", faults)
    {
        check_len(node, "vertexMass", &m, n, "points", faults);
        if let Some(v) = m.iter().position(|&x| x <= 0.0) {
            faults.add(
                "scene",
                SCENE,
                format!(
                    "DiagonalMass.vertexMass[{v}] = {}: every point needs a positive mass (some \
                     SOFA versions refuse a zero)",
                    m[v]
                ),
            );
        }
        if let Some((_, rho, h)) = &materials {
            let tets = (0..n_tets).map(|t| {
                let [a, b, c, d] = mesh.tets.corners(t);
                rho[t] * signed_volume(&a, &b, &c, &d).abs()
            });
            let tris = mesh.triangles.iter().enumerate().map(|(k, tri)| {
                let [a, b, c] = tri.map(|v| mesh.tets.nodes[v as usize]);
                rho[n_tets + k] * h[n_tets + k] * 0.5 * (b - a).cross(&(c - a)).norm()
            });
            let want = tets.chain(tris).sum::<f64>() * KG_PER_M3_TO_G_PER_MM3;
            let got: f64 = m.iter().sum();
            if !close(got, want) {
                faults.add(
                    "scene",
                    SCENE,
                    format!("the masses sum to {got:e} g, the elements weigh {want:e} g"),
                );
            }
        }
    }
    if let Some(node) = scene.one("TetrahedronFEMForceField", faults)
        && let Some(e) = numbers(node, "youngModulus", faults)
    {
        check_len(node, "youngModulus", &e, n_tets, "tetrahedra", faults);
        if let Some((want, _, _)) = &materials
            && let Some(t) = (0..e.len().min(n_tets)).find(|&t| !close(e[t], want[t]))
        {
            faults.add(
                "scene",
                SCENE,
                format!(
                    "TetrahedronFEMForceField.youngModulus[{t}] = {}, the atlas gives {} Pa",
                    e[t], want[t]
                ),
            );
        }
    }
    if n_tris > 0
        && let Some(node) = scene.one("TriangularFEMForceField", faults)
    {
        if let Some(nu) = numbers(node, "poissonRatio", faults) {
            check_len(node, "poissonRatio", &nu, n_tris, "triangles", faults);
        }
        if let Some(eh) = numbers(node, "youngModulus", faults) {
            check_len(node, "youngModulus", &eh, n_tris, "triangles", faults);
            if let Some((e, _, h)) = &materials
                && let Some(k) = (0..eh.len().min(n_tris))
                    .find(|&k| !close(eh[k], e[n_tets + k] * h[n_tets + k]))
            {
                faults.add(
                    "scene",
                    SCENE,
                    format!(
                        "TriangularFEMForceField.youngModulus[{k}] = {}, the atlas's E x \
                         thickness is {}",
                        eh[k],
                        e[n_tets + k] * h[n_tets + k]
                    ),
                );
            }
        }
    }
    let fixed = ["FixedConstraint", "FixedProjectiveConstraint"]
        .iter()
        .flat_map(|t| scene.all(t))
        .collect::<Vec<_>>();
    if fixed.is_empty() {
        faults.add("scene", SCENE, "no fixed constraint: the model would float");
    }
    for node in fixed {
        if let Some(i) = numbers(node, "indices", faults) {
            check_indices(node, "indices", &i, n, faults);
        }
    }
    for node in scene.all("RestShapeSpringsForceField") {
        if let (Some(p), Some(k)) = (
            numbers(node, "points", faults),
            numbers(node, "stiffness", faults),
        ) {
            check_indices(node, "points", &p, n, faults);
            if k.len() != 1 {
                check_len(node, "stiffness", &k, p.len(), "spring points", faults);
            }
        }
    }
    for node in scene.all("DiagonalVelocityDampingForceField") {
        if let Some(c) = numbers(node, "dampingCoefficient", faults) {
            check_len(
                node,
                "dampingCoefficient",
                &c,
                3 * n,
                "point coordinates",
                faults,
            );
        }
    }
}
