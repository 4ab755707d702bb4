//! A cohort: the cases of a batch, read from a folder of case folders or from a manifest
//! (TOML or CSV: case id, image, optional landmarks, optional segmentation, optional DICOM
//! series; a case without landmarks has them proposed from its image), and its deterministic
//! slicing into shards for job arrays.
//!
//! Manifest paths are relative to the manifest's folder unless absolute.
//!
//! ```toml
//! [[case]]
//! id = "p01"
//! image = "scans/p01/dicom"
//! landmarks = "scans/p01/picks.fcsv"
//! segmentation = "scans/p01/seg"   # optional
//! series = "3f2a9c01"               # optional: which series of a folder holding several
//! ```
//!
//! ```text
//! id,image,landmarks,segmentation,series
//! p01,scans/p01/dicom,scans/p01/picks.fcsv,scans/p01/seg,3f2a9c01
//! ```
//!
//! `series` is what `run --series` takes (a SeriesInstanceUID or a prefix of at least 6 hex
//! digits of its SHA-256, as `inspect` lists them); a folder of case folders cannot name one.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::Case;
use super::case::IMAGE_NAMES;
use crate::image::nifti::is_nifti_path;

/// The cohort could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CohortError {
    #[error("{path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("{path}: case {id:?} appears twice; case ids must be unique")]
    DuplicateId { path: PathBuf, id: String },
    #[error(
        "{path}: no cases (expected case folders with dicom/ or image.nii.gz, or a manifest){skipped}"
    )]
    Empty { path: PathBuf, skipped: String },
    #[error("{path}, case {id:?}: {field} {file} does not exist")]
    MissingFile {
        path: PathBuf,
        id: String,
        field: &'static str,
        file: PathBuf,
    },
    #[error("--shard {given}: expected K/N with 0 <= K < N (K counts from 0)")]
    Shard { given: String },
}

/// One manifest row.
#[derive(Debug, Deserialize)]
struct ManifestCase {
    id: String,
    image: PathBuf,
    /// Empty or absent: the landmarks are proposed from the image.
    #[serde(default)]
    landmarks: Option<PathBuf>,
    #[serde(default)]
    segmentation: Option<PathBuf>,
    /// Empty or absent: the image must hold one series.
    #[serde(default)]
    series: Option<String>,
}

#[derive(Debug, Deserialize)]
struct TomlManifest {
    case: Vec<ManifestCase>,
}

/// A cohort as read: its cases, and what in a cohort folder was not taken as a case and why.
#[derive(Debug)]
pub struct Cohort {
    pub cases: Vec<Case>,
    pub skipped: Vec<Skipped>,
}

/// An entry of a cohort folder that is not a case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Skipped {
    /// The entry's name in the cohort folder.
    pub name: String,
    pub reason: String,
}

/// Reads the cohort at `path`: a folder whose sub-folders are cases, or a `.toml`/`.csv`
/// manifest. Cases come sorted by id.
pub fn read_cohort(path: &Path) -> Result<Cohort, CohortError> {
    let read_err = |message: String| CohortError::Read {
        path: path.to_path_buf(),
        message,
    };
    let mut skipped = Vec::new();
    let mut cases = if path.is_dir() {
        let (cases, skips) = folder_cases(path).map_err(|e| read_err(e.to_string()))?;
        skipped = skips;
        cases
    } else {
        let text = crate::io_util::read_text(path).map_err(|e| read_err(e.to_string()))?;
        let rows = match path.extension().and_then(|e| e.to_str()) {
            Some("toml") => {
                toml::from_str::<TomlManifest>(&text)
                    .map_err(|e| read_err(format!("not a cohort manifest: {e}")))?
                    .case
            }
            Some("csv") => csv::Reader::from_reader(text.as_bytes())
                .deserialize()
                .collect::<Result<Vec<ManifestCase>, _>>()
                .map_err(|e| {
                    read_err(format!(
                        "not a cohort manifest (columns id,image,landmarks[,segmentation][,series]): {e}"
                    ))
                })?,
            _ => {
                return Err(read_err(
                    "expected a folder of cases or a .toml/.csv manifest".into(),
                ));
            }
        };
        manifest_cases(path, rows)?
    };
    if cases.is_empty() {
        return Err(CohortError::Empty {
            path: path.to_path_buf(),
            skipped: skipped
                .iter()
                .map(|s| format!("\n  {}: {}", s.name, s.reason))
                .collect(),
        });
    }
    cases.sort_by(|a, b| a.id.cmp(&b.id));
    let mut seen = BTreeSet::new();
    for c in &cases {
        if !seen.insert(c.id.clone()) {
            return Err(CohortError::DuplicateId {
                path: path.to_path_buf(),
                id: c.id.clone(),
            });
        }
    }
    Ok(Cohort { cases, skipped })
}

