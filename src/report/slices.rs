//! The slice overlays of a case report: for each ossicle, the axial, coronal and sagittal CBCT
//! slices through the centroid of its registered surface, with the contours of every atlas
//! structure after the rigid fit, after the deformable registration, and of the manual
//! segmentation. The field of view frames the ossicle (its registered bounding box plus a
//! margin); the grey window is a bone window taken from the image's own intensities (CBCT grey
//! values are not calibrated HU, so fixed HU windows would not carry over between scanners).

use std::collections::BTreeMap;

use nalgebra::{Point3, Vector3};

use super::error::ReportError;
use super::html::{Figure, FigureContent};
use super::overlay::{Contour, Marker, SliceSpec, View, render_slice};
use crate::atlas::Part;
use crate::image::{Sampler, Volume};
use crate::mesh::TriMesh;

/// Contour colour of the atlas after the rigid fit (used nowhere else on the page).
pub const RIGID_COLOUR: [u8; 3] = [255, 160, 0];
/// Contour colour of the atlas after the deformable registration.
pub const REGISTERED_COLOUR: [u8; 3] = [255, 0, 255];
/// Contour colour of the manual segmentation.
pub const SEGMENTATION_COLOUR: [u8; 3] = [0, 230, 80];
/// Colour of the landmarks' crosses.
pub const LANDMARK_COLOUR: [u8; 3] = [0, 200, 255];
/// Side of every overlay image \[pixels\].
pub const OVERLAY_PIXELS: usize = 256;
/// Space around the ossicle's bounding box [mm].
const MARGIN_MM: f64 = 1.0;
/// Fractions of the voxel values at the black and white ends of the bone window: air is the
/// darkest percent, the densest bone (otic capsule) the brightest half percent.
const WINDOW_QUANTILES: (f64, f64) = (0.01, 0.995);
/// Most voxels read to find the window (a regular subsample of larger images).
const WINDOW_SAMPLES: usize = 1 << 20;

/// The surfaces drawn on the overlays, by structure name.
pub struct OverlaySurfaces<'a> {
    pub rigid: &'a BTreeMap<String, TriMesh>,
    pub registered: &'a BTreeMap<String, TriMesh>,
    pub segmentation: Option<&'a BTreeMap<String, TriMesh>>,
    /// The patient's landmarks (picked or proposed), drawn as crosses near each slice.
    pub landmarks: &'a [Point3<f64>],
}

/// The grey window [lo, hi] of the image: its 1st and 99.5th percentile voxel values.
pub fn bone_window(volume: &Volume) -> (f32, f32) {
    let Some([lo, hi]) = volume.quantiles([WINDOW_QUANTILES.0, WINDOW_QUANTILES.1], WINDOW_SAMPLES)
    else {
        return (0.0, 1.0);
    };
    (lo, if hi > lo { hi } else { lo + 1.0 })
}

/// Area-weighted centroid and bounding box (min, max) of a surface.
fn centroid_and_box(mesh: &TriMesh) -> (Point3<f64>, Point3<f64>, Point3<f64>) {
    let (mut sum, mut area) = (Vector3::zeros(), 0.0);
    for t in 0..mesh.triangles.len() {
        let a = mesh.triangle_area(t);
        sum += mesh.triangle_centroid(t).coords * a;
        area += a;
    }
    let mut lo = Point3::from(Vector3::repeat(f64::INFINITY));
    let mut hi = Point3::from(Vector3::repeat(f64::NEG_INFINITY));
    for p in &mesh.vertices {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let centre = if area > 0.0 {
        Point3::from(sum / area)
    } else {
        nalgebra::center(&lo, &hi)
    };
    (centre, lo, hi)
}

/// How each view is laid out, for the captions (see `overlay`).
fn orientation(view: View) -> &'static str {
    match view {
        View::Axial => "from below: patient right on the left, anterior up",
        View::Coronal => "from the front: patient right on the left, superior up",
        View::Sagittal => "from the left: anterior on the left, superior up",
    }
}

/// The overlays, per ossicle that has a registered surface: (ossicle, its three views).
pub fn overlay_figures(
    sampler: &Sampler,
    surfaces: &OverlaySurfaces,
) -> Result<Vec<(&'static str, Vec<Figure>)>, ReportError> {
    let window = bone_window(sampler.volume());
    let mut contours = Vec::new();
    let sets = [
        (Some(surfaces.rigid), RIGID_COLOUR),
        (Some(surfaces.registered), REGISTERED_COLOUR),
        (surfaces.segmentation, SEGMENTATION_COLOUR),
    ];
    for (set, color) in sets {
        for mesh in set.into_iter().flat_map(|s| s.values()) {
            contours.push(Contour { mesh, color });
        }
    }
    let markers: Vec<Marker> = surfaces
        .landmarks
        .iter()
        .map(|&point| Marker {
            point,
            color: LANDMARK_COLOUR,
        })
        .collect();
    let mut out = Vec::new();
    for part in Part::BONES {
        let Some(mesh) = surfaces
            .registered
            .get(part.name())
            .filter(|m| !m.triangles.is_empty())
        else {
            continue;
        };
        let (centre, lo, hi) = centroid_and_box(mesh);
        let half_width_mm = (hi - lo).max() / 2.0 + MARGIN_MM;
        let mut figures = Vec::new();
        for view in [View::Axial, View::Coronal, View::Sagittal] {
            let spec = SliceSpec {
                view,
                centre,
                half_width_mm,
                pixel_mm: 2.0 * half_width_mm / OVERLAY_PIXELS as f64,
                window,
            };
            let caption = format!(
                "{} {}, {:.1} mm field ({})",
                part.name(),
                view.name(),
                2.0 * half_width_mm,
                orientation(view)
            );
            let png = render_slice(sampler, &spec, &contours, &markers)
                .to_png()
                .map_err(|source| ReportError::Png {
                    figure: caption.clone(),
                    source,
                })?;
            figures.push(Figure {
                caption,
                content: FigureContent::Png(png),
            });
        }
        out.push((part.name(), figures));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn bone_window_spans_air_to_dense_bone() {
        // 1000 voxels: 10 % air, 89 % soft tissue ramp, 1 % dense bone
        let data: Vec<f32> = (0..1000)
            .map(|i| match i {
                0..100 => -1000.0,
                990.. => 2000.0,
                i => i as f32,
            })
            .collect();
        let v = Volume {
            dims: [10, 10, 10],
            spacing: [1.0; 3],
            origin: Vector3::zeros(),
            direction: Matrix3::identity(),
            data,
        };
        assert_eq!(bone_window(&v), (-1000.0, 2000.0));
    }

    #[test]
    fn centroid_of_a_box_surface_is_its_centre() {
        let mesh = crate::mesh::shapes::box_mesh(
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(2.0, 4.0, 6.0),
            3,
        );
        let (c, lo, hi) = centroid_and_box(&mesh);
        assert!((c - Point3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        assert_eq!((lo, hi), (Point3::origin(), Point3::new(2.0, 4.0, 6.0)));
    }
}
