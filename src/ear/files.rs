//! Landmark files: 3D Slicer markups `.fcsv` (parsed by its `# columns` header, with
//! `# CoordinateSystem` LPS/RAS or the legacy 0 = RAS / 1 = LPS), Slicer `.mrk.json`
//! (`coordinateSystem`, `controlPoints[].label/position`), our `landmarks.json`, and a plain
//! CSV `label,x,y,z` (LPS). RAS is converted to LPS here, once. Writers give the text, so
//! callers can write it atomically.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde_json::{Value, json};

use super::{LandmarkName, Landmarks, Side};

/// Landmarks read from a file, with what the file said besides the points.
#[derive(Debug, Clone, PartialEq)]
pub struct LandmarkFile {
    pub landmarks: Landmarks,
    /// The side of the ear, if the file says it.
    pub side: Option<Side>,
    /// Notes for the user (e.g. a coordinate system assumed).
    pub notes: Vec<String>,
}

/// A landmark file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum LandmarkFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: unknown landmark file type; expected .fcsv, .mrk.json, .json or .csv")]
    UnknownFormat { path: PathBuf },
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error(
        "{path}: landmark {name} is missing; expected umbo, incudomalleolar (IMJ) and incudostapedial (ISJ)"
    )]
    Missing { path: PathBuf, name: &'static str },
    #[error("{path}: landmark {name} is given twice (lines {first} and {second})")]
    Duplicate {
        path: PathBuf,
        name: &'static str,
        first: usize,
        second: usize,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Frame {
    Lps,
    Ras,
}

fn parse_err(path: &Path, line: usize, message: impl Into<String>) -> LandmarkFileError {
    LandmarkFileError::Parse {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// Collects named points (with the line each came from), then checks all three are there.
struct Collected<'a> {
    path: &'a Path,
    points: HashMap<LandmarkName, (Point3<f64>, usize)>,
}

impl<'a> Collected<'a> {
    fn new(path: &'a Path) -> Self {
        Collected {
            path,
            points: HashMap::new(),
        }
    }

    /// Adds a point if its label names a landmark; other labels are ignored (files often hold
    /// more markups than ours).
    fn add(&mut self, label: &str, p: Point3<f64>, line: usize) -> Result<(), LandmarkFileError> {
        let Some(name) = LandmarkName::parse(label) else {
            return Ok(());
        };
        if !p.iter().all(|v| v.is_finite()) {
            return Err(parse_err(
                self.path,
                line,
                format!("landmark {label:?} has a non-finite coordinate"),
            ));
        }
        if let Some((_, first)) = self.points.insert(name, (p, line)) {
            return Err(LandmarkFileError::Duplicate {
                path: self.path.to_path_buf(),
                name: name.key(),
                first,
                second: line,
            });
        }
        Ok(())
    }

    fn finish(self, frame: Frame) -> Result<Landmarks, LandmarkFileError> {
        let get = |name: LandmarkName| {
            self.points
                .get(&name)
                .map(|(p, _)| to_lps(*p, frame))
                .ok_or(LandmarkFileError::Missing {
                    path: self.path.to_path_buf(),
                    name: name.key(),
                })
        };
        Ok(Landmarks {
            umbo: get(LandmarkName::Umbo)?,
            incudomalleolar: get(LandmarkName::Incudomalleolar)?,
            incudostapedial: get(LandmarkName::Incudostapedial)?,
        })
    }
}

fn to_lps(p: Point3<f64>, frame: Frame) -> Point3<f64> {
    match frame {
        Frame::Lps => p,
        Frame::Ras => Point3::new(-p.x, -p.y, p.z),
    }
}

/// Reads a landmark file, choosing the format by extension.
pub fn read_landmarks(path: &Path) -> Result<LandmarkFile, LandmarkFileError> {
    let text = crate::io_util::read_text(path).map_err(|source| LandmarkFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let name = path.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".fcsv") {
        parse_fcsv(&text, path)
    } else if name.ends_with(".mrk.json") {
        parse_mrk_json(&text, path)
    } else if name.ends_with(".json") {
        parse_json(&text, path)
    } else if name.ends_with(".csv") {
        parse_csv(&text, path)
    } else {
        Err(LandmarkFileError::UnknownFormat {
            path: path.to_path_buf(),
        })
    }
}

fn parse_frame(value: &str) -> Option<Frame> {
    match value.trim().to_ascii_uppercase().as_str() {
        "LPS" | "1" => Some(Frame::Lps),
        "RAS" | "0" => Some(Frame::Ras),
        _ => None,
    }
}

fn parse_fcsv(text: &str, path: &Path) -> Result<LandmarkFile, LandmarkFileError> {
    let mut frame = None;
    let mut columns: Vec<String> = "id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID"
        .split(',')
        .map(String::from)
        .collect();
    let mut data_lines = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(comment) = line.trim_start().strip_prefix('#') {
            if let Some((key, value)) = comment.split_once('=') {
                match key.trim().to_ascii_lowercase().as_str() {
                    "coordinatesystem" => {
                        frame = Some(parse_frame(value).ok_or_else(|| {
                            parse_err(
                                path,
                                i + 1,
                                format!(
                                    "CoordinateSystem {:?}: expected LPS, RAS, 0 or 1",
                                    value.trim()
                                ),
                            )
                        })?);
                    }
                    "columns" => columns = value.split(',').map(|c| c.trim().to_string()).collect(),
                    _ => {}
                }
            }
        } else if !line.trim().is_empty() {
            data_lines.push((i + 1, line));
        }
    }
    let mut notes = Vec::new();
    let frame = frame.unwrap_or_else(|| {
        notes.push("no '# CoordinateSystem' line: RAS assumed (legacy Slicer default)".into());
        Frame::Ras
    });
    let col = |name: &str| columns.iter().position(|c| c.eq_ignore_ascii_case(name));
    let (Some(cx), Some(cy), Some(cz), Some(cl)) = (col("x"), col("y"), col("z"), col("label"))
    else {
        return Err(parse_err(
            path,
            1,
            "the '# columns' header lacks x, y, z or label",
        ));
    };
    let mut collected = Collected::new(path);
    for (line, text) in data_lines {
        let record = csv_record(text).map_err(|e| parse_err(path, line, e))?;
        let field = |k: usize, what: &str| {
            record
                .get(k)
                .ok_or_else(|| parse_err(path, line, format!("missing column {what}")))
        };
        let num = |k: usize, what: &str| -> Result<f64, LandmarkFileError> {
            let f = field(k, what)?;
            f.trim().parse().map_err(|_| {
                parse_err(
                    path,
                    line,
                    format!("{what} is {f:?}, expected a number (mm)"),
                )
            })
        };
        let p = Point3::new(num(cx, "x")?, num(cy, "y")?, num(cz, "z")?);
        collected.add(field(cl, "label")?, p, line)?;
    }
    Ok(LandmarkFile {
        landmarks: collected.finish(frame)?,
        side: None,
        notes,
    })
}

/// One CSV line (quotes and doubled quotes as Slicer writes them).
fn csv_record(line: &str) -> Result<csv::StringRecord, String> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(line.as_bytes());
    match reader.records().next() {
        Some(Ok(record)) => Ok(record),
        Some(Err(e)) => Err(e.to_string()),
        None => Ok(csv::StringRecord::new()),
    }
}

fn json_value(text: &str, path: &Path) -> Result<Value, LandmarkFileError> {
    serde_json::from_str(text).map_err(|e| parse_err(path, e.line(), e.to_string()))
}

fn json_point(v: &Value, path: &Path, what: &str) -> Result<Point3<f64>, LandmarkFileError> {
    let arr = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| parse_err(path, 0, format!("{what}: expected [x, y, z]")))?;
    let c = |k: usize| {
        arr[k].as_f64().ok_or_else(|| {
            parse_err(
                path,
                0,
                format!("{what}[{k}] is {}, expected a number (mm)", arr[k]),
            )
        })
    };
    Ok(Point3::new(c(0)?, c(1)?, c(2)?))
}

