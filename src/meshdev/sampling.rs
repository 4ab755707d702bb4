//! Deterministic, area-weighted point samples of a triangle surface.
//!
//! The metrics are area-weighted (docs/metrics.md, after Metro and MESH), so the samples
//! are too. Two schemes:
//!
//! * `Sampling::Area` (default): **systematic area sampling**. The surface's cumulative area
//!   is cut into `count` equal strata; sample k sits at cumulative area
//!   `(k + u₀)/count · A`, which picks its triangle, so each triangle receives
//!   ⌊count·Aₜ/A⌋ or ⌈count·Aₜ/A⌉ samples (count proportional to area, zero-area triangles
//!   none). Inside the triangle the point is uniform (`s = √r₁`, barycentric
//!   `(1 − s, s(1 − r₂), s·r₂)`). `u₀`, `r₁`, `r₂` come from SplitMix64 of the explicit seed and
//!   k, so the samples are identical across runs and thread counts. Every sample carries the
//!   weight A/count (mm²). Default count: 10 per triangle as Metro, clamped to
//!   [`MIN_DEFAULT_SAMPLES`, `MAX_DEFAULT_SAMPLES`].
//! * `Sampling::VertexAreas`: the vertices, each with weight `w_v = ⅓·Σ` area of its incident
//!   triangles (vertices on no triangle are dropped).

use nalgebra::Point3;
use rayon::prelude::*;

use super::error::MeshDevError;
use crate::mesh::TriMesh;
use crate::mesh::spatial::validate_mesh;

/// Fewest samples the default count gives (per surface).
pub const MIN_DEFAULT_SAMPLES: usize = 10_000;
/// Most samples the default count gives (per surface).
pub const MAX_DEFAULT_SAMPLES: usize = 1_000_000;
/// Most area samples a caller may ask for per surface (about 64 bytes of working memory
/// each in `compare`: 3.2 GB).
pub const MAX_SAMPLES: usize = 50_000_000;
/// Default seed of the area sampler.
pub const DEFAULT_SEED: u64 = 0x007A_71A5;

/// How a surface is turned into weighted sample points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampling {
    /// Systematic area sampling; `count: None` means 10 per triangle, clamped to
    /// [`MIN_DEFAULT_SAMPLES`, `MAX_DEFAULT_SAMPLES`].
    Area { count: Option<usize>, seed: u64 },
    /// Vertices weighted by a third of their incident triangle areas.
    VertexAreas,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling::Area {
            count: None,
            seed: DEFAULT_SEED,
        }
    }
}

impl Sampling {
    /// Checks an explicit sample count: 1 ..= `MAX_SAMPLES`.
    pub fn validate(&self) -> Result<(), MeshDevError> {
        match *self {
            Sampling::Area {
                count: Some(count), ..
            } if !(1..=MAX_SAMPLES).contains(&count) => Err(MeshDevError::InvalidOption {
                field: "sampling.count",
                value: count.to_string(),
                expected: "1 ..= 50,000,000 samples per surface",
            }),
            _ => Ok(()),
        }
    }
}

/// Sample points and their area weights (mm²); the weights sum to the surface area.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    pub points: Vec<Point3<f64>>,
    pub weights: Vec<f64>,
}

/// SplitMix64 (Steele, Lea & Flood 2014) of `x`, as a uniform number in [0, 1).
fn unit(x: u64) -> f64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Samples `mesh` by `scheme`; a surface of zero area gives no samples.
pub fn sample_surface(mesh: &TriMesh, scheme: &Sampling) -> Result<Samples, MeshDevError> {
    validate_mesh(mesh, "sampled")?;
    scheme.validate()?;
    Ok(match *scheme {
        Sampling::Area { count, seed } => {
            let count = count.unwrap_or_else(|| {
                (10 * mesh.triangles.len()).clamp(MIN_DEFAULT_SAMPLES, MAX_DEFAULT_SAMPLES)
            });
            area_samples(mesh, count, seed)
        }
        Sampling::VertexAreas => vertex_samples(mesh),
    })
}

