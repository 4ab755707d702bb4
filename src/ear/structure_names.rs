//! Which structure of the ear a surface file holds, from its name.
//!
//! Why: real data comes named by whoever exported it. The project writes `malleus.ply`, but a
//! 3D Slicer export is `Segmentation_Malleus.stl`, a library's specimen `01_Malleus.ply`, and
//! a chain segmented as one piece `Ossicular chain.obj`. A file whose stem is a structure's
//! name (in any case) names it; otherwise a stem whose words name exactly one structure does,
//! unless another file of the same folder claims that structure too (then neither guess is
//! made and the files keep their stems, which the callers report as unknown).

use std::path::{Path, PathBuf};

/// The structures a file name can name: each canonical name with the words (or phrases of
/// consecutive words) that name it. `ossicles` is also a canonical name of its own (the fused
/// chain's other file name), so an exact `ossicles` stem is kept as it is.
const WORDS: [(&str, &[&[&str]]); 5] = [
    ("malleus", &[&["malleus"], &["hammer"]]),
    ("incus", &[&["incus"], &["anvil"]]),
    ("stapes", &[&["stapes"], &["stirrup"]]),
    ("eardrum", &[&["eardrum"], &["tympanic", "membrane"]]),
    ("chain", &[&["chain"], &["ossicles"], &["ossicular"]]),
];

/// Stems kept as they are (lowercased) when a file is named exactly so.
const EXACT: [&str; 6] = ["malleus", "incus", "stapes", "eardrum", "chain", "ossicles"];

/// A file's stem: its name up to the first dot (`malleus.ply`, `chain.vtu`, `labels.nii.gz`).
pub fn file_stem(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    name.split('.').next().unwrap_or_default().to_string()
}

/// The stem's words, lowercased: split at every character that is not a letter or digit, and
/// where a lowercase letter is followed by an uppercase one (`RightMalleus`) or letters meet
/// digits (`Malleus01`).
fn words(stem: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut current = String::new();
    let mut previous: Option<char> = None;
    for c in stem.chars() {
        let boundary = match previous {
            None => false,
            Some(p) => {
                !c.is_alphanumeric()
                    || (p.is_lowercase() && c.is_uppercase())
                    || (p.is_alphabetic() != c.is_alphabetic())
            }
        };
        if boundary && !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
        if c.is_alphanumeric() {
            current.extend(c.to_lowercase());
        }
        previous = Some(c);
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// The structure a stem's words name, if they name exactly one (`01_Malleus` → malleus,
/// `Segmentation_Tympanic membrane` → eardrum; `malleus_incus` → none).
pub fn structure_in_words(stem: &str) -> Option<&'static str> {
    let words = words(stem);
    let mut named = WORDS.iter().filter(|(_, phrases)| {
        phrases.iter().any(|phrase| {
            words
                .windows(phrase.len())
                .any(|w| w.iter().zip(phrase.iter()).all(|(a, b)| a == b))
        })
    });
    match (named.next(), named.next()) {
        (Some((name, _)), None) => Some(name),
        _ => None,
    }
}

/// The structure name of each of `paths` (one folder's surface files): an exact structure
/// name in any case, lowercased; else the one structure its words name when no other file
/// claims it; else the stem as it is.
pub fn structure_names(paths: &[PathBuf]) -> Vec<String> {
    let stems: Vec<String> = paths.iter().map(|p| file_stem(p)).collect();
    let exact: Vec<Option<&str>> = stems
        .iter()
        .map(|s| EXACT.iter().copied().find(|e| e.eq_ignore_ascii_case(s)))
        .collect();
    let worded: Vec<Option<&str>> = stems
        .iter()
        .zip(&exact)
        .map(|(s, e)| e.is_none().then(|| structure_in_words(s)).flatten())
        .collect();
    stems
        .iter()
        .zip(exact.iter().zip(&worded))
        .map(
            |(stem, (exact_name, worded_name))| match (exact_name, worded_name) {
                (Some(name), _) => name.to_string(),
                (None, Some(name)) => {
                    let claimed_exactly = exact.iter().flatten().any(|e| claims(e, name));
                    let guesses = worded.iter().flatten().filter(|w| *w == name).count();
                    if claimed_exactly || guesses > 1 {
                        stem.clone()
                    } else {
                        name.to_string()
                    }
                }
                (None, None) => stem.clone(),
            },
        )
        .collect()
}

/// Whether a file named exactly `exact` holds the structure `name` (`ossicles` is the chain).
fn claims(exact: &str, name: &str) -> bool {
    exact == name || (exact == "ossicles" && name == "chain")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(files: &[&str]) -> Vec<String> {
        let paths: Vec<PathBuf> = files.iter().map(PathBuf::from).collect();
        structure_names(&paths)
    }

    #[test]
    fn words_split_at_separators_case_changes_and_digits() {
        assert_eq!(words("01_Malleus"), ["01", "malleus"]);
        assert_eq!(words("RightMalleus"), ["right", "malleus"]);
        assert_eq!(words("Malleus01"), ["malleus", "01"]);
        assert_eq!(
            words("Segmentation_Tympanic membrane"),
            ["segmentation", "tympanic", "membrane"]
        );
        assert_eq!(words("STAPES"), ["stapes"]);
        assert!(words("__").is_empty());
    }

    #[test]
    fn a_stem_names_a_structure_only_when_its_words_name_exactly_one() {
        assert_eq!(structure_in_words("01_Malleus"), Some("malleus"));
        assert_eq!(structure_in_words("left-incus-smoothed"), Some("incus"));
        assert_eq!(
            structure_in_words("Segmentation_Tympanic Membrane"),
            Some("eardrum")
        );
        assert_eq!(structure_in_words("Ossicular chain"), Some("chain"));
        assert_eq!(structure_in_words("malleus_incus"), None);
        assert_eq!(structure_in_words("membrane"), None);
        assert_eq!(structure_in_words("incusx"), None);
        assert_eq!(structure_in_words("Segment_1"), None);
    }

    #[test]
    fn exact_names_win_and_two_guesses_at_one_structure_make_none() {
        assert_eq!(
            names(&[
                "a/01_Malleus.stl",
                "a/02_Incus.stl",
                "a/03_Stapes.stl",
                "a/TM.stl"
            ]),
            ["malleus", "incus", "stapes", "TM"]
        );
        // the project's own name in another case, lowercased; the other malleus keeps its stem
        assert_eq!(
            names(&["a/Malleus.ply", "a/malleus_smoothed.ply"]),
            ["malleus", "malleus_smoothed"]
        );
        // two files that would both be the incus: no guess
        assert_eq!(
            names(&["a/incus_left.ply", "a/incus_right.ply", "a/stapes.ply"]),
            ["incus_left", "incus_right", "stapes"]
        );
        // an exact `ossicles` claims the chain; `chain` words elsewhere are not guessed
        assert_eq!(
            names(&["a/ossicles.obj", "a/chain_v2.obj"]),
            ["ossicles", "chain_v2"]
        );
        assert_eq!(names(&["a/labels.nii.gz"]), ["labels"]);
    }
}
