//! The tetrahedra a simulator would assemble: none inverted, none flattened. A near-flat
//! element keeps a tiny fraction of its stiffness's scale in one direction and huge in
//! others, which ill-conditions the bone stiffness of the whole chain; so `verify` bounds
//! each tetrahedron's shape quality (`mesh::quality::shape_quality`) and, against the atlas
//! the package was registered from, its volume over its atlas counterpart's (scaled by the
//! landmark fit's scale³). The bounds are the registration's own floors
//! (`mesh::quality::MIN_SHAPE_QUALITY`, `MIN_VOLUME_RATIO`): `run` refuses to write a package
//! below them, so `verify` flags only packages made otherwise or changed since.

use serde::Serialize;

use super::faults::Faults;
use crate::atlas::Atlas;
use crate::mesh::io::VolumeMesh;
use crate::mesh::quality::shape_quality;
pub use crate::mesh::quality::{MIN_SHAPE_QUALITY, MIN_VOLUME_RATIO};

/// The worst tetrahedra found (0-based indices in mesh order).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ElementQuality {
    /// The smallest shape quality and its tetrahedron.
    pub min_shape_quality: f64,
    pub min_shape_quality_tetrahedron: usize,
    /// The smallest volume ratio to the atlas and its tetrahedron; `None` when the atlas the
    /// package was registered from was not at hand.
    pub min_volume_ratio: Option<f64>,
    pub min_volume_ratio_tetrahedron: Option<usize>,
}

/// The atlas a package was registered from (mirrored to the package's side) with the scale
/// of its landmark fit.
pub(super) struct Reference<'a> {
    pub atlas: &'a Atlas,
    pub scale: f64,
}

/// The name of the region of `label` in `atlas`, or the label.
fn region_name(atlas: Option<&Atlas>, label: u16) -> String {
    atlas
        .and_then(|a| a.region(label))
        .map_or_else(|| format!("region {label}"), |r| r.name.clone())
}

/// The smallest of `values` (NaN counts as smallest) with its index, and how many are below
/// `bound` (or NaN); `None` when empty.
struct Worst {
    index: usize,
    value: f64,
    failing: usize,
}

fn worst(values: &[f64], bound: f64) -> Option<Worst> {
    let low = |v: f64| if v.is_nan() { f64::NEG_INFINITY } else { v };
    let (index, value) = values
        .iter()
        .copied()
        .enumerate()
        .min_by(|a, b| low(a.1).total_cmp(&low(b.1)))?;
    let failing = values.iter().filter(|&&v| low(v) < bound).count();
    Some(Worst {
        index,
        value,
        failing,
    })
}

/// Tetrahedra with a non-positive volume.
pub(super) fn check_orientation(mesh: &VolumeMesh, file: &str, faults: &mut Faults) {
    let bad: Vec<(usize, f64)> = (0..mesh.tets.tets.len())
        .filter_map(|t| {
            let v = mesh.tets.tet_volume(t);
            (v.is_nan() || v <= 1e-12).then_some((t, v))
        })
        .collect();
    if let Some(&(first, v)) = bad.first() {
        faults.add(
            "orientation",
            file,
            format!(
                "{} inverted or degenerate tetrahedra (volume <= 0), first: tetrahedron {first} \
                 ({v:.3e} mm^3)",
                bad.len()
            ),
        );
    }
}

/// Bounds the shape quality of every tetrahedron of `mesh` and, with `reference`, its volume
/// ratio to the atlas; each failing bound is one fault naming the count and the worst element.
pub(super) fn check_quality(
    mesh: &VolumeMesh,
    reference: Option<&Reference>,
    file: &str,
    faults: &mut Faults,
) -> Option<ElementQuality> {
    let tets = &mesh.tets;
    let names = reference.map(|r| r.atlas);
    let quality: Vec<f64> = (0..tets.tets.len())
        .map(|t| shape_quality(&tets.corners(t)))
        .collect();
    let Worst {
        index: worst,
        value: q,
        failing,
    } = self::worst(&quality, MIN_SHAPE_QUALITY)?;
    if failing > 0 {
        faults.add(
            "quality",
            file,
            format!(
                "{failing} tetrahedra below shape quality {MIN_SHAPE_QUALITY} (volume over the \
                 regular tetrahedron's of the same RMS edge), worst: tetrahedron {worst} ({}) \
                 at {q:.3e}",
                region_name(names, tets.regions[worst])
            ),
        );
    }
    let mut summary = ElementQuality {
        min_shape_quality: q,
        min_shape_quality_tetrahedron: worst,
        min_volume_ratio: None,
        min_volume_ratio_tetrahedron: None,
    };
    let Some(r) = reference else {
        return Some(summary);
    };
    let rest = &r.atlas.mesh.tets;
    if rest.tets != tets.tets {
        faults.add(
            "quality",
            file,
            format!(
                "the tetrahedra are not those of atlas '{}' the manifest names ({} against \
                 {}): no volume ratio to compare",
                r.atlas.name,
                tets.tets.len(),
                rest.tets.len()
            ),
        );
        return Some(summary);
    }
    let cube = r.scale.powi(3);
    let ratio: Vec<f64> = (0..tets.tets.len())
        .map(|t| tets.tet_volume(t) / (rest.tet_volume(t).abs() * cube))
        .collect();
    let Worst {
        index: worst,
        value: v,
        failing,
    } = self::worst(&ratio, MIN_VOLUME_RATIO)?;
    summary.min_volume_ratio = Some(v);
    summary.min_volume_ratio_tetrahedron = Some(worst);
    if failing > 0 {
        faults.add(
            "quality",
            file,
            format!(
                "{failing} tetrahedra below {}% of their atlas volume (times the fit's scale^3), \
                 worst: tetrahedron {worst} ({}) at {:.2}% ({:.3e} mm^3 of {:.3e}), shape \
                 quality {:.3e}",
                MIN_VOLUME_RATIO * 100.0,
                region_name(names, tets.regions[worst]),
                v * 100.0,
                tets.tet_volume(worst),
                rest.tet_volume(worst).abs() * cube,
                quality[worst]
            ),
        );
    }
    Some(summary)
}
