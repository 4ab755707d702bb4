//! The case report on a synthetic case: the embedded atlas on a striped volume, a
//! "segmentation" that is the atlas moved by 0.1 mm, and hand-made scores.

use std::collections::BTreeMap;

use base64::Engine;
use nalgebra::{Matrix3, Point3, Vector3};
use serde_json::{Value, json};

use super::*;
use crate::image::{ImageInfo, Volume};
use crate::register::rigid::SimilarityTransform;
use crate::report::metrics::Scores;
use crate::report::metrics::distances_json;
use crate::report::slices::OVERLAY_PIXELS;

struct Fixture {
    atlas: Atlas,
    image: LoadedImage,
    rigid: Vec<Point3<f64>>,
    registered: Vec<Point3<f64>>,
    reference: BTreeMap<String, TriMesh>,
    deviation: BTreeMap<String, (TriMesh, Vec<f64>)>,
    scores: Scores,
    deform: DeformRecord,
    fit: RigidFit,
}

fn fixture() -> Fixture {
    let atlas = crate::atlas::default_atlas().unwrap();
    let registered = atlas.nodes().to_vec();
    let shift = |d: Vector3<f64>| registered.iter().map(|p| p + d).collect::<Vec<_>>();
    let rigid = shift(Vector3::new(0.3, 0.0, 0.0));
    let truth = shift(Vector3::new(0.0, 0.1, 0.0));
    let (mut lo, mut hi) = (registered[0], registered[0]);
    for p in &registered {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let spacing = 0.25;
    let dims = ((hi - lo) / spacing).map(|e| e.ceil() as usize + 17);
    let dims = [dims.x, dims.y, dims.z];
    let data = (0..dims[0] * dims[1] * dims[2])
        .map(|n| ((n % dims[0] + n / dims[0]) % 20) as f32 * 150.0 - 1000.0)
        .collect();
    let image = LoadedImage {
        volume: Volume {
            dims,
            spacing: [spacing; 3],
            origin: lo.coords - Vector3::repeat(2.0),
            direction: Matrix3::identity(),
            data,
        },
        info: ImageInfo {
            format: "nifti1".into(),
            modality: "CT".into(),
            transfer_syntax: String::new(),
            transfer_syntax_name: String::new(),
            slices: dims[2],
            files: 1,
            series_uid_sha256: None,
            laterality: None,
            warnings: vec!["qform used".into()],
            notes: vec![],
        },
    };
    let mut reference = BTreeMap::new();
    let mut deviation = BTreeMap::new();
    for part in Part::STRUCTURES {
        let mesh = atlas.part_surface(part, &truth);
        deviation.insert(
            part.name().to_string(),
            (mesh.clone(), vec![0.1; mesh.vertices.len()]),
        );
        reference.insert(part.name().to_string(), mesh);
    }
    let scores: Scores = serde_json::from_value(json!({
        "malleus": {"registered": distances_json(0.045, 0.14, -0.012, 0.978),
                    "rigid": distances_json(0.15, 0.35, 0.084, 0.648), "masd_improvement": 0.7},
        "incus": {"registered": distances_json(0.033, 0.6, 0.007, 0.993),
                  "rigid": distances_json(0.113, 0.247, 0.007, 0.764), "masd_improvement": 0.708},
        "stapes": {"registered": distances_json(0.064, 0.235, 0.041, 0.926),
                   "rigid": distances_json(0.121, 0.388, 0.041, 0.796), "masd_improvement": 0.471,
                   "far_mm": 0.5,
                   "by_region": {
                       "stapes": {"label": 7, "area_mm2": 17.0, "mean_signed_mm": 0.1,
                                  "mean_abs_mm": 0.12, "max_abs_mm": 0.8,
                                  "far_outside_share": 0.25, "far_inside_share": 0.05},
                       "incudostapedial_joint": {"label": 9, "area_mm2": 1.0,
                                  "mean_signed_mm": 0.01, "mean_abs_mm": 0.02,
                                  "max_abs_mm": 0.1, "far_outside_share": 0.0,
                                  "far_inside_share": 0.0}}},
        "eardrum": {"registered": distances_json(0.033, 0.137, 0.019, 0.974),
                    "rigid": null, "masd_improvement": null},
    }))
    .unwrap();
    let deform = serde_json::from_value(json!({
        "articulation": null,
        "status": {"status": "converged", "reason": "plateau", "mean_offset_mm": 0.1},
        "iterations": 3,
        "history": (1..=3).map(|i| json!({"iteration": i, "borders_found": 100,
            "borders_used": 90, "mean_offset_mm": 0.3 / i as f64, "max_update_mm": 0.3,
            "p99_update_mm": 0.2 / (i * i) as f64, "spring_scale": 1.0})).collect::<Vec<_>>(),
        "refinement": null,
        "eardrum": {"free_nodes": 10, "found_last_round": 9, "mean_offset_mm": 0.05},
        "probe_step_mm": 0.25,
    }))
    .unwrap();
    let fit = RigidFit {
        transform: SimilarityTransform::new(Matrix3::identity(), Vector3::zeros(), 1.0476),
        residuals_mm: vec![0.078, 0.061, 0.085],
        rms_mm: 0.075,
    };
    Fixture {
        atlas,
        image,
        rigid,
        registered,
        reference,
        deviation,
        scores,
        deform,
        fit,
    }
}

/// Changes the fixture's deform record through its JSON form (as an older or another run's
/// record would read).
fn edit_deform(f: &mut Fixture, edit: impl FnOnce(&mut Value)) {
    let mut value = serde_json::to_value(&f.deform).unwrap();
    edit(&mut value);
    f.deform = serde_json::from_value(value).unwrap();
}

fn html(f: &Fixture, accuracy: Accuracy) -> String {
    html_with(f, accuracy, None)
}

fn html_with(
    f: &Fixture,
    accuracy: Accuracy,
    mechanics: Option<&crate::mechanics::Validation>,
) -> String {
    html_warned(f, accuracy, mechanics, &[])
}

fn html_warned(
    f: &Fixture,
    accuracy: Accuracy,
    mechanics: Option<&crate::mechanics::Validation>,
    landmark_warnings: &[LandmarkWarning],
) -> String {
    html_proposed(f, accuracy, mechanics, landmark_warnings, None)
}

fn html_proposed(
    f: &Fixture,
    accuracy: Accuracy,
    mechanics: Option<&crate::mechanics::Validation>,
    landmark_warnings: &[LandmarkWarning],
    proposed: Option<Proposed>,
) -> String {
    let sampler = Sampler::new(&f.image.volume).unwrap();
    case_report_html(&CaseReportInput {
        case_id: "case-<7>",
        image: &f.image,
        sampler: &sampler,
        side: Side::Right,
        side_source: "landmark file",
        atlas: &f.atlas,
        condition: crate::mechanics::Condition::Normal,
        fit: &f.fit,
        landmark_warnings,
        landmarks: &f.atlas.landmark_positions(&f.rigid),
        proposed,
        rigid_nodes: &f.rigid,
        registered_nodes: &f.registered,
        deform: &f.deform,
        accuracy,
        mechanics,
        timings: &[("ingest", 0.5), ("deform", 1.25)],
        total_seconds: 2.0,
    })
    .unwrap()
}

/// The inline PNGs, decoded: (width, height, RGB pixels).
fn pngs(html: &str) -> Vec<(u32, u32, Vec<[u8; 3]>)> {
    html.split("data:image/png;base64,")
        .skip(1)
        .map(|rest| {
            let b64 = &rest[..rest.find('"').unwrap()];
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap();
            let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
                .read_info()
                .unwrap();
            let mut buf = vec![0; reader.output_buffer_size().unwrap()];
            let info = reader.next_frame(&mut buf).unwrap();
            assert_eq!(info.color_type, png::ColorType::Rgb);
            let pixels = buf[..info.buffer_size()]
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect();
            (info.width, info.height, pixels)
        })
        .collect()
}

fn count(images: &[(u32, u32, Vec<[u8; 3]>)], colour: [u8; 3]) -> usize {
    images
        .iter()
        .flat_map(|i| i.2.iter())
        .filter(|p| **p == colour)
        .count()
}

fn is_self_contained(html: &str) {
    for needle in ["<script", "<link", "<iframe", "url(", "@import", "href="] {
        assert!(!html.contains(needle), "{needle}");
    }
    assert_eq!(
        html.matches(" src=\"").count(),
        html.matches(" src=\"data:image/png;base64,").count(),
        "every image inline"
    );
    assert!(html.contains("<title>otoatlas case report: case-&lt;7&gt;</title>"));
}

#[test]
fn scored_case_shows_every_section_with_its_numbers() {
    let f = fixture();
    let html = html(
        &f,
        Accuracy::Scored {
            scores: &f.scores,
            deviation: f
                .deviation
                .iter()
                .map(|(n, (m, d))| (n.as_str(), (m, d.as_slice())))
                .collect(),
            reference: &f.reference,
        },
    );
    is_self_contained(&html);
    // summary: geometry, side, landmarks, scale, deformable stage, timings, ingest warnings
    for needle in [
        "<td>0.250 × 0.250 × 0.250</td>",
        "<td>LPS</td>",
        "<td>right (from the landmark file)</td>",
        "<td>incudostapedial</td><td>0.085</td>",
        "<td>RMS</td><td>0.075</td>",
        "<td>1.0476</td>",
        "<td>converged, 3 iterations</td>",
        "<td>deform</td><td>1.25</td>",
        "<td>total</td><td>2.00</td>",
        "ingest: qform used",
    ] {
        assert!(html.contains(needle), "{needle}");
    }
    // one row per structure, in anatomical order, rigid and registered side by side
    let rows = [
        "<tr><td>malleus</td><td>0.150</td><td>0.045</td><td>70 %</td><td>0.350</td><td>0.140</td><td>0.084</td><td>-0.012</td><td>0.648</td><td>0.978</td><td>0.440</td><td>met</td></tr>",
        "<tr><td>incus</td><td>0.113</td><td>0.033</td><td>71 %</td><td>0.247</td><td>0.600</td><td>0.007</td><td>0.007</td><td>0.764</td><td>0.993</td><td>0.900</td><td>missed</td></tr>",
        "<tr><td>stapes</td><td>0.121</td><td>0.064</td><td>47 %</td><td>0.388</td><td>0.235</td><td>0.041</td><td>0.041</td><td>0.796</td><td>0.926</td><td>0.535</td><td>met</td></tr>",
        "<tr><td>eardrum</td><td>–</td><td>0.033</td><td>–</td><td>–</td><td>0.137</td><td>–</td><td>0.019</td><td>–</td><td>0.974</td><td>0.437</td><td>–</td></tr>",
    ];
    let at: Vec<usize> = rows
        .iter()
        .map(|r| html.find(r).unwrap_or_else(|| panic!("{r}")))
        .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "anatomical order");
    assert!(html.contains("Missing the targets (MASD ≤ 0.2 mm and HD95 ≤ 0.5 mm): incus."));
    // where the distances lie: the stapes's far region, 17 × 0.3 of its 18 mm², and not the
    // joint beside it, which has none
    assert!(html.contains(
        "<tr><td>stapes</td><td>stapes</td><td>17.00</td><td>0.100</td><td>0.800</td><td>25.0 %</td><td>5.0 %</td><td>28.3 %</td></tr>"
    ));
    assert!(!html.contains("<td>incudostapedial_joint</td>"));
    // four histograms and the convergence curve
    assert_eq!(html.matches("<svg").count(), 5);
    assert!(html.contains("99th percentile nodal update"));
    // nine overlays that decode to the expected size, with the three contours
    let images = pngs(&html);
    assert_eq!(images.len(), 9);
    for (w, h, _) in &images {
        assert_eq!((*w, *h), (OVERLAY_PIXELS as u32, OVERLAY_PIXELS as u32));
    }
    for colour in [RIGID_COLOUR, REGISTERED_COLOUR, SEGMENTATION_COLOUR] {
        assert!(count(&images, colour) > 500, "{colour:?}");
    }
    let grey = images
        .iter()
        .flat_map(|i| i.2.iter())
        .filter(|p| p[0] == p[1] && p[1] == p[2] && p[0] > 0 && p[0] < 255)
        .count();
    assert!(
        grey > 9 * OVERLAY_PIXELS * OVERLAY_PIXELS / 2,
        "CT grey: {grey}"
    );
}

