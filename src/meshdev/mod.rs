//! Surface-distance scoring of a test (registered) surface against a reference (manual
//! segmentation) surface, MeshDev-style, with the metrics defined in docs/metrics.md:
//! MASD (headline), ASSD, RMS, HD, HD95, signed bias, Surface Dice@τ, and the MeshDev-mode
//! one-sided per-vertex mean and max (after Roy, Foufou & Truchetet 2004).
//!
//! * Distances are exact point-to-triangle distances (Ericson's region method) found through
//!   our own SAH bounding-volume hierarchy, both in `mesh::spatial` (which also holds the
//!   measurements that chose it over `parry3d-f64`).
//! * Signs come from the reference's angle-weighted pseudonormals (`mesh::spatial`,
//!   Bærentzen & Aanæs 2005); positive = test outside the reference.
//! * Both surfaces are sampled by area (`sampling`), each sample weighted by its area;
//!   statistics follow `stats`; the per-vertex deviation map is coloured by `colormap` and
//!   summed per triangle label (the atlas region) by `by_label`.
//!
//! Every result is deterministic: samples depend only on the seed, sums run in a fixed order.

pub mod by_label;
pub mod colormap;
pub mod error;
pub mod sampling;
pub mod stats;
pub mod structures;

use rayon::prelude::*;

pub use crate::mesh::spatial::{
    Bvh, ClosestHit, Feature, Pseudonormals, SignedSurface, closest_point_on_triangle,
};
pub use by_label::{LabelDeviation, deviation_by_label};
pub use colormap::ColourRange;
pub use error::MeshDevError;
pub use sampling::{MAX_SAMPLES, Samples, Sampling, sample_surface};
pub use stats::{Directed, SurfaceDistances};

use crate::mesh::TriMesh;

/// What to compute and how.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CompareOptions {
    /// How both surfaces are sampled (default: area sampling, 10 per triangle, fixed seed).
    pub sampling: Sampling,
    /// Surface Dice tolerance τ (mm); `run` uses one voxel of the image (docs/metrics.md).
    pub tolerance_mm: f64,
    /// Fixed signed range of the deviation colours (default −0.5 … +0.5 mm).
    pub colour_range: ColourRange,
}

impl CompareOptions {
    /// Default sampling and colour range with Surface Dice tolerance `tolerance_mm`
    /// (give one voxel, e.g. the CBCT's largest spacing).
    pub fn with_tolerance(tolerance_mm: f64) -> Self {
        CompareOptions {
            sampling: Sampling::default(),
            tolerance_mm,
            colour_range: ColourRange::default(),
        }
    }

    fn validate(&self) -> Result<(), MeshDevError> {
        if !(self.tolerance_mm.is_finite() && self.tolerance_mm >= 0.0) {
            return Err(MeshDevError::InvalidOption {
                field: "tolerance_mm",
                value: self.tolerance_mm.to_string(),
                expected: "a finite tolerance >= 0 mm",
            });
        }
        self.sampling.validate()?;
        self.colour_range.validate()
    }
}

/// Per test vertex: signed distance to the reference (mm, positive outside) and its colour.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviationMap {
    pub quality: Vec<f64>,
    pub colours: Vec<[u8; 3]>,
}

/// The result of one comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    pub distances: SurfaceDistances,
    pub deviation: DeviationMap,
}

fn require_area(mesh: &TriMesh, role: &'static str) -> Result<(), MeshDevError> {
    if mesh.area() > 0.0 {
        Ok(())
    } else {
        Err(MeshDevError::ZeroArea { mesh: role })
    }
}

/// A reference surface made ready for comparisons: its signed-distance index and its area
/// samples, built once for every test surface compared with it (`run` scores the rigid and
/// the registered atlas against the same segmentation).
pub struct PreparedReference {
    index: SignedSurface,
    samples: Samples,
    sampling: Sampling,
}

impl PreparedReference {
    /// Indexes and samples `reference` with `sampling`.
    pub fn new(reference: &TriMesh, sampling: &Sampling) -> Result<Self, MeshDevError> {
        sampling.validate()?;
        let (index, samples) = rayon::join(
            || SignedSurface::new(reference, "reference"),
            || sample_surface(reference, sampling),
        );
        let index = index?;
        require_area(reference, "reference")?;
        Ok(PreparedReference {
            index,
            samples: samples?,
            sampling: *sampling,
        })
    }
}

/// Compares `test` (e.g. the registered atlas structure) with `reference` (e.g. the manual
/// segmentation of the same structure): symmetric statistics and the per-vertex signed
/// deviation map of `test`.
pub fn compare(
    test: &TriMesh,
    reference: &TriMesh,
    options: &CompareOptions,
) -> Result<Comparison, MeshDevError> {
    options.validate()?;
    compare_prepared(
        test,
        &PreparedReference::new(reference, &options.sampling)?,
        options,
    )
}

/// As [`compare`], against a reference already indexed and sampled with `options.sampling`.
pub fn compare_prepared(
    test: &TriMesh,
    reference: &PreparedReference,
    options: &CompareOptions,
) -> Result<Comparison, MeshDevError> {
    options.validate()?;
    if reference.sampling != options.sampling {
        return Err(MeshDevError::InvalidOption {
            field: "sampling",
            value: format!("{:?}", options.sampling),
            expected: "the sampling the reference was prepared with",
        });
    }
    let (test_bvh, test_samples) = rayon::join(
        || Bvh::new(test, "test"),
        || sample_surface(test, &options.sampling),
    );
    let test_bvh = test_bvh?;
    require_area(test, "test")?;
    let (test_samples, reference_samples) = (test_samples?, &reference.samples);
    let reference_index = &reference.index;
    let signed: Vec<f64> = test_samples
        .points
        .par_iter()
        .map(|p| reference_index.signed_distance(p))
        .collect();
    let unsigned: Vec<f64> = signed.par_iter().map(|s| s.abs()).collect();
    let back: Vec<f64> = reference_samples
        .points
        .par_iter()
        .map(|p| test_bvh.closest(p).distance)
        .collect();
    let quality: Vec<f64> = test
        .vertices
        .par_iter()
        .map(|p| reference_index.signed_distance(p))
        .collect();
    let vertex_distances: Vec<f64> = quality.par_iter().map(|s| s.abs()).collect();

    let tolerance = options.tolerance_mm;
    let (test_to_ref, ref_to_test) = rayon::join(
        || stats::directed(&unsigned, &test_samples.weights, tolerance),
        || stats::directed(&back, &reference_samples.weights, tolerance),
    );
    let bias = stats::weighted_mean(&signed, &test_samples.weights);
    let distances = stats::symmetric(test_to_ref, ref_to_test, bias, &vertex_distances, tolerance);
    let colours = quality
        .par_iter()
        .map(|&s| options.colour_range.colour(s))
        .collect();
    Ok(Comparison {
        distances,
        deviation: DeviationMap { quality, colours },
    })
}