/// Millimetres per unit of the `key` a file states (`mm` when absent), with a note when the
/// coordinates are converted. Slicer writes `coordinateUnits` as a string or one per axis.
fn unit_scale(
    value: Option<&Value>,
    key: &str,
    path: &Path,
) -> Result<(f64, Option<String>), LandmarkFileError> {
    let unit = match value {
        None | Some(Value::Null) => return Ok((1.0, None)),
        Some(Value::String(s)) => s.clone(),
        Some(Value::Array(units))
            if !units.is_empty() && units.iter().all(|u| u.as_str() == units[0].as_str()) =>
        {
            units[0].as_str().unwrap_or_default().to_string()
        }
        Some(other) => {
            return Err(parse_err(
                path,
                0,
                format!("{key} is {other}; expected a unit of length such as \"mm\""),
            ));
        }
    };
    let scale = match unit.trim() {
        "mm" => return Ok((1.0, None)),
        "m" => 1000.0,
        "cm" => 10.0,
        "um" | "\u{b5}m" => 0.001,
        other => {
            return Err(parse_err(
                path,
                0,
                format!("{key} {other:?}: expected mm, cm, m or um"),
            ));
        }
    };
    Ok((
        scale,
        Some(format!("coordinates in {unit} ({key}), converted to mm")),
    ))
}

