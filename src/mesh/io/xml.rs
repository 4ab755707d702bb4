//! The small subset of XML the VTU reader needs: finding elements by name (not nested in
//! themselves), reading attributes, and decoding VTK `DataArray` contents (ASCII or inline
//! base64 binary) into `f64`, with line numbers for error messages.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD;

/// One element: its opening tag (with attributes) and the text between the tags.
#[derive(Debug, Clone, Copy)]
pub struct Element<'a> {
    pub tag: &'a str,
    pub body: &'a str,
    /// Byte offset of the tag in the searched text.
    pub start: usize,
}

/// Elements named `name` in `text`, in document order.
pub fn elements<'a>(text: &'a str, name: &'a str) -> impl Iterator<Item = Element<'a>> + 'a {
    let mut pos = 0;
    std::iter::from_fn(move || {
        loop {
            let rel = text.get(pos..)?.find(&format!("<{name}"))?;
            let start = pos + rel;
            let after = start + 1 + name.len();
            pos = after;
            let next = text[after..].chars().next()?;
            if !(next.is_whitespace() || next == '>' || next == '/') {
                continue;
            }
            let tag_end = after + text[after..].find('>')?;
            let tag = &text[start..=tag_end];
            if tag.ends_with("/>") {
                pos = tag_end + 1;
                return Some(Element {
                    tag,
                    body: "",
                    start,
                });
            }
            let close = format!("</{name}>");
            let body_end = tag_end + 1 + text[tag_end + 1..].find(&close)?;
            pos = body_end + close.len();
            return Some(Element {
                tag,
                body: &text[tag_end + 1..body_end],
                start,
            });
        }
    })
}

/// The value of attribute `key` in an opening tag.
pub fn attr<'a>(tag: &'a str, key: &str) -> Option<&'a str> {
    let mut rest = tag;
    while let Some(i) = rest.find(key) {
        let before_ok = rest[..i].ends_with(|c: char| c.is_whitespace());
        let after = rest[i + key.len()..].trim_start();
        if before_ok && let Some(value) = after.strip_prefix('=') {
            let value = value.trim_start();
            let quote = value.chars().next()?;
            if quote == '"' || quote == '\'' {
                let inner = &value[1..];
                return inner.find(quote).map(|end| &inner[..end]);
            }
        }
        rest = &rest[i + key.len()..];
    }
    None
}

/// 1-based line number of byte `offset` in `text`.
pub fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// A decoded `DataArray`.
#[derive(Debug, Clone)]
pub struct DataArray {
    pub name: String,
    pub components: usize,
    pub values: Vec<f64>,
    line: usize,
}

fn value_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "Int8" | "UInt8" => 1,
        "Int16" | "UInt16" => 2,
        "Int32" | "UInt32" | "Float32" => 4,
        "Int64" | "UInt64" | "Float64" => 8,
        _ => return None,
    })
}

fn decode_le(ty: &str, b: &[u8]) -> f64 {
    let mut w = [0u8; 8];
    w[..b.len()].copy_from_slice(b);
    match ty {
        "Int8" => b[0] as i8 as f64,
        "UInt8" => b[0] as f64,
        "Int16" => i16::from_le_bytes([w[0], w[1]]) as f64,
        "UInt16" => u16::from_le_bytes([w[0], w[1]]) as f64,
        "Int32" => i32::from_le_bytes([w[0], w[1], w[2], w[3]]) as f64,
        "UInt32" => u32::from_le_bytes([w[0], w[1], w[2], w[3]]) as f64,
        "Float32" => f32::from_le_bytes([w[0], w[1], w[2], w[3]]) as f64,
        "Int64" => i64::from_le_bytes(w) as f64,
        "UInt64" => u64::from_le_bytes(w) as f64,
        _ => f64::from_le_bytes(w),
    }
}

impl DataArray {
    /// Where this array is, for error messages.
    pub fn at(&self) -> String {
        format!("line {} DataArray '{}'", self.line, self.name)
    }