#[test]
fn without_a_segmentation_the_page_says_so_and_shows_the_atlas_contours() {
    let f = fixture();
    let html = html(&f, Accuracy::NoSegmentation);
    is_self_contained(&html);
    assert!(html.contains("The case has no manual segmentation: no surface distances."));
    assert!(html.contains("The case has no manual segmentation: no distances."));
    assert!(!html.contains("<td>malleus</td>"));
    assert!(!html.contains("Where the distances lie"));
    assert_eq!(
        html.matches("<svg").count(),
        1,
        "the convergence curve only"
    );
    let images = pngs(&html);
    assert_eq!(images.len(), 9);
    assert!(count(&images, RIGID_COLOUR) > 500);
    assert!(count(&images, REGISTERED_COLOUR) > 500);
    assert_eq!(count(&images, SEGMENTATION_COLOUR), 0);
}

#[test]
fn a_run_resumed_past_score_shows_the_stored_scores_and_says_what_is_missing() {
    let f = fixture();
    let html = html(&f, Accuracy::Resumed { scores: &f.scores });
    is_self_contained(&html);
    assert!(html.contains("<tr><td>stapes</td><td>0.121</td><td>0.064</td>"));
    assert!(html.contains("the distances below are the earlier run&#39;s"));
    assert!(html.contains("the per-vertex distances are not in memory"));
    assert_eq!(html.matches("<svg").count(), 1);
    assert_eq!(count(&pngs(&html), SEGMENTATION_COLOUR), 0);
}

