//! The SOFA components a package's scene may use, each with the plugin that provides it, as
//! checked in the sofa-framework/sofa sources of v23.06–v24.12 (docs/package-format.md, "The
//! SOFA scene").
//! The scene writer emits only these; `verify` rejects any other element and any component
//! whose plugin the scene does not require.

/// The SOFA versions the scene is correct on: DiagonalVelocityDampingForceField has no
/// implicit terms in v23.06 (its `addDForce` and `addBToMatrix` are empty; restored in v23.12,
/// sofa-framework/sofa #3999), which with c·dt/m up to 28.6 on the footplate is unstable; and
/// `FixedConstraint`, the only name v23.12 knows, is removed in v25.06.
pub const SOFA_VERSIONS: &str = "v23.12 to v24.12";

/// Elements of the scene file that are not components (no plugin to load).
pub const STRUCTURAL: [&str; 2] = ["Node", "RequiredPlugin"];

/// (component, plugin): every component the scene may contain. `None`: part of the core
/// (Sofa.Simulation.Core), needs no `RequiredPlugin`.
pub const COMPONENTS: [(&str, Option<&str>); 18] = [
    ("DefaultAnimationLoop", None),
    ("MeshGmshLoader", Some("Sofa.Component.IO.Mesh")),
    ("MeshVTKLoader", Some("Sofa.Component.IO.Mesh")),
    ("MechanicalObject", Some("Sofa.Component.StateContainer")),
    (
        "TetrahedronSetTopologyContainer",
        Some("Sofa.Component.Topology.Container.Dynamic"),
    ),
    (
        "TriangleSetTopologyContainer",
        Some("Sofa.Component.Topology.Container.Dynamic"),
    ),
    (
        "EulerImplicitSolver",
        Some("Sofa.Component.ODESolver.Backward"),
    ),
    (
        "SparseLDLSolver",
        Some("Sofa.Component.LinearSolver.Direct"),
    ),
    ("DiagonalMass", Some("Sofa.Component.Mass")),
    (
        "TetrahedronFEMForceField",
        Some("Sofa.Component.SolidMechanics.FEM.Elastic"),
    ),
    (
        "TriangularFEMForceField",
        Some("Sofa.Component.SolidMechanics.FEM.Elastic"),
    ),
    (
        "RestShapeSpringsForceField",
        Some("Sofa.Component.SolidMechanics.Spring"),
    ),
    // named FixedProjectiveConstraint from v24.06; the old name loads until v25.06
    (
        "FixedConstraint",
        Some("Sofa.Component.Constraint.Projective"),
    ),
    (
        "FixedProjectiveConstraint",
        Some("Sofa.Component.Constraint.Projective"),
    ),
    (
        "DiagonalVelocityDampingForceField",
        Some("Sofa.Component.MechanicalLoad"),
    ),
    (
        "SurfacePressureForceField",
        Some("Sofa.Component.MechanicalLoad"),
    ),
    ("ConstantForceField", Some("Sofa.Component.MechanicalLoad")),
    (
        "FastTriangularBendingSprings",
        Some("Sofa.Component.SolidMechanics.Spring"),
    ),
];

/// The plugin of `component`: `Some(None)` for a core component, `None` if unknown.
pub fn plugin_of(component: &str) -> Option<Option<&'static str>> {
    COMPONENTS
        .iter()
        .find(|(name, _)| *name == component)
        .map(|(_, plugin)| *plugin)
}

/// The plugins the components in `used` need, sorted and without repeats.
pub fn plugins_for<'a>(used: impl IntoIterator<Item = &'a str>) -> Vec<&'static str> {
    let mut plugins: Vec<&'static str> = used
        .into_iter()
        .filter_map(|c| plugin_of(c).flatten())
        .collect();
    plugins.sort_unstable();
    plugins.dedup();
    plugins
}
