//! The atlas placed again from a registration: the similarity that best maps its ossicles'
//! surface nodes at rest onto where a registration took them.
//!
//! Why: three landmarks are a thin basis for the start. A pick 0.2 mm off moves the whole
//! placement, and with it the head the stapes is turned about, and the deformable stage keeps
//! much of the pose and size it starts from (the FEM's rest shape). A registration of the
//! whole chain is a better start than its landmarks: `run` registers once without the surface
//! level, places the atlas again by this similarity and registers from there
//! ([`deform_placed_again`]); `landmarks --auto` does the same after its chain search, whose
//! pose is 8-10 % small (`auto_landmarks`).

use std::time::Instant;

use nalgebra::Point3;

use super::DeformSettings;
use super::atlas_fit::{Registered, deform_atlas, place};
use super::chain_search::SCALE_RANGE;
use super::deform::{DeformConfig, DeformError, Steps};
use super::refine::RefineConfig;
use super::rigid::{SimilarityTransform, fit_similarity};
use super::support::registered_support;
use crate::atlas::{Atlas, Part};
use crate::image::Sampler;
use crate::progress::Reporter;

/// The nodes of the ossicles' surfaces, sorted.
pub(crate) fn bone_nodes(atlas: &Atlas) -> Vec<usize> {
    let mut nodes: Vec<usize> = Part::BONES
        .iter()
        .flat_map(|&part| atlas.part_triangles(part))
        .flatten()
        .map(|i| i as usize)
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    nodes
}

/// The similarity that best maps the atlas's `bones` nodes at rest onto `registered`: where
/// to place the atlas for the next registration. `None` for a degenerate fit, or a scale
/// outside `scales`: a chain registered badly (the wrong side's forced on the image, say)
/// shrinks pass by pass.
pub(crate) fn placement_from_registration(
    atlas: &Atlas,
    bones: &[usize],
    registered: &[Point3<f64>],
    scales: (f64, f64),
) -> Option<SimilarityTransform> {
    let rest: Vec<Point3<f64>> = bones.iter().map(|&i| atlas.nodes()[i]).collect();
    let moved: Vec<Point3<f64>> = bones.iter().map(|&i| registered[i]).collect();
    fit_similarity(&rest, &moved, true)
        .map(|fit| fit.transform)
        .filter(|p| (scales.0..=scales.1).contains(&p.scale))
}

/// The scales a placement pass may give the atlas placed at `placed` by its landmarks: the
/// landmark fit's scale times `SCALE_RANGE`. The landmark fit's own size was judged with the
/// landmarks (a third beyond the atlas's is accepted there), so the pass bounds only how far
/// a registration may take it; bounded by the atlas's own size instead (until 2026-11-29),
/// every pass of a chain over 1.25 times the atlas was refused.
fn pass_scales(atlas: &Atlas, bones: &[usize], placed: &[Point3<f64>]) -> (f64, f64) {
    placement_from_registration(atlas, bones, placed, (0.0, f64::INFINITY))
        .map_or(SCALE_RANGE, |fit| {
            (SCALE_RANGE.0 * fit.scale, SCALE_RANGE.1 * fit.scale)
        })
}