#[test]
fn the_surface_level_decides_the_verdict_after_coarse_fem_levels() {
    let mut f = fixture();
    edit_deform(&mut f, |d| {
        d["status"] = json!({"status": "max_iterations"});
        d["refinement"] = json!({"rounds": 7, "mean_offset_first_mm": 0.138,
            "mean_offset_last_mm": 0.054, "found_fraction": 0.74, "max_move_mm": 0.6,
            "stiffened_nodes": 300, "stop": "plateau"});
    });
    let page = html(&f, Accuracy::NoSegmentation);
    assert!(page.contains(
        "<p class=\"ok\">The deformable registration converged: the FEM levels (3 iterations) \
         then the surface level (7 rounds, mean distance to the bone borders 0.138 → 0.054 mm); \
         stop: the distance stopped falling.</p>"
    ));
    assert!(page.contains(
        "<td>FEM levels max_iterations, 3 iterations; surface level 7 rounds, stop plateau, \
         0.054 mm from the bone borders</td>"
    ));
    assert!(!page.contains("did not converge"));
    // a surface level that found nothing is a failure, whatever the FEM levels did (and its
    // offsets, never measured, are null in the record)
    edit_deform(&mut f, |d| {
        d["status"] = json!({"status": "inversion_guard", "message": "element 7 inverted"});
        d["refinement"]["stop"] = json!("nothing_found");
        d["refinement"]["mean_offset_first_mm"] = json!(null);
        d["refinement"]["mean_offset_last_mm"] = json!(null);
    });
    let page = html(&f, Accuracy::NoSegmentation);
    assert!(page.contains(
        "<p class=\"bad\">The surface level found no bone border around the registered atlas: \
         the FEM levels (3 iterations) then the surface level (7 rounds). Check the overlays.</p>"
    ));
    assert!(page.contains(
        "<p class=\"note\">The FEM levels stopped at their last valid state: element 7 inverted.</p>"
    ));
}

