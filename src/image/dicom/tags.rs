//! Typed access to the DICOM attributes ingest needs, with errors that name file and tag.

use std::path::Path;

use dicom_core::Tag;
use dicom_object::InMemDicomObject;

use crate::image::ImageError;

/// A trimmed string attribute, or `None` if absent or empty.
pub fn string(obj: &InMemDicomObject, tag: Tag) -> Option<String> {
    let value = obj.get(tag)?.to_str().ok()?;
    let trimmed = value.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    (!trimmed.is_empty()).then(|| trimmed.to_string())
}

/// A multi-valued decimal attribute of exactly `n` values, `None` if absent.
pub fn floats(
    obj: &InMemDicomObject,
    tag: Tag,
    name: &'static str,
    n: usize,
    path: &Path,
) -> Result<Option<Vec<f64>>, ImageError> {
    let Some(elem) = obj.get(tag) else {
        return Ok(None);
    };
    let values = elem.to_multi_float64().map_err(|e| ImageError::BadValue {
        path: path.to_path_buf(),
        tag: name,
        value: format!("unreadable ({e})"),
        expected: format!("{n} decimal numbers"),
    })?;
    if values.len() != n || values.iter().any(|v| !v.is_finite()) {
        return Err(ImageError::BadValue {
            path: path.to_path_buf(),
            tag: name,
            value: format!("{values:?}"),
            expected: format!("{n} finite decimal numbers"),
        });
    }
    Ok(Some(values))
}

/// A single decimal attribute, `None` if absent.
pub fn float(
    obj: &InMemDicomObject,
    tag: Tag,
    name: &'static str,
    path: &Path,
) -> Result<Option<f64>, ImageError> {
    Ok(floats(obj, tag, name, 1, path)?.map(|v| v[0]))
}

/// A single integer attribute, `None` if absent.
pub fn int(
    obj: &InMemDicomObject,
    tag: Tag,
    name: &'static str,
    path: &Path,
) -> Result<Option<i64>, ImageError> {
    let Some(elem) = obj.get(tag) else {
        return Ok(None);
    };
    elem.to_int::<i64>()
        .map(Some)
        .map_err(|e| ImageError::BadValue {
            path: path.to_path_buf(),
            tag: name,
            value: format!("unreadable ({e})"),
            expected: "an integer".into(),
        })
}

/// The first item of a sequence attribute, if any.
pub fn first_item(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemDicomObject> {
    obj.get(tag)?.items()?.first()
}