fn parse_mrk_json(text: &str, path: &Path) -> Result<LandmarkFile, LandmarkFileError> {
    let root = json_value(text, path)?;
    let markups = root["markups"]
        .as_array()
        .ok_or_else(|| parse_err(path, 0, "no \"markups\" array"))?;
    let mut collected = Collected::new(path);
    let mut notes = Vec::new();
    for (m, markup) in markups.iter().enumerate() {
        let (scale, note) = unit_scale(
            markup.get("coordinateUnits"),
            &format!("markups[{m}].coordinateUnits"),
            path,
        )?;
        notes.extend(note);
        let this_frame = match markup.get("coordinateSystem").and_then(Value::as_str) {
            None => Frame::Lps, // the schema's default
            Some(s) => parse_frame(s).ok_or_else(|| {
                parse_err(
                    path,
                    0,
                    format!("markups[{m}].coordinateSystem {s:?}: expected LPS or RAS"),
                )
            })?,
        };
        let points = markup["controlPoints"]
            .as_array()
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        for (k, cp) in points.iter().enumerate() {
            let label = cp["label"].as_str().unwrap_or_default();
            if LandmarkName::parse(label).is_none() {
                continue;
            }
            let what = format!("markups[{m}].controlPoints[{k}].position");
            // convert per markup, since two markups may use different systems
            let p = to_lps(
                json_point(&cp["position"], path, &what)? * scale,
                this_frame,
            );
            collected.add(label, p, k + 1)?;
        }
    }
    Ok(LandmarkFile {
        landmarks: collected.finish(Frame::Lps)?,
        side: None,
        notes,
    })
}

fn parse_json(text: &str, path: &Path) -> Result<LandmarkFile, LandmarkFileError> {
    let root = json_value(text, path)?;
    let obj = root
        .as_object()
        .ok_or_else(|| parse_err(path, 1, "expected an object {\"umbo\": [x, y, z], ...}"))?;
    let frame = match obj.get("coordinate_system").and_then(Value::as_str) {
        None => Frame::Lps,
        Some(s) => parse_frame(s).ok_or_else(|| {
            parse_err(
                path,
                0,
                format!("coordinate_system {s:?}: expected LPS or RAS"),
            )
        })?,
    };
    let side = match obj.get("side").and_then(Value::as_str) {
        None => None,
        Some(s) => Some(
            Side::parse(s)
                .ok_or_else(|| parse_err(path, 0, format!("side {s:?}: expected left or right")))?,
        ),
    };
    let (scale, note) = unit_scale(obj.get("units"), "units", path)?;
    let mut collected = Collected::new(path);
    for (k, (key, value)) in obj.iter().enumerate() {
        if LandmarkName::parse(key).is_some() {
            collected.add(key, json_point(value, path, key)? * scale, k + 1)?;
        }
    }
    Ok(LandmarkFile {
        landmarks: collected.finish(frame)?,
        side,
        notes: note.into_iter().collect(),
    })
}

fn parse_csv(text: &str, path: &Path) -> Result<LandmarkFile, LandmarkFileError> {
    let mut collected = Collected::new(path);
    let mut seen_data = false;
    for (i, text) in text.lines().enumerate() {
        let line = i + 1;
        if text.trim().is_empty() || text.trim_start().starts_with('#') {
            continue;
        }
        let record = csv_record(text).map_err(|e| parse_err(path, line, e))?;
        if record.len() < 4 {
            return Err(parse_err(path, line, "expected label,x,y,z"));
        }
        let nums: Result<Vec<f64>, _> = (1..4).map(|k| record[k].trim().parse::<f64>()).collect();
        match nums {
            Ok(n) => collected.add(record[0].trim(), Point3::new(n[0], n[1], n[2]), line)?,
            Err(_) if !seen_data => {} // a header line such as "label,x,y,z"
            Err(_) => return Err(parse_err(path, line, "x, y, z must be numbers (mm, LPS)")),
        }
        seen_data = true;
    }
    Ok(LandmarkFile {
        landmarks: collected.finish(Frame::Lps)?,
        side: None,
        notes: Vec::new(),
    })
}

