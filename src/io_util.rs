//! Small file-system helpers shared by every writer: atomic writes (temporary sibling, then
//! rename) so a crash never leaves a half-written output, and hashing.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::Error;

/// Wraps an `std::io::Error` with the path it happened on.
pub fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Largest text input read whole (landmarks, configuration, manifests, mappings): far above
/// any real one, small enough that `/dev/zero` or a mistaken image path fails fast.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Reads a UTF-8 text file of at most [`MAX_TEXT_BYTES`], without reading further: a larger
/// (or endless) input is an `InvalidData` error saying so. A leading UTF-8 byte-order mark
/// is dropped.
pub fn read_text(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut bytes = Vec::new();
    fs::File::open(path)?
        .take(MAX_TEXT_BYTES + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_TEXT_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "larger than {} MiB, too large for a text input of this kind",
                MAX_TEXT_BYTES >> 20
            ),
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// The temporary sibling used while `path` is being written.
fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Writes `bytes` to `path` atomically: a temporary sibling is written, synced and renamed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        fs::create_dir_all(parent).map_err(io_err(parent))?;
    }
    let tmp = temp_sibling(path);
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(io_err(path)(e));
    }
    fs::rename(&tmp, path).map_err(io_err(path))
}

/// Writes the folder `dir` as a whole: `write` fills a temporary sibling, which then replaces
/// `dir` (an older `dir` is moved aside, and restored if the rename fails). On any error the
/// temporary is removed and an older `dir` is left as it was, so `dir` is complete or absent.
pub fn write_dir_atomic<T>(
    dir: &Path,
    write: impl FnOnce(&Path) -> Result<T, Error>,
) -> Result<T, Error> {
    let parent = dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    fs::create_dir_all(parent).map_err(io_err(parent))?;
    let tmp = temp_sibling(dir);
    let old = tmp.with_extension("old");
    for stale in [&tmp, &old] {
        if stale.exists() {
            fs::remove_dir_all(stale).map_err(io_err(stale))?;
        }
    }
    let result = write(&tmp).and_then(|value| {
        swap_into_place(&tmp, dir, &old)?;
        Ok(value)
    });
    if result.is_err() {
        let _ = fs::remove_dir_all(&tmp);
    }
    result
}

/// Renames `tmp` to `dir`; an existing `dir` is moved to `old` first and removed after.
fn swap_into_place(tmp: &Path, dir: &Path, old: &Path) -> Result<(), Error> {
    let had_old = dir.exists();
    if had_old {
        fs::rename(dir, old).map_err(io_err(dir))?;
    }
    if let Err(e) = fs::rename(tmp, dir) {
        if had_old {
            let _ = fs::rename(old, dir);
        }
        return Err(io_err(dir)(e));
    }
    if had_old {
        fs::remove_dir_all(old).map_err(io_err(old))?;
    }
    Ok(())
}

/// Lower-case hexadecimal SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_of_abc_matches_the_fips_vector() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn atomic_write_leaves_only_the_final_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("out.json");
        write_atomic(&path, b"{}").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"{}");
        let names: Vec<_> = fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1);
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn an_atomic_folder_replaces_the_old_one_whole_or_not_at_all() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("pkg");
        write_dir_atomic(&dir, |tmp| write_atomic(&tmp.join("a"), b"1")).unwrap();
        assert_eq!(names(&dir), ["a"]);
        // a failing writer leaves the old folder untouched and no temporary
        let failed = write_dir_atomic(&dir, |tmp| {
            write_atomic(&tmp.join("b"), b"2")?;
            Err::<(), _>(Error::Usage("stop".into()))
        });
        assert!(failed.is_err());
        assert_eq!(names(&dir), ["a"]);
        assert_eq!(names(root.path()), ["pkg"]);
        // a successful one replaces it whole
        let value = write_dir_atomic(&dir, |tmp| write_atomic(&tmp.join("b"), b"2").map(|_| 7));
        assert_eq!(value.unwrap(), 7);
        assert_eq!(names(&dir), ["b"]);
        assert_eq!(names(root.path()), ["pkg"]);
    }
}
