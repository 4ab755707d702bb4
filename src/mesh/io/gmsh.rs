//! Gmsh MSH 2.2 ASCII ("Gmsh reference manual", legacy MSH 2 format): nodes, 4-node tets
//! (element type 4) and 3-node triangles (type 2), with physical tag = elementary tag = region.
//! The reader accepts any MSH 2.2 ASCII file, skips other element types (points, lines...)
//! and takes the region from the first tag (0 when untagged).

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use super::{MeshIoError, VolumeMesh, read_text, write_bytes};

const MSH_TRIANGLE: u32 = 2;
const MSH_TETRA: u32 = 4;

/// The MSH 2.2 document for `mesh`; `names` (region label → name) become `$PhysicalNames`,
/// one per label used, of dimension 3 for tetrahedra and 2 for triangles, so that Gmsh and
/// meshio show the groups by name. `Err` names an inconsistency.
pub fn msh_string(mesh: &VolumeMesh, names: &BTreeMap<u16, String>) -> Result<String, String> {
    mesh.check(&[])?;
    let m = &mesh.tets;
    let mut s = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n");
    let used: BTreeSet<(u8, u16)> = m
        .regions
        .iter()
        .map(|r| (3, *r))
        .chain(mesh.triangle_regions.iter().map(|r| (2, *r)))
        .filter(|(_, r)| names.contains_key(r))
        .collect();
    if !used.is_empty() {
        let _ = writeln!(s, "$PhysicalNames\n{}", used.len());
        for (dim, r) in &used {
            let name = names[r].replace('"', "'");
            let _ = writeln!(s, "{dim} {r} \"{name}\"");
        }
        s.push_str("$EndPhysicalNames\n");
    }
    s.push_str("$Nodes\n");
    let _ = writeln!(s, "{}", m.nodes.len());
    for (i, p) in m.nodes.iter().enumerate() {
        let _ = writeln!(s, "{} {:?} {:?} {:?}", i + 1, p.x, p.y, p.z);
    }
    let _ = writeln!(s, "$EndNodes\n$Elements\n{}", mesh.cell_count());
    let mut id = 0;
    for (t, &r) in m.tets.iter().zip(&m.regions) {
        id += 1;
        let _ = writeln!(
            s,
            "{id} {MSH_TETRA} 2 {r} {r} {} {} {} {}",
            t[0] + 1,
            t[1] + 1,
            t[2] + 1,
            t[3] + 1
        );
    }
    for (t, &r) in mesh.triangles.iter().zip(&mesh.triangle_regions) {
        id += 1;
        let _ = writeln!(
            s,
            "{id} {MSH_TRIANGLE} 2 {r} {r} {} {} {}",
            t[0] + 1,
            t[1] + 1,
            t[2] + 1
        );
    }
    s.push_str("$EndElements\n");
    Ok(s)
}

/// Writes `mesh` as Gmsh MSH 2.2 ASCII, with `names` as its physical names.
pub fn write_msh(
    path: &Path,
    mesh: &VolumeMesh,
    names: &BTreeMap<u16, String>,
) -> Result<(), MeshIoError> {
    let text = msh_string(mesh, names).map_err(|e| MeshIoError::parse(path, "mesh to write", e))?;
    write_bytes(path, text.as_bytes())
}

/// Line-oriented cursor over the file, for messages that name the line.
struct Lines<'a> {
    path: &'a Path,
    iter: std::iter::Enumerate<std::str::Lines<'a>>,
    line: usize,
}

impl<'a> Lines<'a> {
    fn next(&mut self, expected: &str) -> Result<&'a str, MeshIoError> {
        match self.iter.next() {
            Some((i, l)) => {
                self.line = i + 1;
                Ok(l.trim())
            }
            None => Err(MeshIoError::parse(
                self.path,
                "end of file",
                expected.to_string(),
            )),
        }
    }
    fn err(&self, expected: impl Into<String>) -> MeshIoError {
        MeshIoError::parse(self.path, format!("line {}", self.line), expected)
    }
    fn numbers<T: std::str::FromStr>(&self, line: &str, what: &str) -> Result<Vec<T>, MeshIoError> {
        line.split_whitespace()
            .map(|w| {
                w.parse::<T>()
                    .map_err(|_| self.err(format!("{what}, found '{w}'")))
            })
            .collect()
    }
}

