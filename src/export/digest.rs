//! SHA-256 digests of files and folders: the per-file hashes a package's manifest lists, and
//! one digest over a set of inputs (a case's image, landmark file and segmentation) that a
//! batch can recompute before running to see whether a package is still current; and a
//! package's listing, which follows no link.

use std::collections::BTreeMap;
use std::path::Path;

use sha2::{Digest, Sha256};

use crate::io_util::{FileError, io_err, is_link_loop, link_loop_error, sha256_hex};

/// Every regular file under `dir` (recursively, following links), as paths relative to `dir`
/// with `/` separators, sorted, each with the SHA-256 of its bytes. A file `dir` itself gives
/// one entry named after it. A link that loops, or leads back to `dir` or above it, is an
/// error naming it (`io_util::is_loop_error` tells it), found before the walk goes round.
pub fn file_digests(dir: &Path) -> Result<BTreeMap<String, String>, FileError> {
    if dir.is_file() {
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        return Ok(BTreeMap::from([(name, file_sha256(dir)?)]));
    }
    Ok(walk(dir, true)?.files)
}

/// A folder's entries as `walk` found them.
#[derive(Debug, Default, PartialEq)]
pub struct Listing {
    /// Regular files (relative path, `/` separated) with the SHA-256 of their bytes.
    pub files: BTreeMap<String, String>,
    /// Entries that are neither a regular file nor a folder, with what they are: "symbolic
    /// link" (not followed), "FIFO", "socket", "block device", "character device".
    pub others: BTreeMap<String, &'static str>,
}

/// Every entry under `dir`, without following symbolic links: a package holds only regular
/// files and folders, so a link (which may point out of it) or a special file is listed as
/// such and never opened.
pub fn package_listing(dir: &Path) -> Result<Listing, FileError> {
    walk(dir, false)
}

/// What a non-regular, non-folder entry is.
fn kind(file_type: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    match file_type {
        t if t.is_symlink() => "symbolic link",
        t if t.is_fifo() => "FIFO",
        t if t.is_socket() => "socket",
        t if t.is_block_device() => "block device",
        t if t.is_char_device() => "character device",
        _ => "special file",
    }
}

fn walk(dir: &Path, follow_links: bool) -> Result<Listing, FileError> {
    let mut out = Listing::default();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((folder, prefix)) = stack.pop() {
        for entry in std::fs::read_dir(&folder).map_err(io_err(&folder))? {
            let entry = entry.map_err(io_err(&folder))?;
            let path = entry.path();
            let rel = format!("{prefix}{}", entry.file_name().to_string_lossy());
            let is_link = entry.file_type().is_ok_and(|t| t.is_symlink());
            if follow_links && is_link && is_link_loop(&path, &folder) {
                return Err(FileError {
                    path,
                    source: link_loop_error(),
                });
            }
            let meta = if follow_links {
                std::fs::metadata(&path)
            } else {
                std::fs::symlink_metadata(&path)
            }
            .map_err(io_err(&path))?;
            if meta.is_dir() {
                stack.push((path, format!("{rel}/")));
            } else if meta.is_file() {
                out.files.insert(rel, file_sha256(&path)?);
            } else {
                out.others.insert(rel, kind(meta.file_type()));
            }
        }
    }
    Ok(out)
}

/// SHA-256 of a file's bytes (lower-case hex), read in pieces (a file never whole in memory).
pub fn file_sha256(path: &Path) -> Result<String, FileError> {
    let mut file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut hasher = Sha256::new();
    std::io::copy(&mut file, &mut hasher).map_err(io_err(path))?;
    Ok(format!("{:x}", hasher.finalize()))
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

    /// A segmentation folder with a link back to itself was walked until the system refused
    /// (ELOOP after 40 levels, exit 1 after the whole run); a link that loops on itself so
    /// too. Both are the link's error, found at once, that `cli::exit` calls bad input.
    #[test]
    fn a_link_loop_is_named_not_walked() {
        for target in [".", "..", "../../seg", "self"] {
            let dir = tempfile::tempdir().unwrap();
            let seg = dir.path().join("seg");
            std::fs::create_dir_all(seg.join("sub")).unwrap();
            std::fs::write(seg.join("incus.ply"), b"ply").unwrap();
            std::os::unix::fs::symlink(target, seg.join("sub/self")).unwrap();
            let err = file_digests(&seg).unwrap_err();
            assert_eq!(err.path, seg.join("sub/self"), "{target}: {err}");
            assert!(
                crate::io_util::is_loop_error(&err.source),
                "{target}: {err}"
            );
            assert!(err.to_string().contains("symbolic links"), "{err}");
        }
        // a link to a folder elsewhere is followed
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("elsewhere")).unwrap();
        std::fs::write(dir.path().join("elsewhere/stapes.ply"), b"ply").unwrap();
        std::fs::create_dir_all(dir.path().join("seg")).unwrap();
        std::os::unix::fs::symlink("../elsewhere", dir.path().join("seg/linked")).unwrap();
        let d = file_digests(&dir.path().join("seg")).unwrap();
        assert_eq!(d.keys().collect::<Vec<_>>(), ["linked/stapes.ply"]);
    }
}
