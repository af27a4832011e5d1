//! Atomic file writes: a file either appears whole or not at all.
//!
//! Every file skelform writes (meshes, pictures, the gallery page) goes through here, so
//! an interrupted or failed run never leaves a truncated file where a good one was, and a
//! program reading the target (a viewer watching it, the next step of a build) never sees
//! half of one. The content is written into a new temporary file `.NAME.tmp-PID-N` in the
//! target's own directory (a rename is only atomic within one file system), flushed and
//! synced to disk, then renamed over the target, and the directory is synced so that the
//! rename survives a crash too. On any error the temporary file is removed and the target
//! is left as it was.
//!
//! The file is created with the platform's default permissions (on Unix, `0o666` less the
//! umask), like a plain [`std::fs::write`]; a target that existed is replaced, not
//! modified, so its own permissions are not kept.
//!
//! ```
//! use skelform_mesh::io::atomic;
//! let dir = std::env::temp_dir().join(format!("atomic-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("notes.txt");
//! atomic::write(&path, b"first").unwrap();
//! atomic::write(&path, b"second").unwrap();
//! assert_eq!(std::fs::read(&path).unwrap(), b"second");
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

use std::ffi::{OsStr, OsString};
use std::fmt;
use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Why an atomic write failed: the file system, or the caller's own writing.
#[derive(Debug)]
pub enum AtomicError<E> {
    /// The path names no file, or the temporary file could not be created, flushed, synced
    /// or renamed over the target.
    Io(io::Error),
    /// The closure given to [`write_with`] failed.
    Write(E),
}

impl<E: fmt::Display> fmt::Display for AtomicError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AtomicError::Io(e) => e.fmt(f),
            AtomicError::Write(e) => e.fmt(f),
        }
    }
}

impl<E: std::error::Error + 'static> std::error::Error for AtomicError<E> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            AtomicError::Io(e) => Some(e),
            AtomicError::Write(e) => Some(e),
        }
    }
}

/// Writes `bytes` to `path` atomically (see the [module documentation](self)).
pub fn write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_with(path, |file| file.write_all(bytes)).map_err(|e| match e {
        AtomicError::Io(e) | AtomicError::Write(e) => e,
    })
}

/// Writes `path` atomically with `fill`, which writes the content into the temporary file
/// (it need not flush; a buffered writer over the file must be flushed before it returns).
/// Once `fill` succeeds the file is flushed, synced and renamed over `path`; if anything
/// fails, `fill` included, the temporary file is removed and `path` is untouched.
pub fn write_with<E>(
    path: &Path,
    fill: impl FnOnce(&mut File) -> Result<(), E>,
) -> Result<(), AtomicError<E>> {
    let file_name = path.file_name().ok_or_else(|| {
        AtomicError::Io(io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let (tmp, mut file) = create_temp(dir, file_name).map_err(AtomicError::Io)?;
    let result = fill(&mut file).map_err(AtomicError::Write).and_then(|()| {
        file.flush().and_then(|()| file.sync_all()).map_err(AtomicError::Io)?;
        drop(file);
        fs::rename(&tmp, path).map_err(AtomicError::Io)
    });
    match result {
        Ok(()) => {
            sync_dir(dir);
            Ok(())
        }
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Creates a new temporary file `DIR/.NAME.tmp-PID-N` that did not exist before. The
/// process id and a counter keep concurrent writers (threads, processes) apart; the leading
/// dot keeps it out of ordinary listings while it exists.
fn create_temp(dir: &Path, file_name: &OsStr) -> io::Result<(PathBuf, File)> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let pid = std::process::id();
    let mut attempts = 0;
    loop {
        attempts += 1;
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let mut name = OsString::from(".");
        name.push(file_name);
        name.push(format!(".tmp-{pid}-{n}"));
        let tmp = dir.join(name);
        match fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 100 => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Makes the rename durable where the platform allows it; failures are not errors (the file
/// itself is complete and synced).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn writes_replace_the_target_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write(&path, b"a longer first version").unwrap();
        write(&path, b"short").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"short");
        assert_eq!(listing(dir.path()), ["a.txt"]);
    }

    #[test]
    fn a_failing_fill_leaves_the_target_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("keep.txt");
        write(&path, b"before").unwrap();
        let e = write_with(&path, |f| {
            f.write_all(b"half").map_err(|e| e.to_string())?;
            Err("refused".to_string())
        })
        .unwrap_err();
        assert!(matches!(&e, AtomicError::Write(m) if m == "refused"), "{e:?}");
        assert_eq!(fs::read(&path).unwrap(), b"before");
        assert_eq!(listing(dir.path()), ["keep.txt"]);
    }

    #[test]
    fn a_failing_rename_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        // A non-empty directory cannot be replaced by a file.
        let target = dir.path().join("taken");
        fs::create_dir(&target).unwrap();
        fs::write(target.join("inside"), b"x").unwrap();
        let e = write(&target, b"data").unwrap_err();
        assert_ne!(e.kind(), io::ErrorKind::InvalidInput);
        assert_eq!(listing(dir.path()), ["taken"]);
        assert_eq!(listing(&target), ["inside"]);
    }

    #[test]
    fn a_path_without_a_file_name_is_refused() {
        let e = write(Path::new("/"), b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        let e = write(Path::new("dir/.."), b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    }
}