/// `deform_atlas` from `placed`, after `settings.deform.placement_passes` registrations that
/// each place the atlas again (`placement_from_registration`). Those registrations are the
/// articulation and the FEM levels only (no surface level, the eardrum following the
/// manubrium): the placement needs the ossicles' pose and size, not their last detail.
/// The registration records the scale of each placement made (`placed_again`) and the
/// passes' time. Every registration keeps the element floors against `placed` (the landmark
/// fit's placement, which `verify` checks a package against), not against the placement it
/// starts from. A pass whose registration fails, or whose placement is refused, ends the
/// passes (logged), and the final registration starts from the placement before it.
pub fn deform_placed_again(
    atlas: &Atlas,
    placed: &[Point3<f64>],
    sampler: &Sampler,
    step: f64,
    settings: DeformSettings,
    progress: &dyn Reporter,
) -> Result<Registered, DeformError> {
    let clock = Instant::now();
    let passes = settings.deform.placement_passes;
    let mut start = placed.to_vec();
    let mut scales = Vec::with_capacity(passes);
    let deform = DeformConfig {
        probe_eardrum: false,
        ..settings.deform.clone()
    };
    let refine = RefineConfig {
        enabled: false,
        ..settings.refine.clone()
    };
    let coarse = DeformSettings {
        articulate: settings.articulate,
        deform: &deform,
        refine: &refine,
        steps: Steps::Chord,
    };
    let bones = bone_nodes(atlas);
    let allowed = pass_scales(atlas, &bones, placed);
    for _ in 0..passes {
        let registered = match deform_atlas(atlas, &start, placed, sampler, step, coarse, progress)
        {
            Ok(registered) => registered,
            Err(e) => {
                progress.log(&format!(
                    "registering the atlas to place it again failed ({e}); registering from the placement before"
                ));
                break;
            }
        };
        let Some(placement) =
            placement_from_registration(atlas, &bones, &registered.deform.positions, allowed)
        else {
            progress.log(
                "the registered ossicles' similarity is degenerate or out of the ossicles' sizes; registering from the placement before",
            );
            break;
        };
        progress.log(&format!(
            "atlas placed again at scale {:.3} (the registered ossicles' similarity)",
            placement.scale
        ));
        start = place(atlas, &placement);
        scales.push(placement.scale);
    }
    let seconds = clock.elapsed().as_secs_f64();
    let mut registered = deform_atlas(atlas, &start, placed, sampler, step, settings, progress)?;
    // measured here, on the registration kept, not on every intermediate one
    registered.edge_support =
        registered_support(atlas, &registered.deform.positions, sampler, step, settings);
    registered.placed_again = scales;
    registered.seconds.placement = seconds;
    Ok(registered)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    /// The atlas moved by a turn, a shift and `scale`, its eardrum's own nodes thrown 3 mm off.
    fn moved_atlas(atlas: &Atlas, scale: f64) -> Vec<Point3<f64>> {
        let bones = bone_nodes(atlas);
        let turn = Rotation3::from_euler_angles(0.2, -0.1, 0.3);
        let shift = Vector3::new(1.0, -2.0, 0.5);
        let mut moved: Vec<Point3<f64>> = atlas
            .nodes()
            .iter()
            .map(|p| Point3::from(turn * p.coords * scale + shift))
            .collect();
        for i in atlas.part_triangles(Part::Eardrum).concat() {
            if bones.binary_search(&(i as usize)).is_err() {
                moved[i as usize] += Vector3::new(3.0, 0.0, 0.0);
            }
        }
        moved
    }

    #[test]
    fn the_next_placement_is_the_similarity_the_ossicles_moved_by() {
        let atlas = crate::atlas::load_atlas(None, None).unwrap();
        let bones = bone_nodes(&atlas);
        let eardrum: Vec<u32> = atlas.part_triangles(Part::Eardrum).concat();
        assert!(
            eardrum
                .iter()
                .any(|i| bones.binary_search(&(*i as usize)).is_err()),
            "the eardrum has nodes of its own"
        );
        // only the ossicles count: the eardrum's nodes may be anywhere
        let moved = moved_atlas(&atlas, 1.1);
        let placement = placement_from_registration(&atlas, &bones, &moved, SCALE_RANGE).unwrap();
        assert!((placement.scale - 1.1).abs() < 1e-9, "{placement:?}");
        for &i in &bones {
            assert!((placement.apply(&atlas.nodes()[i]) - moved[i]).norm() < 1e-9);
        }
    }

    #[test]
    fn a_placement_out_of_the_ossicles_sizes_is_refused() {
        let atlas = crate::atlas::load_atlas(None, None).unwrap();
        let bones = bone_nodes(&atlas);
        for scale in [0.7, 1.3] {
            let moved = moved_atlas(&atlas, scale);
            assert!(placement_from_registration(&atlas, &bones, &moved, SCALE_RANGE).is_none());
        }
        let collapsed = vec![Point3::origin(); atlas.nodes().len()];
        assert!(placement_from_registration(&atlas, &bones, &collapsed, SCALE_RANGE).is_none());
    }

    /// A chain that the landmarks place at 1.3 times the atlas (the CT chain, inflated by its
    /// partial volume, and 10 % larger) may be placed again at that size, and down to 0.8 and up
    /// to 1.25 of it; not beyond.
    #[test]
    fn a_pass_bounds_the_size_relative_to_the_landmark_fit() {
        let atlas = crate::atlas::load_atlas(None, None).unwrap();
        let bones = bone_nodes(&atlas);
        let placed = moved_atlas(&atlas, 1.3);
        let (low, high) = pass_scales(&atlas, &bones, &placed);
        assert!((low - 0.8 * 1.3).abs() < 1e-9 && (high - 1.25 * 1.3).abs() < 1e-9);
        let again = |scale: f64| {
            placement_from_registration(&atlas, &bones, &moved_atlas(&atlas, scale), (low, high))
        };
        assert!(again(1.3).is_some() && again(1.5).is_some() && again(1.1).is_some());
        assert!(again(1.0).is_none() && again(1.7).is_none());
    }
}