    /// Decodes every `DataArray` in `body` (a slice of `doc`); errors are (where, expected).
    pub fn all(doc: &str, body: &str, header64: bool) -> Result<Vec<DataArray>, (String, String)> {
        let base = (body.as_ptr() as usize).saturating_sub(doc.as_ptr() as usize);
        elements(body, "DataArray")
            .map(|e| {
                let line = line_of(doc, base + e.start);
                let name = attr(e.tag, "Name").unwrap_or("").to_string();
                let at = format!("line {line} DataArray '{name}'");
                let ty = attr(e.tag, "type").unwrap_or("");
                let size = value_size(ty).ok_or_else(|| {
                    (
                        at.clone(),
                        format!("a numeric type attribute, found '{ty}'"),
                    )
                })?;
                let components = match attr(e.tag, "NumberOfComponents") {
                    None => 1,
                    Some(c) => c
                        .trim()
                        .parse()
                        .ok()
                        .filter(|&c| c > 0)
                        .ok_or_else(|| (at.clone(), "NumberOfComponents ≥ 1".to_string()))?,
                };
                let values = match attr(e.tag, "format").unwrap_or("ascii") {
                    "ascii" => {
                        let mut values = Vec::new();
                        for token in e.body.split_ascii_whitespace() {
                            let v: f64 = token.parse().map_err(|_| {
                                let off = token.as_ptr() as usize - doc.as_ptr() as usize;
                                (
                                    format!("line {} DataArray '{name}'", line_of(doc, off)),
                                    format!("a number, found '{token}'"),
                                )
                            })?;
                            values.push(v);
                        }
                        values
                    }
                    "binary" => {
                        let packed: String =
                            e.body.chars().filter(|c| !c.is_whitespace()).collect();
                        let bytes = STANDARD
                            .decode(packed)
                            .map_err(|err| (at.clone(), format!("base64 data ({err})")))?;
                        let head = if header64 { 8 } else { 4 };
                        if bytes.len() < head {
                            return Err((at.clone(), "a byte-count header".to_string()));
                        }
                        let count = if header64 {
                            u64::from_le_bytes(bytes[..8].try_into().unwrap_or([0; 8])) as usize
                        } else {
                            u32::from_le_bytes(bytes[..4].try_into().unwrap_or([0; 4])) as usize
                        };
                        let data = &bytes[head..];
                        if count > data.len() || count % size != 0 {
                            return Err((
                                at.clone(),
                                format!(
                                    "{count} data bytes in whole {ty} values, found {}",
                                    data.len()
                                ),
                            ));
                        }
                        data[..count]
                            .chunks_exact(size)
                            .map(|c| decode_le(ty, c))
                            .collect()
                    }
                    other => {
                        return Err((
                            at.clone(),
                            format!("format \"ascii\" or \"binary\" (inline), found \"{other}\""),
                        ));
                    }
                };
                if values.len() % components != 0 {
                    return Err((
                        at,
                        format!("a multiple of {components} values, found {}", values.len()),
                    ));
                }
                Ok(DataArray {
                    name,
                    components,
                    values,
                    line,
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_elements_and_attributes() {
        let doc = "<a x=\"1\">\n<DataArray Name='p' type=\"Int32\">1 2\n3</DataArray><DataArrays/><DataArray type=\"Float32\" format=\"binary\" Name=\"q\">AAAAAA==</DataArray></a>";
        let a = elements(doc, "a").next().unwrap();
        assert_eq!(attr(a.tag, "x"), Some("1"));
        let arrays = DataArray::all(doc, a.body, false).unwrap();
        assert_eq!(arrays.len(), 2);
        assert_eq!(arrays[0].values, vec![1., 2., 3.]);
        assert_eq!(arrays[0].at(), "line 2 DataArray 'p'");
        assert!(arrays[1].values.is_empty());
        let bad = "<DataArray type=\"Int32\" Name=\"c\">1\n2 x</DataArray>";
        let err = DataArray::all(bad, bad, false).unwrap_err();
        assert_eq!(err.0, "line 2 DataArray 'c'");
    }
}