fn area_samples(mesh: &TriMesh, count: usize, seed: u64) -> Samples {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in 0..mesh.triangles.len() {
        total += mesh.triangle_area(t);
        cumulative.push(total);
    }
    if count == 0 || total <= 0.0 {
        return Samples::default();
    }
    let base = seed.wrapping_mul(0xD1B5_4A32_D192_ED03);
    let offset = unit(base);
    let last = cumulative.len() - 1;
    let points = (0..count)
        .into_par_iter()
        .map(|k| {
            let target = (k as f64 + offset) / count as f64 * total;
            let t = cumulative.partition_point(|&c| c <= target).min(last);
            let key = base ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let s = unit(key).sqrt();
            let r2 = unit(key ^ 0x5851_F42D_4C95_7F2D);
            let [a, b, c] = mesh.corners(t);
            Point3::from(a.coords * (1.0 - s) + b.coords * (s * (1.0 - r2)) + c.coords * (s * r2))
        })
        .collect();
    Samples {
        points,
        weights: vec![total / count as f64; count],
    }
}

fn vertex_samples(mesh: &TriMesh) -> Samples {
    let mut weight = vec![0.0; mesh.vertices.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let third = mesh.triangle_area(t) / 3.0;
        for &v in tri {
            weight[v as usize] += third;
        }
    }
    let (points, weights) = mesh
        .vertices
        .iter()
        .zip(&weight)
        .filter(|&(_, &w)| w > 0.0)
        .map(|(p, &w)| (*p, w))
        .unzip();
    Samples { points, weights }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::shapes;

    #[test]
    fn area_samples_are_deterministic_and_proportional_to_area() {
        // A box of faces 1×1 (two), 1×3 and 3×1 (four): area 14; sample counts per face must
        // be within one of count·A_face/A.
        let m = shapes::box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 3.0), 1);
        let scheme = Sampling::Area {
            count: Some(1400),
            seed: 3,
        };
        let s = sample_surface(&m, &scheme).unwrap();
        assert_eq!(s, sample_surface(&m, &scheme).unwrap());
        assert_eq!(s.points.len(), 1400);
        assert!((s.weights.iter().sum::<f64>() - 14.0).abs() < 1e-9);
        let on = |p: &Point3<f64>, axis: usize, value: f64| (p[axis] - value).abs() < 1e-12;
        for (axis, value, expected) in [(2, 0.0, 100), (2, 3.0, 100), (0, 0.0, 300), (1, 1.0, 300)]
        {
            let n = s.points.iter().filter(|p| on(p, axis, value)).count();
            assert!(n.abs_diff(expected) <= 2, "face {axis}={value}: {n}");
        }
        // Every sample lies on the box surface.
        for p in &s.points {
            let inside = (0..3).all(|k| p[k] >= -1e-12 && p[k] <= [1.0, 1.0, 3.0][k] + 1e-12);
            let on_face = (0..3).any(|k| on(p, k, 0.0) || on(p, k, [1.0, 1.0, 3.0][k]));
            assert!(inside && on_face);
        }
        let other = sample_surface(
            &m,
            &Sampling::Area {
                count: Some(1400),
                seed: 4,
            },
        )
        .unwrap();
        assert_ne!(s.points, other.points);
    }

    #[test]
    fn vertex_weights_are_a_third_of_incident_areas() {
        let m = shapes::box_mesh(Point3::origin(), Point3::new(2.0, 2.0, 2.0), 2);
        let s = sample_surface(&m, &Sampling::VertexAreas).unwrap();
        assert_eq!(s.points.len(), m.vertices.len());
        assert!((s.weights.iter().sum::<f64>() - 24.0).abs() < 1e-12);
        // Every triangle has area ½, so w_v = (number of incident triangles)·½/3.
        for (p, w) in s.points.iter().zip(&s.weights) {
            let v = m.vertices.iter().position(|q| q == p).unwrap() as u32;
            let incident = m.triangles.iter().filter(|t| t.contains(&v)).count();
            assert!((w - incident as f64 * 0.5 / 3.0).abs() < 1e-12);
        }
    }
}
