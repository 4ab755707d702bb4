//! From the frames of one series to a volume geometry: slices ordered by ImagePositionPatient
//! projected on the slice normal (never by file name or InstanceNumber), slice spacing from the
//! positions (never SliceThickness), and a direction matrix whose third column is the actual
//! stacking direction (so gantry tilt and oblique scans come out right).

use std::path::Path;

use nalgebra::{Matrix3, Vector3};

use super::scan::ImageFile;
use crate::image::ImageError;
use crate::image::IngestConfig;

/// The geometry of a series and the order of its frames along k.
#[derive(Debug, Clone)]
pub struct SeriesGeometry {
    pub dims: [usize; 3],
    pub spacing: [f64; 3],
    pub origin: Vector3<f64>,
    pub direction: Matrix3<f64>,
    /// (file index, frame index) of each k-slice, in increasing k.
    pub order: Vec<(usize, usize)>,
    /// Assumptions made where the data did not say (shown to the user).
    pub warnings: Vec<String>,
}

struct Placed<'a> {
    file: usize,
    frame: usize,
    path: &'a Path,
    position: Vector3<f64>,
    along_normal: f64,
}

fn fmt_iop(v: &[f64; 6]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.4}")).collect();
    format!("[{}]", parts.join(", "))
}

/// Computes the geometry of the series made of all frames of `files` (at least one frame).
pub fn series_geometry(
    files: &[ImageFile],
    cfg: &IngestConfig,
) -> Result<SeriesGeometry, ImageError> {
    let first = &files[0];
    for f in &files[1..] {
        if (f.rows, f.columns) != (first.rows, first.columns) {
            return Err(ImageError::MixedDims {
                first: first.path.clone(),
                first_dims: format!("{} columns x {} rows", first.columns, first.rows),
                other: f.path.clone(),
                other_dims: format!("{} columns x {} rows", f.columns, f.rows),
            });
        }
    }
    let n_frames: usize = files.iter().map(|f| f.frames.len()).sum();
    let all_frames = || {
        files
            .iter()
            .enumerate()
            .flat_map(|(fi, f)| f.frames.iter().enumerate().map(move |(k, h)| (fi, k, f, h)))
    };
    let has_geometry =
        all_frames().all(|(_, _, _, h)| h.position.is_some() && h.orientation.is_some());
    if !has_geometry {
        if files.len() > 1 {
            let (_, _, f, _) = all_frames()
                .find(|(_, _, _, h)| h.position.is_none() || h.orientation.is_none())
                .unwrap_or((0, 0, first, &first.frames[0]));
            return Err(ImageError::MissingTag {
                path: f.path.clone(),
                tag: "ImagePositionPatient (0020,0032) / ImageOrientationPatient (0020,0037)",
                expected: "a position and orientation on every slice, to order the slices",
            });
        }
        return Ok(assumed_geometry(first, n_frames));
    }

    // orientation: all frames agree with the first
    let iop0 = first.frames[0]
        .orientation
        .unwrap_or([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    for (_, _, f, h) in all_frames() {
        let iop = h.orientation.unwrap_or(iop0);
        if iop
            .iter()
            .zip(&iop0)
            .any(|(a, b)| (a - b).abs() > cfg.orientation_tolerance)
        {
            return Err(ImageError::MixedOrientation {
                first: first.path.clone(),
                first_iop: fmt_iop(&iop0),
                other: f.path.clone(),
                other_iop: fmt_iop(&iop),
            });
        }
    }
    let row = Vector3::new(iop0[0], iop0[1], iop0[2]);
    let col = Vector3::new(iop0[3], iop0[4], iop0[5]);
    if (row.norm() - 1.0).abs() > 1e-3
        || (col.norm() - 1.0).abs() > 1e-3
        || row.dot(&col).abs() > 1e-3
    {
        return Err(ImageError::BadValue {
            path: first.path.clone(),
            tag: "ImageOrientationPatient (0020,0037)",
            value: fmt_iop(&iop0),
            expected: "two orthogonal unit vectors (row, column direction cosines)".into(),
        });
    }
    let row = row.normalize();
    let col = col.normalize();
    let normal = row.cross(&col);

    // pixel spacing: all frames agree
    let ps0 = first.frames[0].pixel_spacing;
    for (_, _, f, h) in all_frames() {
        let same = match (h.pixel_spacing, ps0) {
            (Some(a), Some(b)) => {
                (a[0] - b[0]).abs() <= 1e-4 * b[0] && (a[1] - b[1]).abs() <= 1e-4 * b[1]
            }
            (None, None) => true,
            _ => false,
        };
        if !same {
            return Err(ImageError::BadValue {
                path: f.path.clone(),
                tag: "PixelSpacing (0028,0030)",
                value: format!("{:?}", h.pixel_spacing),
                expected: format!("the same as in {} ({:?})", first.path.display(), ps0),
            });
        }
    }
    let mut warnings = Vec::new();
    let [row_spacing, col_spacing] = ps0.unwrap_or_else(|| {
        warnings.push("PixelSpacing absent: in-plane spacing assumed 1 mm".to_string());
        [1.0, 1.0]
    });

    let mut placed: Vec<Placed> = all_frames()
        .map(|(fi, k, f, h)| {
            let position = h.position.unwrap_or_else(Vector3::zeros);
            Placed {
                file: fi,
                frame: k,
                path: &f.path,
                position,
                along_normal: normal.dot(&position),
            }
        })
        .collect();
    placed.sort_by(|a, b| {
        a.along_normal
            .total_cmp(&b.along_normal)
            .then_with(|| a.path.cmp(b.path))
            .then(a.frame.cmp(&b.frame))
    });

    let n = placed.len();
    let (slice_dir, slice_spacing) = if n == 1 {
        let s = first.slice_spacing_hint.unwrap_or_else(|| {
            warnings.push("single slice without SpacingBetweenSlices/SliceThickness: slice spacing assumed 1 mm".into());
            1.0
        });
        (normal, s)
    } else {
        check_gaps(&placed, cfg, row_spacing.min(col_spacing))?;
        let span = placed[n - 1].position - placed[0].position;
        let dir = span.normalize();
        let spacing = span.norm() / (n - 1) as f64;
        // every slice on the line through the first and last
        for p in &placed {
            let rel = p.position - placed[0].position;
            let off = (rel - dir * rel.dot(&dir)).norm();
            if off > 0.5 * spacing.min(row_spacing).min(col_spacing) {
                return Err(ImageError::NotStacked {
                    path: p.path.to_path_buf(),
                    offset_mm: off,
                });
            }
        }
        let tilt = dir.dot(&normal).clamp(-1.0, 1.0).acos().to_degrees();
        if tilt > 0.01 {
            warnings.push(format!(
                "slices are stacked {tilt:.2} degrees off their normal (gantry tilt): the direction matrix is sheared"
            ));
        }
        (dir, spacing)
    };

    Ok(SeriesGeometry {
        dims: [first.columns, first.rows, n],
        spacing: [col_spacing, row_spacing, slice_spacing],
        origin: placed[0].position,
        direction: Matrix3::from_columns(&[row, col, slice_dir]),
        order: placed.iter().map(|p| (p.file, p.frame)).collect(),
        warnings,
    })
}

fn check_gaps(placed: &[Placed], cfg: &IngestConfig, in_plane: f64) -> Result<(), ImageError> {
    let gaps: Vec<f64> = placed
        .windows(2)
        .map(|w| w[1].along_normal - w[0].along_normal)
        .collect();
    let duplicate_tol = 1e-3 * in_plane.max(1e-3);
    for (w, g) in placed.windows(2).zip(&gaps) {
        if *g <= duplicate_tol {
            return Err(ImageError::DuplicatePosition {
                first: w[0].path.to_path_buf(),
                other: w[1].path.to_path_buf(),
                position_mm: w[0].along_normal,
            });
        }
    }
    let mut sorted = gaps.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    for (w, g) in placed.windows(2).zip(&gaps) {
        if (g - median).abs() > cfg.slice_gap_tolerance * median {
            return Err(ImageError::NonUniformSpacing {
                before: w[0].path.to_path_buf(),
                after: w[1].path.to_path_buf(),
                at_mm: w[0].along_normal,
                gap_mm: *g,
                median_mm: median,
                hint: if *g > median {
                    "a missing slice?"
                } else {
                    "an extra slice, or two series mixed under one SeriesInstanceUID?"
                },
            });
        }
    }
    Ok(())
}

/// Geometry for a file that carries no position or orientation (some multi-frame exports):
/// identity orientation, origin 0, spacings from the tags that exist. Said in the warnings.
fn assumed_geometry(file: &ImageFile, n_frames: usize) -> SeriesGeometry {
    let mut warnings = vec![
        "no ImagePositionPatient/ImageOrientationPatient: geometry assumed (identity orientation, origin 0)".to_string(),
    ];
    let [row_spacing, col_spacing] = file.frames[0].pixel_spacing.unwrap_or_else(|| {
        warnings.push("PixelSpacing absent: in-plane spacing assumed 1 mm".to_string());
        [1.0, 1.0]
    });
    let slice = file.slice_spacing_hint.unwrap_or_else(|| {
        warnings.push(
            "SpacingBetweenSlices/SliceThickness absent: slice spacing assumed 1 mm".to_string(),
        );
        1.0
    });
    SeriesGeometry {
        dims: [file.columns, file.rows, n_frames],
        spacing: [col_spacing, row_spacing, slice],
        origin: Vector3::zeros(),
        direction: Matrix3::identity(),
        order: (0..n_frames).map(|k| (0, k)).collect(),
        warnings,
    }
}
