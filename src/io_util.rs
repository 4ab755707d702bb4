//! Small file-system helpers shared by every writer: atomic writes (temporary sibling, then
//! rename) so a crash never leaves a half-written output, and hashing; and, for the readers
//! that walk folders following links, capped text reads and symbolic link loops.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// A file-system failure and the path it happened on: the one error of this module, which
/// each layer folds into its own.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct FileError {
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

/// Wraps an `std::io::Error` with the path it happened on.
pub fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> FileError + '_ {
    move |source| FileError {
        path: path.to_path_buf(),
        source,
    }
}

/// True if the symbolic link `link` under `root` never resolves (a chain of links that loops)
/// or resolves to `root` or a folder above it: either would make anything that follows links
/// through the folder (scanning a series, hashing a case's inputs) go round until the system
/// refuses.
pub fn is_link_loop(link: &Path, root: &Path) -> bool {
    match fs::canonicalize(link) {
        Ok(target) => fs::canonicalize(root).is_ok_and(|root| root.starts_with(&target)),
        Err(e) => is_loop_error(&e),
    }
}

/// True if `e` is the system's "too many levels of symbolic links" (ELOOP; std has no stable
/// `ErrorKind` for it), as [`link_loop_error`] makes it too.
pub fn is_loop_error(e: &std::io::Error) -> bool {
    #[cfg(target_os = "linux")]
    {
        e.raw_os_error() == Some(rustix::io::Errno::LOOP.raw_os_error())
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = e;
        false
    }
}

/// The system's "too many levels of symbolic links" error, for a link loop found before the
/// system would refuse it.
pub fn link_loop_error() -> std::io::Error {
    #[cfg(target_os = "linux")]
    {
        std::io::Error::from_raw_os_error(rustix::io::Errno::LOOP.raw_os_error())
    }
    #[cfg(not(target_os = "linux"))]
    {
        std::io::Error::other("symbolic link loop")
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
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
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

/// Writes `value` to `path` as pretty JSON with a final newline, atomically: the form of every
/// JSON record and output the project writes.
pub fn write_json_file<T: serde::Serialize + ?Sized>(
    path: &Path,
    value: &T,
) -> Result<(), FileError> {
    let text = serde_json::to_string_pretty(value).unwrap_or_default() + "\n";
    write_atomic(path, text.as_bytes())
}

/// Writes the folder `dir` as a whole: `write` fills a temporary sibling, which then replaces
/// `dir` (exchanged with an older `dir` in one step where the system can). On any error the
/// temporary is removed and an older `dir` is left as it was, so `dir` is complete or absent.
/// Temporaries that killed runs left beside `dir` are removed first.
pub fn write_dir_atomic<T, E: From<FileError>>(
    dir: &Path,
    write: impl FnOnce(&Path) -> Result<T, E>,
) -> Result<T, E> {
    let parent = dir
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    fs::create_dir_all(parent).map_err(io_err(parent))?;
    let tmp = temp_sibling(dir);
    let old = tmp.with_extension("old");
    remove_stale_siblings(dir)?;
    let result = write(&tmp).and_then(|value| {
        swap_into_place(&tmp, dir, &old)?;
        Ok(value)
    });
    if result.is_err() {
        let _ = fs::remove_dir_all(&tmp);
    }
    result
}

/// Renames `tmp` to `dir`. An existing `dir` is exchanged with `tmp` in one step where the
/// system can (Linux `renameat2` with `RENAME_EXCHANGE`), so `dir` is never absent even if
/// the process is killed; elsewhere it is moved to `old` first. The old folder is removed
/// after.
fn swap_into_place(tmp: &Path, dir: &Path, old: &Path) -> Result<(), FileError> {
    if !dir.exists() {
        return fs::rename(tmp, dir).map_err(io_err(dir));
    }
    #[cfg(target_os = "linux")]
    {
        use rustix::fs::{CWD, RenameFlags, renameat_with};
        if renameat_with(CWD, tmp, CWD, dir, RenameFlags::EXCHANGE).is_ok() {
            // `tmp` now holds the old folder
            return fs::remove_dir_all(tmp).map_err(io_err(tmp));
        }
    }
    fs::rename(dir, old).map_err(io_err(dir))?;
    if let Err(e) = fs::rename(tmp, dir) {
        let _ = fs::rename(old, dir);
        return Err(io_err(dir)(e));
    }
    fs::remove_dir_all(old).map_err(io_err(old))
}

/// Removes the temporary siblings of `path` (`.NAME.PID.tmp`, `.NAME.PID.old`) that a killed
/// process left: those of this process and of processes no longer running.
fn remove_stale_siblings(path: &Path) -> Result<(), FileError> {
    let (Some(parent), Some(name)) = (path.parent(), path.file_name()) else {
        return Ok(());
    };
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = fs::read_dir(parent) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        let Some(pid) = rest
            .strip_suffix(".tmp")
            .or_else(|| rest.strip_suffix(".old"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        let alive = pid != std::process::id() && Path::new(&format!("/proc/{pid}")).exists();
        if !alive {
            let stale = entry.path();
            let removed = if stale.is_dir() {
                fs::remove_dir_all(&stale)
            } else {
                fs::remove_file(&stale)
            };
            removed.map_err(io_err(&stale))?;
        }
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
            Err::<(), _>(io_err(tmp)(std::io::Error::other("stop")))
        });
        assert!(failed.is_err());
        assert_eq!(names(&dir), ["a"]);
        assert_eq!(names(root.path()), ["pkg"]);
        // a successful one replaces it whole
        let value = write_dir_atomic(&dir, |tmp| write_atomic(&tmp.join("b"), b"2").map(|_| 7));
        assert_eq!(value.unwrap(), 7);
        assert_eq!(names(&dir), ["b"]);
        assert_eq!(names(root.path()), ["pkg"]);
        // temporaries a killed run left (its process gone) are removed by the next write;
        // those of a running process (pid 1) are not touched
        for stale in [".pkg.99999999.tmp", ".pkg.99999999.old", ".pkg.1.tmp"] {
            write_atomic(&root.path().join(stale).join("x"), b"0").unwrap();
        }
        write_dir_atomic(&dir, |tmp| write_atomic(&tmp.join("c"), b"3")).unwrap();
        assert_eq!(names(&dir), ["c"]);
        assert_eq!(names(root.path()), [".pkg.1.tmp", "pkg"]);
    }
}
