//! One synthetic case from one seed: every random choice (side, spacing, ossicle motions,
//! shape detail, scale, deformation, pose, pick noise, image noise) is drawn from a ChaCha
//! stream seeded by the case seed, in a fixed order, so a seed always gives the same case.
//!
//! Ranges: scale ±10 %; the chain turns by up to 2° relative to the annulus, the malleus and
//! the stapes by up to 3° in their joints; the deformation moves points by up to 0.8 mm with
//! wavelengths of 10-20 mm (gradient bound ≤ 0.51, so the warp is invertible); rotations are
//! uniform over SO(3), translations up to 60 mm per axis; landmark picks are off by a Gaussian
//! of 0.15 mm RMS, cut at 0.3 mm (a careful reader's precision at 0.2 mm voxels).

use nalgebra::{Matrix3, Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::chain_anatomy::{ChainAnatomy, ChainError};
use super::chain_articulation::ChainArticulation;
use super::chain_variation::ChainVariation;
use super::draws::uniform_rotation;
use super::imaging::{Grid, ImagingParams, render};
use super::mesh_chain::MeshChain;
use super::patient::{Chain, PatientAnatomy};
use super::patient_field::{PatientField, label_map};
use super::scene::{CavityParams, EarScene, TissueLevels};
use super::truth::{
    DeformationRecord, GridRecord, LandmarkRecord, PoseRecord, Truth, eardrum_surface,
    ossicle_surfaces, to_patient,
};
use super::variability::{MotionTarget, OssicleMotion, ShapeDetail, apply_motions};
use super::warp::{Deformation, PatientWarp, WaveMode};
use crate::atlas::{Anatomy, AnatomyError, Side};
use crate::ear::Landmarks;
use crate::image::Volume;
use crate::mesh::TriMesh;
use crate::meshdev::structures::DEFAULT_LABELS;

/// Voxel spacings a phantom may have \[mm\] (NewTom 5G-class CBCT).
pub const SPACING_RANGE_MM: (f64, f64) = (0.125, 0.3);
/// Default landmark pick noise (RMS, mm) and its cut-off.
pub const PICK_NOISE_MM: f64 = 0.15;
const PICK_NOISE_MAX_MM: f64 = 0.3;
/// Margin of the field of view around the chain and the eardrum [mm].
const FOV_MARGIN_MM: f64 = 1.5;
/// Sub-samples per axis in boundary voxels.
const SUPERSAMPLE: usize = 3;

/// What the user chooses; the rest is drawn from the seed.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PhantomOptions {
    /// Voxel spacing \[mm\]; drawn in `SPACING_RANGE_MM` when absent.
    pub spacing_mm: Option<f64>,
    /// Image noise SD \[HU\]; the imaging default when absent.
    pub noise_sd_hu: Option<f64>,
    /// Add cone-beam artefacts (cupping, rings, streaks).
    pub artefacts: bool,
    /// The ear's side; drawn when absent.
    pub side: Option<Side>,
    /// Full width at half maximum of the point-spread function \[mm\]; the imaging default
    /// (0.25 mm) when absent.
    pub blur_mm: Option<f64>,
}