/// Reads a Gmsh MSH 2.2 ASCII file's tets and triangles.
pub fn read_msh(path: &Path) -> Result<VolumeMesh, MeshIoError> {
    let text = read_text(path)?;
    let mut lines = Lines {
        path,
        iter: text.lines().enumerate(),
        line: 0,
    };
    let mut mesh = VolumeMesh::default();
    let mut node_index: HashMap<u64, u32> = HashMap::new();
    let mut seen_format = false;
    let mut elements: Vec<(usize, Vec<u64>)> = Vec::new();
    while let Some((i, line)) = lines.iter.next() {
        lines.line = i + 1;
        match line.trim() {
            "$MeshFormat" => {
                let head = lines.next("the format line")?;
                let words: Vec<&str> = head.split_whitespace().collect();
                if words.len() < 3 || !words[0].starts_with("2.") {
                    return Err(lines.err(format!("MSH version 2.x ('2.2 0 8'), found '{head}'")));
                }
                if words[1] != "0" {
                    return Err(lines.err("file-type 0 (ASCII); binary MSH is not supported"));
                }
                seen_format = true;
            }
            "$Nodes" => {
                let n: usize = lines
                    .next("the node count")?
                    .parse()
                    .map_err(|_| lines.err("a node count"))?;
                for _ in 0..n {
                    let l = lines.next("a node line")?;
                    let w: Vec<&str> = l.split_whitespace().collect();
                    if w.len() < 4 {
                        return Err(lines.err("'id x y z'"));
                    }
                    let id: u64 = w[0]
                        .parse()
                        .map_err(|_| lines.err(format!("a node id, found '{}'", w[0])))?;
                    let c: Vec<f64> = lines.numbers(&w[1..4].join(" "), "a coordinate")?;
                    if node_index
                        .insert(id, mesh.tets.nodes.len() as u32)
                        .is_some()
                    {
                        return Err(lines.err(format!("distinct node ids, {id} repeats")));
                    }
                    mesh.tets.nodes.push(Point3::new(c[0], c[1], c[2]));
                }
                if lines.next("$EndNodes")? != "$EndNodes" {
                    return Err(lines.err("$EndNodes"));
                }
            }
            "$Elements" => {
                let n: usize = lines
                    .next("the element count")?
                    .parse()
                    .map_err(|_| lines.err("an element count"))?;
                for _ in 0..n {
                    let l = lines.next("an element line")?;
                    let w: Vec<u64> = lines.numbers(l, "a non-negative integer")?;
                    if w.len() < 3 || w.len() < 3 + w[2] as usize {
                        return Err(lines.err("'id type ntags tags... nodes...'"));
                    }
                    elements.push((lines.line, w));
                }
                if lines.next("$EndElements")? != "$EndElements" {
                    return Err(lines.err("$EndElements"));
                }
            }
            _ => {}
        }
    }
    if !seen_format {
        return Err(MeshIoError::parse(
            path,
            "file",
            "a $MeshFormat section (Gmsh MSH 2.2 ASCII)",
        ));
    }
    for (line, w) in elements {
        let (ty, ntags) = (w[1] as u32, w[2] as usize);
        let corners = match ty {
            MSH_TETRA => 4,
            MSH_TRIANGLE => 3,
            _ => continue,
        };
        let at = || format!("line {line}");
        let nodes = &w[3 + ntags..];
        if nodes.len() != corners {
            return Err(MeshIoError::parse(
                path,
                at(),
                format!("{corners} node ids for element type {ty}"),
            ));
        }
        let region = if ntags > 0 { w[3] } else { 0 };
        let region = u16::try_from(region)
            .map_err(|_| MeshIoError::parse(path, at(), "a physical tag up to 65535"))?;
        let mut ids = [0u32; 4];
        for (k, id) in nodes.iter().enumerate() {
            ids[k] = *node_index.get(id).ok_or_else(|| {
                MeshIoError::parse(path, at(), format!("a defined node id, found {id}"))
            })?;
        }
        if corners == 4 {
            mesh.tets.tets.push(ids);
            mesh.tets.regions.push(region);
        } else {
            mesh.triangles.push([ids[0], ids[1], ids[2]]);
            mesh.triangle_regions.push(region);
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io::test_meshes::kuhn_cube;
    use crate::mesh::tet::BoundaryOf;

    fn sample() -> VolumeMesh {
        let tets = kuhn_cube();
        let b = tets.boundary(BoundaryOf::Region(2));
        let triangles: Vec<[u32; 3]> = b.node_triangles();
        VolumeMesh {
            triangle_regions: vec![12; triangles.len()],
            triangles,
            tets,
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.msh");
        let mesh = sample();
        write_msh(&path, &mesh, &BTreeMap::new()).unwrap();
        assert_eq!(read_msh(&path).unwrap(), mesh);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n8\n"));
        assert!(text.contains("\n1 4 2 1 1 "));
    }

    #[test]
    fn other_element_types_are_skipped_and_ids_mapped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.msh");
        std::fs::write(&path, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 5 \"bone\"\n$EndPhysicalNames\n$Nodes\n4\n10 0 0 0\n20 1 0 0\n30 0 1 0\n40 0 0 1\n$EndNodes\n$Elements\n3\n1 15 2 0 1 10\n2 1 2 0 1 10 20\n3 4 2 5 1 10 20 30 40\n$EndElements\n").unwrap();
        let m = read_msh(&path).unwrap();
        assert_eq!(m.tets.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.tets.regions, vec![5]);
        assert!(m.triangles.is_empty());
        assert!((m.tets.volume() - 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn bad_files_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.msh");
        let good = msh_string(&sample(), &BTreeMap::new()).unwrap();
        let cases = [
            (good.replacen("2.2 0 8", "4.1 0 8", 1), "line 2"),
            (good.replacen("2.2 0 8", "2.2 1 8", 1), "binary"),
            (
                good.replacen("\n1 4 2 1 1 1 ", "\n1 4 2 1 1 99 ", 1),
                "found 99",
            ),
            (good.replacen("\n3 ", "\n3 x", 1), "line 8"),
            (good.replacen("$EndElements\n", "", 1), "$EndElements"),
            (
                good.replacen("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", "", 1),
                "$MeshFormat",
            ),
        ];
        for (text, needle) in cases {
            std::fs::write(&path, &text).unwrap();
            let e = read_msh(&path).unwrap_err().to_string();
            assert!(e.contains("bad.msh") && e.contains(needle), "{needle}: {e}");
        }
    }
}