#[test]
fn a_deformable_stage_that_stopped_early_is_flagged() {
    let mut f = fixture();
    edit_deform(&mut f, |d| {
        d["status"] = json!({"status": "inversion_guard", "message": "element 7 inverted"});
    });
    let html = html(&f, Accuracy::NoSegmentation);
    assert!(html.contains(
        "<p class=\"bad\">The deformable registration did not converge (inversion_guard: \
         element 7 inverted): check the overlays.</p>"
    ));
}

#[test]
fn landmark_warnings_are_shown_with_their_figures_and_flagged_at_the_top() {
    let f = fixture();
    let quiet = html(&f, Accuracy::NoSegmentation);
    assert!(!quiet.contains("landmark warning"));
    assert!(!quiet.contains("class=\"warn\""));
    let warning = LandmarkWarning::UnusualDistance {
        pair: "umbo-ISJ".into(),
        patient_mm: 1.93,
        typical_mm: [2.1, 4.4],
        possible_mm: [1.5, 5.0],
        atlas_mm: Some(3.69),
    };
    let html = html_warned(&f, Accuracy::NoSegmentation, None, &[warning]);
    is_self_contained(&html);
    let top = html
        .find("<p class=\"warn\">The landmarks are unusual but possible (1 warning)")
        .expect("verdict note");
    let note = html
        .find(
            "<p class=\"warn\">landmark warning: umbo-ISJ is 1.93 mm, outside its typical band \
             2.10-4.40 mm (possible 1.50-5.00 mm); the atlas has 3.69 mm",
        )
        .expect("note with the figures");
    let table = html.find("<td>RMS</td>").unwrap();
    assert!(
        top < table && table < note,
        "verdict first, note under the landmarks"
    );
    // a doubtful registered stapes is flagged as the registration's, not the landmarks'
    let weak = LandmarkWarning::WeakEdgeSupport {
        ossicle: "stapes".into(),
        share: 0.2,
        limit: 0.4,
    };
    let html = html_warned(&f, Accuracy::NoSegmentation, None, &[weak]);
    assert!(html.contains("<p class=\"warn\">The registered pose may be wrong (1 warning)"));
    assert!(
        html.contains("<p class=\"warn\">registration warning: only 20 % of the registered stapes")
    );
    assert!(!html.contains("landmark warning"));
}

