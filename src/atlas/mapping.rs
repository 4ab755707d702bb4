//! The mapping file of `atlas import` (TOML, documented in docs/atlas-format.md): what each
//! cell tag of an imported mesh becomes — a region with its part, material and (for
//! triangles) membrane thickness, optionally split by half-spaces; a dropped tag; a node set;
//! a load surface — and the material library a mapping may name.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use nalgebra::{Point3, Vector3};
use serde::Deserialize;

use super::format::{AtlasError, default_atlas};
use super::mass::without_mesh_correction;
use super::model::{MaterialInfo, Part, RegionInfo, bad_bending_thickness};

/// The mapping file: what each cell tag of the mesh becomes.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// The integer cell array holding the tags in a VTU (default `region`); Gmsh meshes use
    /// each element's first (physical) tag.
    #[serde(default)]
    pub tag_array: Option<String>,
    /// Regions, in label order (the first gets label 1).
    #[serde(default, rename = "region")]
    pub regions: Vec<RegionMap>,
    /// Tags whose cells are left out of the atlas (their nodes may still make node sets).
    #[serde(default)]
    pub drop: Vec<u16>,
    /// Node sets: the nodes of the cells with these tags that the atlas keeps.
    #[serde(default, rename = "node_set")]
    pub node_sets: Vec<SetMap>,
    /// Load surfaces: the triangles with these tags, oriented as in the file.
    #[serde(default, rename = "surface")]
    pub surfaces: Vec<SetMap>,
}

/// One region: the cells of `tag` (whose centroid lies in every half-space of `within`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionMap {
    pub tag: u16,
    pub name: String,
    pub part: Part,
    pub material: MaterialRef,
    /// Membrane thickness \[mm\]: makes this a region of triangles.
    #[serde(default)]
    pub thickness_mm: Option<f64>,
    /// Flexural thickness \[mm\] of a membrane region that bends (a shell); absent: bending-free.
    #[serde(default)]
    pub bending_thickness_mm: Option<f64>,
    /// Splits a tag by position: every half-space must contain the cell's centroid. Regions
    /// of the same tag are tried in file order; the first that contains a cell takes it.
    #[serde(default)]
    pub within: Vec<HalfSpace>,
}

/// A region's material: a name from [`material_library`] or the numbers themselves (SI).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum MaterialRef {
    Named(String),
    Explicit(MaterialInfo),
}

/// The points `x` with `(x - point) · normal >= 0` \[mm\].
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HalfSpace {
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

impl HalfSpace {
    fn contains(&self, p: &Point3<f64>) -> bool {
        (p - Point3::from(self.point)).dot(&Vector3::from(self.normal)) >= 0.0
    }
}

/// A named node set or surface made of the cells of some tags.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetMap {
    pub name: String,
    pub tags: Vec<u16>,
}

