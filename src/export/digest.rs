//! SHA-256 digests of files and folders: the per-file hashes a package's manifest lists, and
//! one digest over a set of inputs (a case's image, landmark file and segmentation) that a
//! batch can recompute before running to see whether a package is still current.

use std::collections::BTreeMap;
use std::path::Path;

use crate::io_util::{FileError, io_err, sha256_hex};

/// Every regular file under `dir` (recursively, following links), as paths relative to `dir`
/// with `/` separators, sorted, each with the SHA-256 of its bytes. A file `dir` itself gives
/// one entry named after it.
pub fn file_digests(dir: &Path) -> Result<BTreeMap<String, String>, FileError> {
    let mut out = BTreeMap::new();
    if dir.is_file() {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        out.insert(name, file_sha256(dir)?);
        return Ok(out);
    }
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, prefix)) = stack.pop() {
        for entry in std::fs::read_dir(&folder).map_err(io_err(&folder))? {
            let entry = entry.map_err(io_err(&folder))?;
            let path = entry.path();
            let rel = format!("{prefix}{}", entry.file_name().to_string_lossy());
            let meta = std::fs::metadata(&path).map_err(io_err(&path))?;
            if meta.is_dir() {
                stack.push((path, format!("{rel}/")));
            } else if meta.is_file() {
                out.insert(rel, file_sha256(&path)?);
            }
        }
    }
    Ok(out)
}

/// SHA-256 of a file's bytes (lower-case hex).
pub fn file_sha256(path: &Path) -> Result<String, FileError> {
    Ok(sha256_hex(&std::fs::read(path).map_err(io_err(path))?))
}

/// One digest over named file digests: SHA-256 of the lines `name<TAB>sha256\n` in the order
/// given. Renaming, adding, removing or changing any file changes it.
pub fn combined_sha256<'a>(entries: impl IntoIterator<Item = (&'a str, &'a str)>) -> String {
    let mut listing = String::new();
    for (name, digest) in entries {
        listing.push_str(name);
        listing.push('\t');
        listing.push_str(digest);
        listing.push('\n');
    }
    sha256_hex(listing.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digests_list_every_file_and_follow_content_and_names() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("a/b")).unwrap();
        std::fs::write(dir.path().join("a/b/x.txt"), b"abc").unwrap();
        std::fs::write(dir.path().join("top"), b"").unwrap();
        let d = file_digests(dir.path()).unwrap();
        let keys: Vec<&str> = d.keys().map(String::as_str).collect();
        assert_eq!(keys, ["a/b/x.txt", "top"]);
        // FIPS 180-2 vectors for "abc" and ""
        assert_eq!(
            d["a/b/x.txt"],
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(
            d["top"],
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
        let all = |d: &BTreeMap<String, String>| {
            combined_sha256(d.iter().map(|(k, v)| (k.as_str(), v.as_str())))
        };
        let before = all(&d);
        std::fs::rename(dir.path().join("top"), dir.path().join("top2")).unwrap();
        assert_ne!(all(&file_digests(dir.path()).unwrap()), before);
    }
}