/// A package validation: the atlas's transfer function, and the package's with |H_V| halved
/// at 4 kHz (-6 dB: one gate fails); no static-pressure curve.
/// Proposed landmarks show their confidence, and when the chain search's best pose was
/// doubted, which poses were registered and which was kept.
#[test]
fn proposed_landmarks_show_their_confidence_and_the_poses_registered() {
    use crate::register::auto_landmarks::PoseTried;
    let f = fixture();
    let tried = |search_score, stapes_support, mean_support, kept| PoseTried {
        search_score,
        scale: 1.14,
        stapes_support,
        mean_support,
        kept,
    };
    let proposed = |poses_tried| Proposed {
        confidence: [0.71, 0.62, 0.93],
        poses_tried,
    };
    let single = html_proposed(
        &f,
        Accuracy::NoSegmentation,
        None,
        &[],
        Some(proposed(vec![tried(0.52, 0.61, 0.74, true)])),
    );
    assert!(single.contains("confidence (proposed)") && single.contains("0.93"));
    assert!(!single.contains("Landmark proposal:"));
    let replaced = html_proposed(
        &f,
        Accuracy::NoSegmentation,
        None,
        &[],
        Some(proposed(vec![
            tried(0.511, 0.13, 0.48, false),
            tried(0.503, 0.40, 0.66, true),
        ])),
    );
    assert!(replaced.contains("Landmark proposal:"), "no proposal note");
    assert!(
        replaced.contains("left 0.13 of the stapes")
            && replaced.contains("next pose was registered, pose 2 (score 0.503) kept: 0.40 of the stapes, 0.66 of the ossicles"),
        "the note does not give the poses' figures"
    );
}

fn validation() -> crate::mechanics::Validation {
    use crate::mechanics::{
        Drive, Mechanics, Ossicles, StaticCurve, TfPoint, TransferFunction, relative_verdict,
    };
    let tf = |scale_4k: f64| TransferFunction {
        drive: Drive::Eardrum,
        drive_pa: 0.632,
        ossicles: Ossicles::Rigid,
        points: [
            (250.0, 13.0, 68.0),
            (1000.0, 34.0, -16.0),
            (4000.0, 13.0, -107.0),
        ]
        .iter()
        .map(|&(f, m, p)| TfPoint {
            frequency_hz: f,
            magnitude_um_s_per_pa: if f == 4000.0 { m * scale_4k } else { m },
            phase_deg: p,
            umbo_um_s_per_pa: 0.0,
        })
        .collect(),
    };
    let mechanics = |t: TransferFunction| Mechanics {
        transfer_function: t,
        udsp: StaticCurve::default(),
        tfa_seconds: 0.0,
        udsp_seconds: 0.0,
    };
    let (package, atlas) = (mechanics(tf(0.5)), mechanics(tf(1.0)));
    let verdict = relative_verdict(
        &package.transfer_function,
        &package.udsp,
        &atlas.transfer_function,
        &atlas.udsp,
    );
    crate::mechanics::Validation {
        condition: crate::mechanics::Condition::Normal,
        mechanics: package,
        reference: Some(atlas),
        verdict,
        evidence: Vec::new(),
        changes: Vec::new(),
    }
}

#[test]
fn a_validated_package_shows_its_gates_and_charts() {
    let f = fixture();
    let v = validation();
    let page = |mechanics| html_with(&f, Accuracy::NoSegmentation, mechanics);
    let html = page(Some(&v));
    is_self_contained(&html);
    // 3 magnitudes, 3 phases (to 4 kHz), the band-centre ratio: only the magnitude at 4 kHz fails
    assert_eq!(v.verdict.gates.len(), 7);
    assert!(html.contains("1 mechanical gate against the atlas fails"));
    assert!(html.contains("1 of 7 gates fail"));
    assert!(html.contains(
        "<td>|H_V| vs atlas at 4000 Hz</td><td>-6.021 dB</td><td>[-3, 3]</td><td>FAIL</td>"
    ));
    assert!(html.contains(
        "<td>|H_V| vs atlas at 250 Hz</td><td>0.000 dB</td><td>[-3, 3]</td><td>pass</td>"
    ));
    // magnitude and phase charts, no static-pressure chart (not computed)
    let without = page(None);
    assert_eq!(
        html.matches("<svg").count(),
        without.matches("<svg").count() + 2
    );
    assert!(html.contains("Goode et al. 1994 band"));
    assert!(!html.contains("umbo displacement under static pressure"));
    assert!(without.contains("Not validated"));
}