/// Reads and checks a mapping file.
pub fn read_mapping(path: &Path) -> Result<Mapping, AtlasError> {
    let text = crate::io_util::read_text(path).map_err(|source| AtlasError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mapping: Mapping = toml::from_str(&text).map_err(|e| {
        AtlasError::invalid(
            path,
            "document",
            "a mapping file (TOML, see docs/atlas-format.md)",
            e.to_string(),
        )
    })?;
    check_mapping(&mapping, path)?;
    Ok(mapping)
}

pub(crate) fn check_mapping(m: &Mapping, path: &Path) -> Result<(), AtlasError> {
    let bad = |field: String, expected: &str, found: String| {
        Err(AtlasError::invalid(path, field, expected, found))
    };
    if m.regions.is_empty() {
        return bad("region".into(), "at least one [[region]]", "none".into());
    }
    let mut names = BTreeSet::new();
    for (k, r) in m.regions.iter().enumerate() {
        if !names.insert(r.name.as_str()) {
            return bad(
                format!("region[{k}].name"),
                "a name used once",
                r.name.clone(),
            );
        }
        if m.drop.contains(&r.tag) {
            return bad(
                format!("region[{k}].tag"),
                "a tag not also listed in drop",
                r.tag.to_string(),
            );
        }
        if let Some(h) = r.thickness_mm.filter(|h| !(h.is_finite() && *h > 0.0)) {
            return bad(
                format!("region[{k}].thickness_mm"),
                "a positive thickness",
                h.to_string(),
            );
        }
        if let Some(h) = bad_bending_thickness(r.bending_thickness_mm, r.thickness_mm) {
            return bad(
                format!("region[{k}].bending_thickness_mm"),
                "a positive thickness, on a region with thickness_mm",
                h.to_string(),
            );
        }
        if r.thickness_mm.is_some() != (r.part == Part::Eardrum) {
            return bad(
                format!("region[{k}].thickness_mm"),
                "a thickness exactly for eardrum (membrane) regions",
                format!("part {} with thickness {:?}", r.part.name(), r.thickness_mm),
            );
        }
        for (j, h) in r.within.iter().enumerate() {
            let finite = h.point.iter().chain(&h.normal).all(|v| v.is_finite());
            if !finite || Vector3::from(h.normal).norm() == 0.0 {
                return bad(
                    format!("region[{k}].within[{j}]"),
                    "a finite point and a non-zero normal",
                    format!("{h:?}"),
                );
            }
        }
    }
    for (what, sets) in [("node_set", &m.node_sets), ("surface", &m.surfaces)] {
        let mut seen = BTreeSet::new();
        for (k, s) in sets.iter().enumerate() {
            if !seen.insert(s.name.as_str()) || s.tags.is_empty() {
                return bad(
                    format!("{what}[{k}]"),
                    "a name used once and at least one tag",
                    format!("{s:?}"),
                );
            }
        }
    }
    Ok(())
}

/// The materials a mapping (or a surface build) may name: the default atlas's as the literature
/// gives them (without the correction that gives the default mesh its anatomy's masses,
/// `mass`), plus one whole-bone material for each ossicle without a region of that name
/// (`malleus`, `incus`), with the bone's Young's modulus and the density that gives it the
/// anatomy's mass.
pub fn material_library() -> Result<BTreeMap<String, MaterialInfo>, AtlasError> {
    let default = default_atlas()?;
    let tets = &default.mesh.tets;
    let mut lib = without_mesh_correction(&default.materials, &default.regions, tets);
    for part in Part::BONES {
        if lib.contains_key(part.name()) {
            continue;
        }
        let (mut mass, mut volume, mut modulus) = (0.0, 0.0, 0.0f64);
        let mut nu = 0.0;
        for r in default.regions.iter().filter(|r| r.part == part) {
            let Some(m) = default.materials.get(&r.material) else {
                continue;
            };
            let meshed = tets.region_volume(r.label);
            mass += m.density_kg_m3 * meshed;
            volume += r.shape_volume_mm3.unwrap_or(meshed);
            modulus = modulus.max(m.youngs_modulus_pa);
            nu = m.poisson_ratio;
        }
        if volume > 0.0 {
            lib.insert(
                part.name().to_string(),
                MaterialInfo {
                    density_kg_m3: mass / volume,
                    youngs_modulus_pa: modulus,
                    poisson_ratio: nu,
                    source: format!(
                        "whole {}: the default atlas's mass of it over the anatomy's volume; E \
                         and Poisson's ratio as the default atlas's bone",
                        part.name()
                    ),
                },
            );
        }
    }
    Ok(lib)
}

/// Regions and materials of the mapping, with labels 1, 2, … in mapping order.
pub(crate) fn resolve_regions(
    m: &Mapping,
    path: &Path,
) -> Result<(Vec<RegionInfo>, BTreeMap<String, MaterialInfo>), AtlasError> {
    let lib = material_library()?;
    let mut regions = Vec::new();
    let mut materials = BTreeMap::new();
    for (k, r) in m.regions.iter().enumerate() {
        let (key, info) = match &r.material {
            MaterialRef::Named(name) => {
                let info = lib.get(name).ok_or_else(|| {
                    AtlasError::invalid(
                        path,
                        format!("region[{k}].material"),
                        format!(
                            "one of {} or {{ density_kg_m3, youngs_modulus_pa, poisson_ratio, \
                             source }}",
                            lib.keys().cloned().collect::<Vec<_>>().join(", ")
                        ),
                        format!("unknown material '{name}'"),
                    )
                })?;
                (name.clone(), info.clone())
            }
            MaterialRef::Explicit(info) => (r.name.clone(), info.clone()),
        };
        if materials.get(&key).is_some_and(|m| *m != info) {
            return Err(AtlasError::invalid(
                path,
                format!("region[{k}].material"),
                "an explicit material for a region name that no named material uses",
                key,
            ));
        }
        materials.insert(key.clone(), info);
        regions.push(RegionInfo {
            label: k as u16 + 1,
            name: r.name.clone(),
            part: r.part,
            material: key,
            thickness_mm: r.thickness_mm,
            bending_thickness_mm: r.bending_thickness_mm,
            shape_volume_mm3: None,
        });
    }
    Ok((regions, materials))
}

impl Mapping {
    /// The index of the region taking a cell of `tag` with centroid `c`, if any.
    pub fn region_of(&self, tag: u16, c: &Point3<f64>) -> Option<usize> {
        self.regions
            .iter()
            .position(|r| r.tag == tag && r.within.iter().all(|h| h.contains(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::materials::MALLEUS_DENSITY_KG_M3;

    fn parse(text: &str) -> Result<Mapping, AtlasError> {
        let m: Mapping = toml::from_str(text).map_err(|e| {
            AtlasError::invalid(Path::new("m.toml"), "document", "TOML", e.to_string())
        })?;
        check_mapping(&m, Path::new("m.toml"))?;
        Ok(m)
    }

    /// The field an error names.
    fn field(e: AtlasError) -> String {
        match e {
            AtlasError::Invalid { field, .. } => field,
            other => panic!("{other}"),
        }
    }

    const BONE: &str =
        "[[region]]\ntag = 1\nname = \"m\"\npart = \"malleus\"\nmaterial = \"malleus\"\n";

    #[test]
    fn half_spaces_split_a_tag_in_file_order() {
        let m = parse(
            "[[region]]\ntag = 2\nname = \"stapes\"\npart = \"stapes\"\nmaterial = \"stapes\"\n\
             within = [{ point = [1, 0, 0], normal = [-1, 0, 0] }, \
                       { point = [0, 0, 2], normal = [0, 0, -1] }]\n\
             [[region]]\ntag = 2\nname = \"incus\"\npart = \"incus\"\nmaterial = \"incus\"\n",
        )
        .unwrap();
        assert_eq!(m.region_of(2, &Point3::new(0.5, 9.0, 1.0)), Some(0));
        // outside either half-space: the next region of the tag
        assert_eq!(m.region_of(2, &Point3::new(1.5, 0.0, 1.0)), Some(1));
        assert_eq!(m.region_of(2, &Point3::new(0.5, 0.0, 2.5)), Some(1));
        // on the plane counts as inside
        assert_eq!(m.region_of(2, &Point3::new(1.0, 0.0, 2.0)), Some(0));
        assert_eq!(m.region_of(3, &Point3::origin()), None);
    }

    #[test]
    fn inconsistent_mappings_are_rejected_naming_the_entry() {
        assert_eq!(field(parse("drop = [1]\n").unwrap_err()), "region");
        assert_eq!(
            field(parse(&format!("drop = [1]\n{BONE}")).unwrap_err()),
            "region[0].tag"
        );
        assert_eq!(
            field(parse(&format!("{BONE}{BONE}")).unwrap_err()),
            "region[1].name"
        );
        // thickness exactly for eardrum regions
        assert_eq!(
            field(parse(&format!("{BONE}thickness_mm = 0.1\n")).unwrap_err()),
            "region[0].thickness_mm"
        );
        let drum =
            "[[region]]\ntag = 5\nname = \"d\"\npart = \"eardrum\"\nmaterial = \"pars_tensa\"\n";
        assert_eq!(field(parse(drum).unwrap_err()), "region[0].thickness_mm");
        assert!(parse(&format!("{drum}thickness_mm = 0.074\n")).is_ok());
        assert_eq!(
            field(
                parse(&format!(
                    "{BONE}within = [{{ point = [0, 0, 0], normal = [0, 0, 0] }}]\n"
                ))
                .unwrap_err()
            ),
            "region[0].within[0]"
        );
        assert_eq!(
            field(parse(&format!("{BONE}[[node_set]]\nname = \"a\"\ntags = []\n")).unwrap_err()),
            "node_set[0]"
        );
        // a misspelt key is an error, not ignored
        assert_eq!(
            field(parse(&format!("{BONE}thicknes_mm = 0.1\n")).unwrap_err()),
            "document"
        );
    }

    #[test]
    fn materials_resolve_by_name_or_explicitly() {
        let m = parse(&format!(
            "{BONE}[[region]]\ntag = 2\nname = \"lig\"\npart = \"connective\"\n\
             material = {{ density_kg_m3 = 1000.0, youngs_modulus_pa = 1e6, \
             poisson_ratio = 0.45, source = \"test\" }}\n\
             [[region]]\ntag = 3\nname = \"x\"\npart = \"stapes\"\nmaterial = \"ivory\"\n"
        ))
        .unwrap();
        let err = resolve_regions(&m, Path::new("m.toml")).unwrap_err();
        assert!(
            err.to_string().contains("unknown material 'ivory'"),
            "{err}"
        );
        let mut m = m;
        m.regions.pop();
        let (regions, materials) = resolve_regions(&m, Path::new("m.toml")).unwrap();
        assert_eq!(
            regions.iter().map(|r| r.label).collect::<Vec<_>>(),
            vec![1, 2]
        );
        assert_eq!(materials["lig"].youngs_modulus_pa, 1e6);
        // the whole malleus: bone modulus, the one density of its regions
        let malleus = &materials["malleus"];
        assert_eq!(malleus.youngs_modulus_pa, 1.41e10);
        assert!((malleus.density_kg_m3 - MALLEUS_DENSITY_KG_M3).abs() < 1e-9);
    }
}