/// A coordinate to 0.1 µm; a value that rounds to zero is written `0.0000`, never `-0.0000`.
fn fmt(v: f64) -> String {
    let text = format!("{v:.4}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => text,
    }
}

/// Slicer markups `.fcsv` text (LPS). The orientation columns are a quaternion w,x,y,z: the
/// identity is `1,0,0,0`, as Slicer writes it.
pub fn write_fcsv(l: &Landmarks) -> String {
    write_fcsv_described(l, &Default::default())
}

/// [`write_fcsv`] with a description per landmark (the `desc` column; commas become
/// semicolons, as the column cannot quote them).
pub fn write_fcsv_described(l: &Landmarks, descriptions: &[String; 3]) -> String {
    let mut s = String::from(
        "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n",
    );
    for (k, name) in LandmarkName::ALL.iter().enumerate() {
        let p = l.get(*name);
        s.push_str(&format!(
            "{},{},{},{},1,0,0,0,1,1,0,{},{},\n",
            k + 1,
            fmt(p.x),
            fmt(p.y),
            fmt(p.z),
            name.key(),
            descriptions[k].replace([',', '\n', '\r'], ";")
        ));
    }
    s
}

/// Slicer markups `.mrk.json` text (LPS).
pub fn write_mrk_json(l: &Landmarks) -> String {
    write_mrk_json_described(l, &Default::default())
}

/// [`write_mrk_json`] with a description per control point (left out where empty).
pub fn write_mrk_json_described(l: &Landmarks, descriptions: &[String; 3]) -> String {
    let points: Vec<Value> = LandmarkName::ALL
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let p = l.get(*name);
            let mut point = json!({
                "id": (k + 1).to_string(),
                "label": name.key(),
                "position": [p.x, p.y, p.z],
                "positionStatus": "defined",
            });
            if !descriptions[k].is_empty() {
                point["description"] = json!(descriptions[k]);
            }
            point
        })
        .collect();
    let doc = json!({
        "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json#",
        "markups": [{
            "type": "Fiducial",
            "coordinateSystem": "LPS",
            "coordinateUnits": "mm",
            "controlPoints": points,
        }],
    });
    serde_json::to_string_pretty(&doc).unwrap_or_default() + "\n"
}

/// Our `landmarks.json` text: LPS mm, and the side when known.
pub fn write_json(l: &Landmarks, side: Option<Side>) -> String {
    write_json_with(l, side, serde_json::Map::new())
}

/// [`write_json`] with further keys after the landmarks (e.g. how they were proposed);
/// readers ignore them.
pub fn write_json_with(
    l: &Landmarks,
    side: Option<Side>,
    extra: serde_json::Map<String, Value>,
) -> String {
    let mut doc = serde_json::Map::new();
    doc.insert("coordinate_system".into(), json!("LPS"));
    doc.insert("units".into(), json!("mm"));
    if let Some(side) = side {
        doc.insert("side".into(), json!(side.as_str()));
    }
    for name in LandmarkName::ALL {
        let p = l.get(name);
        doc.insert(name.key().into(), json!([p.x, p.y, p.z]));
    }
    doc.extend(extra);
    serde_json::to_string_pretty(&Value::Object(doc)).unwrap_or_default() + "\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slicer's writer (Slicer/Slicer, Libs/MRML/Core/vtkMRMLMarkupsFiducialStorageNode.cxx):
    /// `double orientation[4] = { 1.0, 0.0, 0.0, 0.0 };` then
    /// `of << separator << DoubleConvert(orientation[0]) << ... orientation[3]` under the header
    /// `# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID`: an identity
    /// orientation is written `1,0,0,0`. The defect: ours wrote `0,0,0,1`.
    #[test]
    fn fcsv_orientation_is_slicers_identity_quaternion() {
        let text = write_fcsv(&Landmarks {
            umbo: Point3::new(1.0, 2.0, 3.0),
            incudomalleolar: Point3::new(4.0, 5.0, 6.0),
            incudostapedial: Point3::new(7.0, 8.0, 9.0),
        });
        let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(rows.len(), 3);
        for row in rows {
            let columns: Vec<&str> = row.split(',').collect();
            assert_eq!(columns[4..8], ["1", "0", "0", "0"], "{row}");
        }
    }
}
