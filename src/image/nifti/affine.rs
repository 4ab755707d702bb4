//! The voxel-to-world affine of a header by the NIfTI-1 standard's three methods (sform,
//! qform, pixdim), in LPS millimetres, and the RAS affine a written file carries.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Vector3};

use super::field_err;
use super::header::Header;
use crate::image::{ImageError, Volume};

/// A matrix on one line, rows separated by `;` (error messages are one line).
fn one_line(m: &Matrix4<f64>) -> String {
    let rows: Vec<String> = m
        .row_iter()
        .map(|r| {
            r.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    format!("[{}]", rows.join("; "))
}

pub(super) type Geometry = (
    [usize; 3],
    [f64; 3],
    Vector3<f64>,
    Matrix3<f64>,
    Vec<String>,
);

/// The voxel-to-world affine (RAS, file units) per the NIfTI-1 standard's three methods.
fn ras_affine(
    h: &Header,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Matrix4<f64>, ImageError> {
    if h.sform_code > 0 {
        let s = &h.srow;
        return Ok(Matrix4::new(
            s[0][0], s[0][1], s[0][2], s[0][3], s[1][0], s[1][1], s[1][2], s[1][3], s[2][0],
            s[2][1], s[2][2], s[2][3], 0.0, 0.0, 0.0, 1.0,
        ));
    }
    let pix = [h.pixdim[1], h.pixdim[2], h.pixdim[3]];
    if pix.iter().any(|p| !p.is_finite() || *p == 0.0) {
        return Err(field_err(
            path,
            "pixdim[1..3]",
            format!("{pix:?}"),
            "non-zero voxel sizes",
        ));
    }
    if pix.iter().any(|p| *p < 0.0) {
        warnings.push("negative pixdim: absolute values used".into());
    }
    let [dx, dy, dz] = pix.map(f64::abs);
    if h.qform_code > 0 {
        let [b, c, d] = h.quatern;
        let a2 = 1.0 - (b * b + c * c + d * d);
        let (a, b, c, d) = if a2 > 1e-7 {
            (a2.sqrt(), b, c, d)
        } else {
            let n = (b * b + c * c + d * d).sqrt();
            if n == 0.0 {
                return Err(field_err(
                    path,
                    "quatern_b/c/d",
                    format!("{:?}", h.quatern),
                    "a unit quaternion",
                ));
            }
            (0.0, b / n, c / n, d / n)
        };
        let r = Matrix3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        );
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let m = r * Matrix3::from_diagonal(&Vector3::new(dx, dy, qfac * dz));
        let mut out = Matrix4::identity();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&m);
        out.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::from(h.qoffset));
        return Ok(out);
    }
    warnings
        .push("no sform or qform (both codes 0): pixdim only, origin 0 (NIfTI method 1)".into());
    Ok(Matrix4::from_diagonal(&nalgebra::Vector4::new(
        dx, dy, dz, 1.0,
    )))
}

pub(super) fn geometry(h: &Header, path: &Path) -> Result<Geometry, ImageError> {
    let mut warnings = Vec::new();
    let mut affine = ras_affine(h, path, &mut warnings)?;
    let to_mm = match h.xyzt_units & 0x07 {
        1 => 1000.0,
        3 => 0.001,
        _ => 1.0,
    };
    let ras_to_lps = Matrix4::from_diagonal(&nalgebra::Vector4::new(-to_mm, -to_mm, to_mm, 1.0));
    affine = ras_to_lps * affine;
    if affine.iter().any(|v| !v.is_finite()) {
        return Err(field_err(
            path,
            "affine",
            one_line(&affine),
            "finite numbers (origin and voxel axes)",
        ));
    }
    let m = affine.fixed_view::<3, 3>(0, 0).into_owned();
    let mut spacing = [0.0; 3];
    let mut direction = Matrix3::zeros();
    for (c, s) in spacing.iter_mut().enumerate() {
        let col = m.column(c);
        let norm = col.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(field_err(
                path,
                "affine",
                one_line(&affine),
                "three non-degenerate voxel axes",
            ));
        }
        *s = norm;
        direction.set_column(c, &(col / norm));
    }
    if direction.determinant().abs() < 1e-6 {
        return Err(field_err(
            path,
            "affine",
            one_line(&affine),
            "linearly independent voxel axes",
        ));
    }
    let dims = [1, 2, 3].map(|k| {
        if h.dim[0] >= k as i64 {
            h.dim[k].max(1) as usize
        } else {
            1
        }
    });
    let origin = affine.fixed_view::<3, 1>(0, 3).into_owned();
    Ok((dims, spacing, origin, direction, warnings))
}

/// The world-to-file affine of `geometry` in NIfTI's RAS convention (LPS negated on x, y).
pub(super) fn ras_affine_of(geometry: &Volume) -> Matrix4<f64> {
    let mut lps = Matrix4::identity();
    lps.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&geometry.index_to_world_matrix());
    lps.fixed_view_mut::<3, 1>(0, 3).copy_from(&geometry.origin);
    Matrix4::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0)) * lps
}
