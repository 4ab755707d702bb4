//! The architecture invariants of ARCHITECTURE.md, checked on the source: every `crate::`
//! path and `super::` step points to the same or a lower layer (the layer list is read from
//! ARCHITECTURE.md's `layers` block, so the document and the check cannot drift apart), every
//! top-level module is in exactly one layer, and no two modules of the second level import
//! each other in a circle (outside unit tests).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The layers of ARCHITECTURE.md, top first: each line of its `layers` block is one layer.
fn layers() -> Vec<Vec<String>> {
    let doc = std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap();
    let block = doc
        .split("```layers\n")
        .nth(1)
        .and_then(|rest| rest.split("```").next())
        .expect("ARCHITECTURE.md has a ```layers block");
    block
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>())
        .filter(|l| !l.is_empty())
        .collect()
}

/// Every `.rs` file under `src/`, with its module path (`["register", "deform", "probe"]`).
fn sources() -> Vec<(Vec<String>, String)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let src = root().join("src");
    let mut files = Vec::new();
    walk(&src, &mut files);
    files.sort();
    files
        .into_iter()
        .filter_map(|path| {
            let rel = path.strip_prefix(&src).unwrap().with_extension("");
            let mut module: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if module.last().is_some_and(|m| m == "mod") {
                module.pop();
            }
            if module == ["lib"] || module == ["main"] {
                return None;
            }
            Some((module, std::fs::read_to_string(&path).unwrap()))
        })
        .collect()
}

/// The code of a file that is not test code: its unit-test block (from `#[cfg(test)]` on) cut.
fn non_test_code(text: &str) -> String {
    code(text.split("#[cfg(test)]").next().unwrap_or_default())
}

/// The module paths of test-only modules (`#[cfg(test)] mod x;`).
fn test_modules(sources: &[(Vec<String>, String)]) -> BTreeSet<Vec<String>> {
    let mut out = BTreeSet::new();
    for (module, text) in sources {
        for declared in text.split("#[cfg(test)]").skip(1) {
            let line = declared.trim_start().lines().next().unwrap_or_default();
            let name = line
                .trim_start_matches("pub(crate) ")
                .trim_start_matches("pub ")
                .strip_prefix("mod ")
                .and_then(|rest| rest.strip_suffix(';'));
            if let Some(name) = name {
                let mut path = module.clone();
                path.push(name.to_string());
                out.insert(path);
            }
        }
    }
    out
}

/// The code of a file without its comments.
fn code(text: &str) -> String {
    text.lines()
        .filter(|l| {
            let t = l.trim_start();
            !(t.starts_with("//") || t.starts_with("* "))
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths after each `crate::` in `code`, as their identifiers.
fn crate_paths(code: &str) -> Vec<Vec<String>> {
    code.match_indices("crate::")
        .filter(|(i, _)| {
            // not `otoatlas_crate::` or similar
            code[..*i]
                .chars()
                .last()
                .is_none_or(|c| !(c.is_alphanumeric() || c == '_'))
        })
        .map(|(i, m)| {
            let rest = &code[i + m.len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(rest.len());
            rest[..end]
                .split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect()
        })
        .filter(|p: &Vec<String>| !p.is_empty())
        .collect()
}

/// The top-level module a crate-root item belongs to (`crate::Error` is the pipeline's).
fn top_of(path: &[String]) -> String {
    match path[0].as_str() {
        "Error" => "pipeline".into(),
        other => other.into(),
    }
}

#[test]
fn every_arrow_points_down_the_layers_of_architecture_md() {
    let layers = layers();
    let count = layers.len();
    let level: BTreeMap<&str, usize> = layers
        .iter()
        .enumerate()
        .flat_map(|(i, l)| l.iter().map(move |m| (m.as_str(), count - i)))
        .collect();
    let sources = sources();
    let tops: BTreeSet<&str> = sources.iter().map(|(m, _)| m[0].as_str()).collect();
    let listed: BTreeSet<&str> = level.keys().copied().collect();
    assert_eq!(
        tops, listed,
        "the modules of src/ and the layers of ARCHITECTURE.md differ"
    );
    assert_eq!(
        layers.iter().map(Vec::len).sum::<usize>(),
        listed.len(),
        "a module is listed twice"
    );
    let mut wrong = Vec::new();
    for (module, text) in &sources {
        let from = module[0].as_str();
        for path in crate_paths(&code(text)) {
            let to = top_of(&path);
            if to == from {
                continue;
            }
            let Some(&to_level) = level.get(to.as_str()) else {
                wrong.push(format!("{}: crate::{} is no module", module.join("::"), to));
                continue;
            };
            if to_level >= level[from] {
                wrong.push(format!(
                    "{} (layer {}) uses crate::{} (layer {})",
                    module.join("::"),
                    level[from],
                    path.join("::"),
                    to_level
                ));
            }
        }
    }
    wrong.sort();
    wrong.dedup();
    assert!(
        wrong.is_empty(),
        "arrows up or sideways:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_two_second_level_modules_import_each_other_in_a_circle() {
    // unit tests may build their fixtures with a sibling module; the product's code may not
    let all = sources();
    let tests = test_modules(&all);
    let sources: Vec<(Vec<String>, String)> = all
        .into_iter()
        .filter(|(m, _)| !tests.iter().any(|t| m.starts_with(t)))
        .collect();
    let node = |m: &[String]| m.iter().take(2).cloned().collect::<Vec<_>>().join("::");
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (module, text) in &sources {
        let from = node(module);
        let code = non_test_code(text);
        let mut targets: Vec<Vec<String>> = crate_paths(&code)
            .into_iter()
            .filter(|p| p[0] == module[0] && p.len() > 1)
            .collect();
        // `super::x` from a submodule: the sibling `x` of its parent
        if module.len() >= 2 {
            let parent = &module[..module.len() - 1];
            for (i, m) in code.match_indices("super::") {
                let rest = &code[i + m.len()..];
                let end = rest
                    .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                    .unwrap_or(rest.len());
                let mut target = parent.to_vec();
                target.push(rest[..end].to_string());
                targets.push(target);
            }
        }
        for target in targets {
            // a module, not an item (items are CamelCase or SCREAMING)
            if target.len() < 2 || !target[1].starts_with(|c: char| c.is_ascii_lowercase()) {
                continue;
            }
            let to = node(&target);
            if to != from && sources.iter().any(|(m, _)| node(m) == to) {
                edges.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    // a circle: a module reachable from one of its own targets
    let reaches = |start: &str, goal: &str| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![start.to_string()];
        while let Some(n) = stack.pop() {
            if n == goal {
                return true;
            }
            if seen.insert(n.clone()) {
                stack.extend(edges.get(&n).into_iter().flatten().cloned());
            }
        }
        false
    };
    let circles: Vec<String> = edges
        .iter()
        .flat_map(|(from, tos)| tos.iter().map(move |to| (from, to)))
        .filter(|(from, to)| reaches(to, from))
        .map(|(from, to)| format!("{from} -> {to} -> ... -> {from}"))
        .collect();
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}