/// The sub-folders of `dir` that `run` accepts as a case (`dicom/`, `image.nii.gz` or
/// `image.nii`, or DICOM files anywhere below), and every other entry with the reason it is
/// not one. Hidden entries (a leading dot) are ignored.
fn folder_cases(dir: &Path) -> std::io::Result<(Vec<Case>, Vec<Skipped>)> {
    let mut cases = Vec::new();
    let mut skipped = Vec::new();
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    entries.sort();
    for path in entries {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if name.starts_with('.') {
            continue;
        }
        match case_or_reason(&path) {
            Ok(case) => cases.push(case),
            Err(reason) => skipped.push(Skipped { name, reason }),
        }
    }
    Ok((cases, skipped))
}

/// True if `path` holds a case's image the way `Case::open` finds it by name.
fn has_named_image(path: &Path) -> bool {
    IMAGE_NAMES.iter().any(|n| path.join(n).exists())
}

fn case_or_reason(path: &Path) -> Result<Case, String> {
    if !path.is_dir() {
        return Err("not a folder".into());
    }
    if has_named_image(path) || crate::image::dicom::holds_dicom(path) {
        return Case::open(path).map_err(|e| e.to_string());
    }
    let children: Vec<PathBuf> = std::fs::read_dir(path)
        .map_err(|e| format!("cannot be read ({e})"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    if children.is_empty() {
        return Err("empty folder".into());
    }
    if children.iter().any(|c| c.is_dir() && has_named_image(c)) {
        return Err("holds case folders (a nested cohort): give it to batch as a cohort of its own, or list its cases in a manifest".into());
    }
    let niftis: Vec<String> = children
        .iter()
        .filter(|c| is_nifti_path(c))
        .filter_map(|c| c.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    if !niftis.is_empty() {
        return Err(format!(
            "holds {} but no image.nii.gz: rename the scan image.nii.gz, or list the case in a manifest",
            niftis.join(", ")
        ));
    }
    Err("no image: neither dicom/, image.nii.gz, image.nii nor any DICOM file".into())
}

fn manifest_cases(manifest: &Path, rows: Vec<ManifestCase>) -> Result<Vec<Case>, CohortError> {
    let base = manifest.parent().unwrap_or(Path::new("."));
    let resolve = |p: &Path| {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    };
    rows.into_iter()
        .map(|row| {
            let image = resolve(&row.image);
            let landmarks = row
                .landmarks
                .as_deref()
                .filter(|p| !p.as_os_str().is_empty())
                .map(resolve);
            let segmentation = row.segmentation.as_deref().map(resolve);
            let missing = [
                ("image", Some(&image)),
                ("landmarks", landmarks.as_ref()),
                ("segmentation", segmentation.as_ref()),
            ]
            .into_iter()
            .find_map(|(field, p)| p.filter(|p| !p.exists()).map(|p| (field, p.clone())));
            if let Some((field, file)) = missing {
                return Err(CohortError::MissingFile {
                    path: manifest.to_path_buf(),
                    id: row.id,
                    field,
                    file,
                });
            }
            Ok(Case {
                root: image.parent().unwrap_or(base).to_path_buf(),
                id: row.id,
                image,
                landmarks,
                segmentation,
                series: row.series.filter(|s| !s.trim().is_empty()),
            })
        })
        .collect()
}

/// The K-th of N deterministic slices of a cohort (cases sorted by id, every N-th from K).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// Parses `K/N` (K from 0).
    pub fn parse(text: &str) -> Result<Shard, CohortError> {
        let err = || CohortError::Shard {
            given: text.to_string(),
        };
        let (k, n) = text.split_once('/').ok_or_else(err)?;
        let index: usize = k.trim().parse().map_err(|_| err())?;
        let count: usize = n.trim().parse().map_err(|_| err())?;
        if count == 0 || index >= count {
            return Err(err());
        }
        Ok(Shard { index, count })
    }

    /// The shard of this Slurm array task, from `SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_MIN`
    /// and `SLURM_ARRAY_TASK_COUNT`, when they are set.
    pub fn from_slurm() -> Option<Shard> {
        let var = |n: &str| std::env::var(n).ok()?.trim().parse::<usize>().ok();
        let id = var("SLURM_ARRAY_TASK_ID")?;
        let count = var("SLURM_ARRAY_TASK_COUNT")?;
        let min = var("SLURM_ARRAY_TASK_MIN").unwrap_or(0);
        let index = id.checked_sub(min)?;
        (index < count).then_some(Shard { index, count })
    }

    /// This shard's cases.
    pub fn select(self, cases: Vec<Case>) -> Vec<Case> {
        cases
            .into_iter()
            .enumerate()
            .filter(|(i, _)| i % self.count == self.index)
            .map(|(_, c)| c)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case_folder(root: &Path, id: &str) {
        std::fs::create_dir_all(root.join(id).join("dicom")).unwrap();
        std::fs::write(root.join(id).join("landmarks.json"), "{}").unwrap();
    }

    #[test]
    fn a_folder_of_cases_is_read_sorted_and_skips_other_folders() {
        let dir = tempfile::tempdir().unwrap();
        for id in ["c2", "c0", "c1"] {
            case_folder(dir.path(), id);
        }
        std::fs::create_dir_all(dir.path().join("notes")).unwrap();
        std::fs::write(dir.path().join("notes/todo.txt"), "x").unwrap();
        std::fs::create_dir_all(dir.path().join("empty")).unwrap();
        std::fs::create_dir_all(dir.path().join("other")).unwrap();
        std::fs::write(dir.path().join("other/scan.nii.gz"), "x").unwrap();
        case_folder(&dir.path().join("group"), "g0");
        std::fs::write(dir.path().join("readme.txt"), "x").unwrap();
        std::fs::write(dir.path().join(".hidden"), "x").unwrap();
        let cohort = read_cohort(dir.path()).unwrap();
        let ids: Vec<String> = cohort.cases.into_iter().map(|c| c.id).collect();
        assert_eq!(ids, ["c0", "c1", "c2"]);
        let reasons: Vec<(&str, &str)> = cohort
            .skipped
            .iter()
            .map(|s| (s.name.as_str(), s.reason.split(' ').next().unwrap_or("")))
            .collect();
        assert_eq!(
            reasons,
            [
                ("empty", "empty"),
                ("group", "holds"),
                ("notes", "no"),
                ("other", "holds"),
                ("readme.txt", "not")
            ]
        );
        assert!(cohort.skipped[3].reason.contains("scan.nii.gz"));
        let empty = tempfile::tempdir().unwrap();
        assert!(matches!(
            read_cohort(empty.path()),
            Err(CohortError::Empty { .. })
        ));
    }

    #[test]
    fn manifests_resolve_paths_and_name_missing_files() {
        let dir = tempfile::tempdir().unwrap();
        case_folder(dir.path(), "a");
        let csv = dir.path().join("cohort.csv");
        std::fs::write(
            &csv,
            "id,image,landmarks,segmentation\np1,a/dicom,a/landmarks.json,\n",
        )
        .unwrap();
        let cases = read_cohort(&csv).unwrap().cases;
        assert_eq!(cases[0].id, "p1");
        assert_eq!(cases[0].image, dir.path().join("a/dicom"));
        assert_eq!(cases[0].segmentation, None);
        let toml_path = dir.path().join("cohort.toml");
        std::fs::write(
            &toml_path,
            "[[case]]\nid = \"p1\"\nimage = \"a/dicom\"\nlandmarks = \"a/landmarks.json\"\n\
             [[case]]\nid = \"p2\"\nimage = \"b/dicom\"\nlandmarks = \"a/landmarks.json\"\n",
        )
        .unwrap();
        match read_cohort(&toml_path) {
            Err(CohortError::MissingFile { id, field, .. }) => {
                assert_eq!((id.as_str(), field), ("p2", "image"))
            }
            other => panic!("expected a missing image, got {other:?}"),
        }
        std::fs::write(
            &toml_path,
            "[[case]]\nid = \"p1\"\nimage = \"a/dicom\"\nlandmarks = \"a/landmarks.json\"\n\
             [[case]]\nid = \"p1\"\nimage = \"a/dicom\"\nlandmarks = \"a/landmarks.json\"\n",
        )
        .unwrap();
        assert!(matches!(
            read_cohort(&toml_path),
            Err(CohortError::DuplicateId { .. })
        ));
    }

    #[test]
    fn a_manifest_names_the_series_of_a_folder_of_several() {
        let dir = tempfile::tempdir().unwrap();
        case_folder(dir.path(), "a");
        let csv = dir.path().join("cohort.csv");
        std::fs::write(
            &csv,
            "id,image,landmarks,series\np1,a/dicom,a/landmarks.json,3f2a9c01\np2,a/dicom,,\n",
        )
        .unwrap();
        let series: Vec<Option<String>> = read_cohort(&csv)
            .unwrap()
            .cases
            .into_iter()
            .map(|c| c.series)
            .collect();
        assert_eq!(series, [Some("3f2a9c01".to_string()), None]);
        let toml_path = dir.path().join("cohort.toml");
        std::fs::write(
            &toml_path,
            "[[case]]\nid = \"p1\"\nimage = \"a/dicom\"\nseries = \"1.2.840.99.1\"\n\
             [[case]]\nid = \"p2\"\nimage = \"a/dicom\"\nseries = \"\"\n",
        )
        .unwrap();
        let series: Vec<Option<String>> = read_cohort(&toml_path)
            .unwrap()
            .cases
            .into_iter()
            .map(|c| c.series)
            .collect();
        assert_eq!(series, [Some("1.2.840.99.1".to_string()), None]);
    }

    #[test]
    fn shards_partition_the_cohort() {
        let dir = tempfile::tempdir().unwrap();
        for i in 0..7 {
            case_folder(dir.path(), &format!("c{i}"));
        }
        let all = read_cohort(dir.path()).unwrap().cases;
        let mut seen: Vec<String> = (0..3)
            .flat_map(|k| {
                Shard { index: k, count: 3 }
                    .select(all.clone())
                    .into_iter()
                    .map(|c| c.id)
            })
            .collect();
        seen.sort();
        let ids: Vec<String> = all.iter().map(|c| c.id.clone()).collect();
        assert_eq!(seen, ids);
        assert_eq!(Shard::parse("1/3").unwrap(), Shard { index: 1, count: 3 });
        for bad in ["3/3", "1", "a/2", "0/0"] {
            assert!(Shard::parse(bad).is_err(), "{bad}");
        }
    }
}
