//! Reading `scene.scn` for `verify`: its elements by tag, an attribute's numbers, and the
//! tolerance a recomputed number must meet.

use std::collections::BTreeMap;

use roxmltree::Node;

use super::faults::Faults;
use crate::export::scene::SCENE;

/// Largest relative difference accepted between a scene number and its recomputation.
const REL_TOL: f64 = 1e-9;

pub(super) fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= REL_TOL * a.abs().max(b.abs())
}

/// The scene's elements by tag name.
#[derive(Default)]
pub(super) struct Scene<'a, 'input> {
    by_tag: BTreeMap<&'a str, Vec<Node<'a, 'input>>>,
}

impl<'a, 'input> Scene<'a, 'input> {
    /// Records one element.
    pub(super) fn add(&mut self, tag: &'a str, node: Node<'a, 'input>) {
        self.by_tag.entry(tag).or_default().push(node);
    }

    /// Every element named `tag`.
    pub(super) fn all(&self, tag: &str) -> impl Iterator<Item = Node<'a, 'input>> + '_ {
        self.by_tag.get(tag).into_iter().flatten().copied()
    }

    /// The one element named `tag` (a fault if absent or repeated).
    pub(super) fn one(&self, tag: &str, faults: &mut Faults) -> Option<Node<'a, 'input>> {
        match self.by_tag.get(tag).map(Vec::as_slice) {
            Some([node]) => Some(*node),
            found => {
                let n = found.map_or(0, <[_]>::len);
                faults.add(
                    "scene",
                    SCENE,
                    format!("{n} {tag} components, expected one"),
                );
                None
            }
        }
    }
}

/// The numbers of attribute `attr` of `node` (a fault if absent or not numbers).
pub(super) fn numbers(node: Node, attr: &str, faults: &mut Faults) -> Option<Vec<f64>> {
    let tag = node.tag_name().name();
    let Some(text) = node.attribute(attr) else {
        faults.add("scene", SCENE, format!("{tag} has no {attr}"));
        return None;
    };
    let parsed: Result<Vec<f64>, _> = text.split_whitespace().map(str::parse).collect();
    match parsed {
        Ok(v) if v.iter().all(|x| x.is_finite()) => Some(v),
        _ => {
            faults.add(
                "scene",
                SCENE,
                format!("{tag}.{attr}: expected finite numbers"),
            );
            None
        }
    }
}