/// Errors making a phantom.
#[derive(Debug, thiserror::Error)]
pub enum PhantomError {
    #[error("--spacing {0} mm is outside {min}..={max} mm", min = SPACING_RANGE_MM.0, max = SPACING_RANGE_MM.1)]
    Spacing(f64),
    #[error("--noise {0} HU: expected a finite value from 0 to 1000 HU")]
    Noise(f64),
    #[error("--blur {0} mm: expected a finite value from 0 to 1 mm")]
    Blur(f64),
    #[error(transparent)]
    Chain(#[from] ChainError),
    #[error("phantom seed {seed}: the varied anatomy is invalid: {source}")]
    Anatomy {
        seed: u64,
        #[source]
        source: AnatomyError,
    },
    /// A case could not be written (a file, its image or a mesh).
    #[error(transparent)]
    Write(#[from] crate::io_util::FileError),
    #[error(transparent)]
    WriteImage(#[from] crate::image::ImageError),
    #[error(transparent)]
    WriteMesh(#[from] crate::mesh::io::MeshIoError),
}

impl PhantomOptions {
    /// Checks the user's choices.
    pub fn check(&self) -> Result<(), PhantomError> {
        if let Some(s) = self.spacing_mm
            && !(s.is_finite() && (SPACING_RANGE_MM.0..=SPACING_RANGE_MM.1).contains(&s))
        {
            return Err(PhantomError::Spacing(s));
        }
        if let Some(n) = self.noise_sd_hu
            && !(n.is_finite() && (0.0..=1000.0).contains(&n))
        {
            return Err(PhantomError::Noise(n));
        }
        if let Some(b) = self.blur_mm
            && !(b.is_finite() && (0.0..=1.0).contains(&b))
        {
            return Err(PhantomError::Blur(b));
        }
        Ok(())
    }
}

/// A generated case, in memory.
pub struct PhantomCase {
    pub truth: Truth,
    pub image: Volume,
    /// Label map on the image grid (see `DEFAULT_LABELS`).
    pub labels: Vec<u8>,
    /// True surfaces in patient space, named malleus, incus, stapes (or chain, for a fused
    /// real chain), eardrum.
    pub surfaces: Vec<(&'static str, TriMesh)>,
    /// The landmarks as a reader would pick them (with pick noise).
    pub picked: Landmarks,
}

fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + rng.random::<f64>() * (hi - lo)
}

fn unit_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::from_fn(|_, _| StandardNormal.sample(rng));
        if let Some(u) = v.try_normalize(1e-6) {
            return u;
        }
    }
}

fn draw_motions(spec: &crate::atlas::AnatomySpec, rng: &mut ChaCha8Rng) -> Vec<OssicleMotion> {
    let mut motions = Vec::new();
    let mut current = spec.clone();
    for (target, max_deg) in [
        (MotionTarget::Chain, 2.0),
        (MotionTarget::Malleus, 3.0),
        (MotionTarget::Stapes, 3.0),
    ] {
        let pivot = match target {
            MotionTarget::Stapes => current.joints.incudostapedial.center,
            _ => current.joints.incudomalleolar.center,
        };
        let m = OssicleMotion {
            target,
            pivot,
            axis: unit_vector(rng).into(),
            angle_deg: uniform(rng, 0.3 * max_deg, max_deg),
        };
        current = apply_motions(&current, std::slice::from_ref(&m));
        motions.push(m);
    }
    motions
}

fn draw_deformation(rng: &mut ChaCha8Rng) -> Deformation {
    let total = uniform(rng, 0.5, 0.8);
    let weights: Vec<f64> = (0..6).map(|_| uniform(rng, 0.2, 1.0)).collect();
    let sum: f64 = weights.iter().sum();
    Deformation {
        modes: weights
            .iter()
            .map(|w| {
                let amplitude = unit_vector(rng) * (total * w / sum);
                let wavelength = uniform(rng, 10.0, 20.0);
                let wave = unit_vector(rng) * (std::f64::consts::TAU / wavelength);
                WaveMode {
                    amplitude_mm: amplitude.into(),
                    wave_vector: wave.into(),
                    phase: uniform(rng, 0.0, std::f64::consts::TAU),
                }
            })
            .collect(),
    }
}

fn pick(rng: &mut ChaCha8Rng, p: &Point3<f64>) -> Point3<f64> {
    let sd = PICK_NOISE_MM / 3f64.sqrt();
    loop {
        let e = Vector3::from_fn(|_, _| {
            let z: f64 = StandardNormal.sample(rng);
            sd * z
        });
        if e.norm() <= PICK_NOISE_MAX_MM {
            return p + e;
        }
    }
}

/// The image grid: axis-aligned LPS, covering `points` with a margin, origin on a 1 µm grid.
fn field_of_view(points: impl Iterator<Item = Point3<f64>>, spacing: f64) -> Grid {
    let (mut lo, mut hi) = (
        Point3::from([f64::INFINITY; 3]),
        Point3::from([f64::NEG_INFINITY; 3]),
    );
    for p in points {
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let origin =
        (lo.coords - Vector3::from_element(FOV_MARGIN_MM)).map(|v| (v * 1000.0).floor() / 1000.0);
    let dims =
        [0, 1, 2].map(|c| ((hi[c] + FOV_MARGIN_MM - origin[c]) / spacing).ceil() as usize + 1);
    Grid {
        dims,
        spacing: [spacing; 3],
        origin,
        direction: Matrix3::identity(),
    }
}

/// Generates the case of `seed` from the atlas anatomy.
pub fn generate_case(seed: u64, options: &PhantomOptions) -> Result<PhantomCase, PhantomError> {
    options.check()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (side, spacing) = draw_side_and_spacing(&mut rng, options);
    let invalid = |source| PhantomError::Anatomy { seed, source };
    let base = side_anatomy(side).map_err(invalid)?;
    let motions = draw_motions(base.spec(), &mut rng);
    let anatomy = Anatomy::from_spec(
        apply_motions(base.spec(), &motions),
        &format!("<phantom seed {seed}>"),
    )
    .map_err(invalid)?;
    let detail = ShapeDetail::draw(&anatomy, &mut rng);
    let warp = PatientWarp {
        scale: uniform(&mut rng, 0.9, 1.1),
        deformation: draw_deformation(&mut rng),
        rotation: uniform_rotation(&mut rng),
        translation: Vector3::from_fn(|_, _| uniform(&mut rng, -60.0, 60.0)),
    };
    let cavity = draw_cavity(&mut rng);
    let imaging_seed: u64 = rng.random();
    let exact_atlas = anatomy.landmarks();
    let patient = PatientAnatomy::new(anatomy, detail);
    let [m, i, s] = ossicle_surfaces(&patient);
    let scene = EarScene::new(&patient, TissueLevels::default(), cavity.clone());
    let case = Imaged {
        seed,
        side,
        spacing,
        chain: &patient,
        scene,
        bones: vec![("malleus", m), ("incus", i), ("stapes", s)],
        exact_atlas,
        warp,
        cavity,
        imaging_seed,
    };
    let mut made = case.image(options, &mut rng);
    made.truth.ossicle_motions = motions;
    made.truth.shape_detail = patient.detail().clone();
    Ok(made)
}

/// Whether each case images the real chain as it is, a seeded variation of its shape or a
/// seeded articulation of its ossicles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChainShape {
    AsGiven,
    /// Per case, the chain stretched and sheared by [`ChainVariation::draw`] of its seed.
    Varied,
    /// Per case, the malleus and the stapes turned about their joints by
    /// [`ChainArticulation::draw`] of its seed (a chain with its ossicles apart).
    Articulated,
}

/// A real chain to make phantoms of: its placement in the atlas frame (landmark fit and ICP,
/// the same for every case of one side) is made once per side, when first needed; a varied or
/// articulated chain is placed anew for every case.
pub struct ChainPhantoms {
    chain: ChainAnatomy,
    shape: ChainShape,
    /// The placement on the right, then on the left side.
    placed: [Option<MeshChain>; 2],
}

impl ChainPhantoms {
    pub fn new(chain: ChainAnatomy, shape: ChainShape) -> ChainPhantoms {
        ChainPhantoms {
            chain,
            shape,
            placed: [None, None],
        }
    }

    /// The chain of case `seed` placed on `side` (mirrored when it is the other ear).
    fn placed(&mut self, side: Side, seed: u64) -> Result<&MeshChain, PhantomError> {
        let slot = &mut self.placed[match side {
            Side::Right => 0,
            Side::Left => 1,
        }];
        // as given, each side is placed once; varied or articulated, each case anew
        let placed = match slot.take() {
            Some(placed) if self.shape == ChainShape::AsGiven => placed,
            _ => {
                let chain = match self.shape {
                    ChainShape::AsGiven => self.chain.clone(),
                    ChainShape::Varied => self
                        .chain
                        .varied(ChainVariation::draw(seed, self.chain.centroid())),
                    ChainShape::Articulated => self
                        .chain
                        .articulated(ChainArticulation::draw(seed, &self.chain.landmarks))?,
                };
                let mirrored = side != chain.side;
                let chain = if mirrored { chain.mirrored() } else { chain };
                let atlas =
                    side_anatomy(side).map_err(|source| PhantomError::Anatomy { seed, source })?;
                MeshChain::place(&chain, atlas, mirrored)?
            }
        };
        Ok(slot.insert(placed))
    }
}

/// Generates the case of `seed` whose ossicles are the real chain of `chains` (mirrored to the
/// side drawn or asked for): no ossicle motions, shape detail, scale or deformation of its own
/// (its size is its own), only pose, side, imaging and pick noise are drawn, and the chain's
/// shape variation or articulation when `chains` asks for it.
pub fn generate_chain_case(
    seed: u64,
    options: &PhantomOptions,
    chains: &mut ChainPhantoms,
) -> Result<PhantomCase, PhantomError> {
    options.check()?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (side, spacing) = draw_side_and_spacing(&mut rng, options);
    let placed = chains.placed(side, seed)?;
    let warp = PatientWarp {
        scale: placed.placement().atlas_to_chain.scale,
        deformation: Deformation { modes: Vec::new() },
        rotation: uniform_rotation(&mut rng),
        translation: Vector3::from_fn(|_, _| uniform(&mut rng, -60.0, 60.0)),
    };
    let cavity = draw_cavity(&mut rng);
    let imaging_seed: u64 = rng.random();
    let scene = EarScene::new(placed, TissueLevels::default(), cavity.clone())
        .with_footplate(placed.footplate().clone());
    let case = Imaged {
        seed,
        side,
        spacing,
        chain: placed,
        scene,
        bones: placed
            .meshes()
            .iter()
            .map(|(k, m)| (k.name(), m.clone()))
            .collect(),
        exact_atlas: placed.landmarks(),
        warp,
        cavity,
        imaging_seed,
    };
    let mut made = case.image(options, &mut rng);
    if placed.is_fused() {
        made.truth.labels = vec![
            (DEFAULT_LABELS[0].0, "chain".into()),
            (DEFAULT_LABELS[3].0, DEFAULT_LABELS[3].1.into()),
        ];
    }
    made.truth.anatomy = Some(placed.placement().clone());
    Ok(made)
}

fn draw_side_and_spacing(rng: &mut ChaCha8Rng, options: &PhantomOptions) -> (Side, f64) {
    let drawn_side = if rng.random::<bool>() {
        Side::Left
    } else {
        Side::Right
    };
    let drawn_spacing =
        (uniform(rng, SPACING_RANGE_MM.0, SPACING_RANGE_MM.1) * 1000.0).round() / 1000.0;
    (
        options.side.unwrap_or(drawn_side),
        options.spacing_mm.unwrap_or(drawn_spacing),
    )
}

/// The atlas anatomy on `side`.
fn side_anatomy(side: Side) -> Result<Anatomy, AnatomyError> {
    let right = Anatomy::default_right()?;
    match side {
        Side::Right => Ok(right),
        Side::Left => right.mirrored(),
    }
}

fn draw_cavity(rng: &mut ChaCha8Rng) -> CavityParams {
    CavityParams {
        wall_phase: uniform(rng, 0.0, std::f64::consts::TAU),
        ..CavityParams::default()
    }
}

/// A patient ready to image: its chain and scene in the atlas frame, the true bone surfaces
/// there, and the warp into the scanner.
struct Imaged<'a> {
    seed: u64,
    side: Side,
    spacing: f64,
    chain: &'a dyn Chain,
    scene: EarScene<'a>,
    bones: Vec<(&'static str, TriMesh)>,
    exact_atlas: Landmarks,
    warp: PatientWarp,
    cavity: CavityParams,
    imaging_seed: u64,
}

impl Imaged<'_> {
    /// Renders the image and the label map, picks the landmarks, and writes the truth record
    /// (without the atlas-specific motions, detail and chain placement).
    fn image(self, options: &PhantomOptions, rng: &mut ChaCha8Rng) -> PhantomCase {
        let warp = &self.warp;
        // truth surfaces, then the field of view around them
        let drum = eardrum_surface(self.chain.anatomy().eardrum());
        let surfaces: Vec<(&'static str, TriMesh)> = self
            .bones
            .into_iter()
            .chain(std::iter::once(("eardrum", drum)))
            .map(|(n, mesh)| (n, to_patient(&mesh, warp)))
            .collect();
        let grid = field_of_view(
            surfaces
                .iter()
                .flat_map(|(_, m)| m.vertices.iter().copied()),
            self.spacing,
        );

        let mut imaging = ImagingParams {
            supersample: SUPERSAMPLE,
            ..ImagingParams::clean(self.imaging_seed)
        };
        if let Some(noise) = options.noise_sd_hu {
            imaging.noise_sd_hu = noise;
        }
        if let Some(blur) = options.blur_mm {
            imaging.psf_fwhm_mm = blur;
        }
        if options.artefacts {
            imaging.cupping_hu = 80.0;
            imaging.rings = 3;
            imaging.ring_amplitude_hu = 40.0;
            imaging.streaks = 2;
            imaging.streak_amplitude_hu = 120.0;
        }
        let levels = self.scene.levels().clone();
        let field = PatientField {
            scene: self.scene,
            warp,
        };
        let image = render(&field, &grid, &imaging);
        let labels = label_map(self.chain, warp, &grid);

        let exact = Landmarks::from_points(self.exact_atlas.points().map(|p| warp.to_patient(&p)));
        let picked = Landmarks::from_points(exact.points().map(|p| pick(rng, &p)));
        let truth = Truth {
            generator: format!("otoatlas phantom {}", env!("CARGO_PKG_VERSION")),
            seed: self.seed,
            side: self.side,
            anatomy: None,
            landmarks: LandmarkRecord::from(&exact),
            landmarks_picked: LandmarkRecord::from(&picked),
            pick_noise_sd_mm: PICK_NOISE_MM,
            pose: PoseRecord::from(warp),
            ossicle_motions: Vec::new(),
            deformation: deformation_record(warp, &grid),
            shape_detail: ShapeDetail::default(),
            image: GridRecord {
                dims: grid.dims,
                spacing_mm: grid.spacing,
                origin: grid.origin.into(),
                direction: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            },
            imaging,
            tissue_levels: levels,
            cavity: self.cavity,
            labels: DEFAULT_LABELS
                .iter()
                .map(|(l, n)| (*l, n.to_string()))
                .collect(),
        };
        PhantomCase {
            truth,
            image,
            labels,
            surfaces,
            picked,
        }
    }
}

/// The deformation's record, with its largest displacement and smallest Jacobian determinant
/// over the field of view (every 0.5 mm).
fn deformation_record(warp: &PatientWarp, grid: &Grid) -> DeformationRecord {
    let d = &warp.deformation;
    let step = 0.5;
    let n = |c: usize| ((grid.dims[c] as f64 * grid.spacing[c]) / step).ceil() as usize + 1;
    let (mut max_disp, mut min_det) = (0.0f64, f64::INFINITY);
    for k in 0..n(2) {
        for j in 0..n(1) {
            for i in 0..n(0) {
                let x =
                    Point3::from(grid.origin + Vector3::new(i as f64, j as f64, k as f64) * step);
                let w = warp
                    .rotation
                    .inverse_transform_vector(&(x.coords - warp.translation));
                max_disp = max_disp.max(d.displacement(&w).norm());
                min_det = min_det.min((Matrix3::identity() + d.jacobian(&w)).determinant());
            }
        }
    }
    DeformationRecord {
        field: d.clone(),
        displacement_bound_mm: d.displacement_bound(),
        gradient_bound: d.gradient_bound(),
        max_displacement_mm: max_disp,
        min_jacobian_determinant: min_det,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_deformations_stay_within_0_8_mm_and_invertible() {
        for seed in 0..40 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let d = draw_deformation(&mut rng);
            assert!(d.displacement_bound() <= 0.8 + 1e-12);
            let g = d.gradient_bound();
            assert!(g < 0.52, "seed {seed}: gradient bound {g}");
            // sampled: displacement within the bound, Jacobian determinant at least (1 - g)³
            for _ in 0..200 {
                let w = Vector3::from_fn(|_, _| uniform(&mut rng, -30.0, 30.0));
                assert!(d.displacement(&w).norm() <= d.displacement_bound());
                let det = (Matrix3::identity() + d.jacobian(&w)).determinant();
                assert!(det >= (1.0 - g).powi(3) - 1e-12, "seed {seed}: {det}");
            }
        }
    }

    #[test]
    fn rotations_are_proper_and_spread_over_so3() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let n = 2000;
        let mut mean_z = Vector3::zeros();
        for _ in 0..n {
            let r = uniform_rotation(&mut rng);
            assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
            mean_z += r * Vector3::z();
        }
        // a uniform rotation sends a fixed axis uniformly over the sphere: mean near zero
        assert!((mean_z / n as f64).norm() < 0.06);
    }

    #[test]
    fn options_outside_their_ranges_are_refused() {
        for spacing in [0.1, 0.31, f64::NAN] {
            let o = PhantomOptions {
                spacing_mm: Some(spacing),
                ..PhantomOptions::default()
            };
            assert!(matches!(o.check(), Err(PhantomError::Spacing(_))));
        }
        let o = PhantomOptions {
            noise_sd_hu: Some(-1.0),
            ..PhantomOptions::default()
        };
        assert!(matches!(o.check(), Err(PhantomError::Noise(_))));
        for blur in [-0.1, 1.5, f64::INFINITY] {
            let o = PhantomOptions {
                blur_mm: Some(blur),
                ..PhantomOptions::default()
            };
            assert!(matches!(o.check(), Err(PhantomError::Blur(_))), "{blur}");
        }
        assert!(PhantomOptions::default().check().is_ok());
    }
}
