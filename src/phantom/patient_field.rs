//! The patient in the scanner: the ear's tissue field and its label map in LPS patient space,
//! each point pulled back into the atlas frame by the explicit inverse warp.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::drum::drum_position;
use super::imaging::{FieldSample, Grid, TissueField};
use super::patient::{Chain, ChainTissue};
use super::scene::EarScene;
use super::warp::PatientWarp;
use crate::meshdev::structures::DEFAULT_LABELS;

/// The tissue field of a patient in scanner space.
pub struct PatientField<'a> {
    pub scene: EarScene<'a>,
    pub warp: &'a PatientWarp,
}

impl TissueField for PatientField<'_> {
    fn sample(&self, x: &Point3<f64>, footprint_mm: f64) -> FieldSample {
        let a = self.warp.to_atlas(x);
        let atlas = self.scene.sample(&a, footprint_mm / self.warp.scale);
        FieldSample {
            hu: atlas.hu,
            clearance_mm: atlas.clearance_mm / self.warp.inverse_lipschitz(),
        }
    }
}

/// The label map of the ossicles and the eardrum on `grid` (i fastest), numbered as
/// `meshdev`'s default structures (1 malleus, 2 incus, 3 stapes, 4 eardrum, 0 none): an
/// ossicle where the
/// voxel centre lies in it; the eardrum where the membrane passes within half a voxel of the
/// centre (a one-voxel sheet, since the real one is far thinner than a voxel).
pub fn label_map(patient: &dyn Chain, warp: &PatientWarp, grid: &Grid) -> Vec<u8> {
    let eardrum = patient.anatomy().eardrum();
    let [nx, ny, nz] = grid.dims;
    let half_voxel = 0.5 * grid.spacing.iter().copied().fold(0.0, f64::max) / warp.scale;
    let mut labels = vec![0u8; nx * ny * nz];
    labels
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, out)| {
            for j in 0..ny {
                for i in 0..nx {
                    let x = grid.world(Vector3::new(i as f64, j as f64, k as f64));
                    let a = warp.to_atlas(&x);
                    // outside the chain's box, the chain is nothing (far = 0)
                    match patient.distances(&a, 0.0).tissue() {
                        Some(ChainTissue::Bone(o)) => {
                            out[i + nx * j] = DEFAULT_LABELS[o as usize].0 as u8;
                            continue;
                        }
                        Some(ChainTissue::Soft) => continue,
                        None => {}
                    }
                    let drum = drum_position(eardrum, &a);
                    if drum.s <= 1.0 && drum.height.abs() <= half_voxel {
                        out[i + nx * j] = DEFAULT_LABELS[3].0 as u8;
                    }
                }
            }
        });
    labels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atlas::Anatomy;
    use crate::phantom::imaging::{ImagingParams, render};
    use crate::phantom::patient::PatientAnatomy;
    use crate::phantom::scene::{CavityParams, TissueLevels};
    use crate::phantom::variability::ShapeDetail;
    use crate::phantom::warp::{Deformation, WaveMode};
    use nalgebra::{Matrix3, Rotation3};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// The same field, but never claiming a clearance: every voxel is supersampled.
    struct Everywhere<'a>(&'a PatientField<'a>);

    impl TissueField for Everywhere<'_> {
        fn sample(&self, p: &Point3<f64>, footprint_mm: f64) -> FieldSample {
            FieldSample {
                clearance_mm: 0.0,
                ..self.0.sample(p, footprint_mm)
            }
        }
    }

    #[test]
    fn adaptive_supersampling_equals_supersampling_every_voxel() {
        // a left ear with surface detail
        let anatomy = Anatomy::default_right().unwrap().mirrored().unwrap();
        let detail = ShapeDetail::draw(&anatomy, &mut ChaCha8Rng::seed_from_u64(4));
        let patient = PatientAnatomy::new(anatomy, detail);
        let warp = PatientWarp {
            scale: 0.95,
            deformation: Deformation {
                modes: vec![WaveMode {
                    amplitude_mm: [0.4, -0.3, 0.2],
                    wave_vector: [0.3, -0.2, 0.4],
                    phase: 1.0,
                }],
            },
            rotation: Rotation3::from_euler_angles(0.4, 2.0, -0.7),
            translation: Vector3::new(-20.0, 35.0, 4.0),
        };
        let scene = EarScene::new(&patient, TissueLevels::default(), CavityParams::default());
        let field = PatientField { scene, warp: &warp };
        // a 6 mm cube around the umbo: manubrium, eardrum sheet, canal, cavity
        let umbo = warp.to_patient(&patient.anatomy().landmarks().umbo);
        let grid = Grid {
            dims: [20, 20, 20],
            spacing: [0.3; 3],
            origin: umbo.coords - Vector3::from_element(3.0),
            direction: Matrix3::identity(),
        };
        let params = ImagingParams {
            noise_sd_hu: 0.0,
            psf_fwhm_mm: 0.0,
            ..ImagingParams::clean(1)
        };
        let adaptive = render(&field, &grid, &params);
        let full = render(&Everywhere(&field), &grid, &params);
        let worst = adaptive
            .data
            .iter()
            .zip(&full.data)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 0.01, "largest difference {worst} HU");
        // the sheet shows as partial volume: values strictly between air and soft tissue
        let partial = adaptive
            .data
            .iter()
            .filter(|v| **v > -990.0 && **v < -100.0)
            .count();
        assert!(partial > 50, "{partial} partial-volume voxels");
    }
}
