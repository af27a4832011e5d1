//! Atomic file writes: a file either appears whole or not at all.
//!
//! Every file skelform writes (meshes, pictures, the gallery page) goes through here, so
//! an interrupted or failed run never leaves a truncated file where a good one was, and a
//! program reading the target (a viewer watching it, the next step of a build) never sees
//! half of one. The content is written into a new temporary file `.NAME.tmp-PID-N` in the
//! target's own directory (a rename is only atomic within one file system), flushed and
//! synced to disk, then renamed over the target, and the directory is synced so that the
//! rename survives a crash too. On any error the temporary file is removed and the target
//! is left as it was. On Linux a large file being replaced is held open across the rename
//! and closed while the directory is synced, so that freeing its blocks overlaps that sync
//! instead of lengthening the rename. A writer may wrap the temporary file in [`WriteAhead`], which starts
//! the write-out to disk while the content is still being written, so that the final sync
//! has less to wait for; the sync itself, and so what is on disk when the write returns, is
//! the same.
//!
//! # Permissions, read-only targets, links
//!
//! - A new file gets the platform's default permissions (on Unix, `0o666` less the umask),
//!   like [`std::fs::write`]. A file that is replaced keeps its permission bits: the
//!   temporary file is given the target's mode before anything is written into it, so a
//!   `0600` file stays `0600` (its owner is the writer's, as after any rewrite by a user who
//!   is not root).
//! - A read-only target (no write bit set) is refused with
//!   [`io::ErrorKind::PermissionDenied`] and left as it is, although a rename could replace
//!   it: a file someone made read-only is not overwritten behind their back, as a shell's
//!   `>` would not either.
//! - A symbolic link is written *through*: the file it points at (following links to the
//!   end, up to 40 of them) is replaced, in its own directory, and the link is kept. A link
//!   to nothing creates the file it names.
//! - A target that exists but is not a regular file (a directory, a device such as
//!   `/dev/null`, a FIFO) is refused: renaming over it would replace the device node itself.
//!
//! # Signals
//!
//! On Unix, while a temporary file exists its path is in a registry of live temporary
//! files, and the first atomic write installs a handler for `SIGINT`, `SIGTERM` and
//! `SIGHUP` (for each signal whose disposition is still the default: a signal that is
//! ignored, as under `nohup`, stays ignored, and a handler the host program installed, a
//! Python interpreter's for instance, is left alone). The handler removes every registered
//! temporary file with `unlink` (async-signal-safe; the registry is a fixed array of atomic
//! pointers to paths allocated before registration, so the handler neither locks nor
//! allocates), restores the default disposition and raises the signal again, so the process
//! ends as killed by that signal: a shell reports the conventional status `128 + signo`
//! (130 for `SIGINT`, 143 for `SIGTERM`), and a shell loop running skelform stops on
//! Ctrl-C as it should. It is hand-written on `libc::sigaction` rather than `signal-hook`
//! because the whole handler is a dozen lines, must unlink from the handler itself (a flag
//! polled by a thread would not run while the writing thread is stuck in a slow `write`),
//! and skelform already depends on `libc`.
//!
//! What no handler can cover: `SIGKILL` (and a crash of the machine) leaves the temporary
//! file, hidden in the target's directory as `.NAME.tmp-PID-N` (for `out.ply`, written by
//! process 4242: `.out.ply.tmp-4242-0`); the target itself is never partial. Such files are
//! safe to delete. At most 64 temporary files are registered at once; a write beyond that
//! (64 concurrent atomic writes in one process) is still atomic, only not cleaned up on a
//! signal.
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
/// fails, `fill` included, the temporary file is removed and `path` is untouched. See the
/// [module documentation](self) for permissions, read-only targets, links and signals.
pub fn write_with<E>(
    path: &Path,
    fill: impl FnOnce(&mut File) -> Result<(), E>,
) -> Result<(), AtomicError<E>> {
    let path = resolve_links(path).map_err(AtomicError::Io)?;
    let file_name = path.file_name().ok_or_else(|| {
        AtomicError::Io(io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let existing = match fs::metadata(&path) {
        Ok(m) => Some(m),
        Err(e) if e.kind() == io::ErrorKind::NotFound => None,
        Err(e) => return Err(AtomicError::Io(e)),
    };
    if let Some(m) = &existing {
        if !m.is_file() && !m.is_dir() {
            return Err(AtomicError::Io(io::Error::other(format!(
                "{} exists and is not a regular file (a device, FIFO or socket); not replaced",
                path.display()
            ))));
        }
        if m.is_file() && m.permissions().readonly() {
            return Err(AtomicError::Io(io::Error::new(
                io::ErrorKind::PermissionDenied,
                format!(
                    "{} is read-only; not replaced (make it writable or remove it first)",
                    path.display()
                ),
            )));
        }
    }
    let (tmp, mut file, guard) = create_temp(dir, file_name).map_err(AtomicError::Io)?;
    let result = existing
        .as_ref()
        .filter(|m| m.is_file())
        .map_or(Ok(()), |m| file.set_permissions(m.permissions()))
        .map_err(AtomicError::Io)
        .and_then(|()| fill(&mut file).map_err(AtomicError::Write))
        .and_then(|()| {
            file.flush().and_then(|()| file.sync_all()).map_err(AtomicError::Io)?;
            drop(file);
            let replaced = existing.as_ref().and_then(|m| hold_replaced(&path, m));
            fs::rename(&tmp, &path).map_err(AtomicError::Io)?;
            Ok(replaced)
        });
    let outcome = match result {
        Ok(replaced) => {
            sync_dir_releasing(dir, replaced);
            Ok(())
        }
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(e)
        }
    };
    // Only now, after the rename or the removal: a signal before this point finds the path
    // registered and removes the file if it is still there.
    drop(guard);
    outcome
}

/// A writer over a temporary file of [`write_with`], filled from its start, that asks the
/// system to begin writing each completed stretch of [`WriteAhead::STEP`] bytes to disk
/// while the rest is still being produced (Linux's `sync_file_range` with
/// `SYNC_FILE_RANGE_WRITE`, which starts the write-out and does not wait for it). The sync
/// that [`write_with`] does at the end is unchanged and is still what makes the file
/// durable: this only means it finds most of the file on its way to the disk already, so it
/// waits for the tail instead of the whole (for a 23 MB mesh, about 9 ms less of the sync,
/// for a few ms more of writing). A failed request is ignored (the final sync reports any
/// real error); elsewhere than on Linux this is a plain pass-through writer.
pub struct WriteAhead<'a> {
    file: &'a mut File,
    /// Bytes written so far, the file's length.
    written: u64,
    /// Bytes whose write-out has been started.
    started: u64,
}

impl<'a> WriteAhead<'a> {
    /// How many written bytes make a write-out worth starting: small enough that the disk
    /// starts early, big enough that each request is a long sequential write.
    pub const STEP: u64 = 1 << 20;

    /// Wraps `file`, which must be empty and written from its start (as [`write_with`]
    /// gives it).
    pub fn new(file: &'a mut File) -> Self {
        WriteAhead { file, written: 0, started: 0 }
    }

    fn start_write_out(&mut self) {
        #[cfg(target_os = "linux")]
        {
            use std::os::fd::AsRawFd;
            let (Ok(from), Ok(len)) =
                (i64::try_from(self.started), i64::try_from(self.written - self.started))
            else {
                return;
            };
            // SAFETY: a plain system call on an open descriptor; it reads no memory of ours.
            unsafe {
                libc::sync_file_range(self.file.as_raw_fd(), from, len, libc::SYNC_FILE_RANGE_WRITE)
            };
        }
        self.started = self.written;
    }
}

impl Write for WriteAhead<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.file.write(buf)?;
        self.written += n as u64;
        if self.written - self.started >= Self::STEP {
            self.start_write_out();
        }
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

/// The file that writing `path` should replace: `path` itself, or, for a symbolic link, the
/// file at the end of its chain of links (which need not exist yet).
fn resolve_links(path: &Path) -> io::Result<PathBuf> {
    let mut current = path.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&current) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = fs::read_link(&current)?;
                current = match current.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(current),
        }
    }
    Err(io::Error::other(format!("{}: too many levels of symbolic links", path.display())))
}

/// Creates a new temporary file `DIR/.NAME.tmp-PID-N` that did not exist before. The
/// process id and a counter keep concurrent writers (threads, processes) apart; the leading
/// dot keeps it out of ordinary listings while it exists. The path is registered for
/// removal on a signal *before* the file is created, so that no signal can come between
/// the file's creation and its registration (the handler unlinking a path not created yet
/// is harmless); a name that turns out to be taken is unregistered before the next try.
fn create_temp(dir: &Path, file_name: &OsStr) -> io::Result<(PathBuf, File, signals::Registered)> {
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
        let guard = signals::Registered::new(&tmp);
        match fs::OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f, guard)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 100 => continue,
            Err(e) => return Err(e),
        }
    }
}

/// The registry of live temporary files and the signal handler that removes them.
#[cfg(unix)]
mod signals {
    use std::ffi::{CString, c_char, c_int};
    use std::os::unix::ffi::OsStrExt;
    use std::path::Path;
    use std::ptr;
    use std::sync::Once;
    use std::sync::atomic::{AtomicPtr, Ordering};

    /// How many temporary files can be registered at once.
    const SLOTS: usize = 64;
    const SIGNALS: [c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

    /// Each slot holds a path from `CString::into_raw`, or null. Whoever swaps a pointer out
    /// (the owner when done, or the handler) owns it, so the handler never reads a freed
    /// path.
    static REGISTRY: [AtomicPtr<c_char>; SLOTS] =
        [const { AtomicPtr::new(ptr::null_mut()) }; SLOTS];
    static INSTALL: Once = Once::new();

    extern "C" fn on_signal(signo: c_int) {
        for slot in &REGISTRY {
            let p = slot.swap(ptr::null_mut(), Ordering::SeqCst);
            if !p.is_null() {
                // SAFETY: `p` came from `CString::into_raw` and nobody else holds it now;
                // unlink is async-signal-safe. The path is leaked: the process ends.
                unsafe { libc::unlink(p) };
            }
        }
        // SA_RESETHAND has already restored the default action; raising the signal again
        // ends the process by it once the handler returns (it is blocked until then).
        // SAFETY: raise is async-signal-safe.
        unsafe { libc::raise(signo) };
    }

    fn install() {
        for signo in SIGNALS {
            // SAFETY: plain sigaction calls with zeroed, then filled, structures.
            unsafe {
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(signo, ptr::null(), &mut old) != 0
                    || old.sa_sigaction != libc::SIG_DFL
                {
                    continue;
                }
                let mut new: libc::sigaction = std::mem::zeroed();
                new.sa_sigaction = on_signal as extern "C" fn(c_int) as libc::sighandler_t;
                new.sa_flags = libc::SA_RESETHAND | libc::SA_RESTART;
                libc::sigemptyset(&mut new.sa_mask);
                for s in SIGNALS {
                    libc::sigaddset(&mut new.sa_mask, s);
                }
                libc::sigaction(signo, &new, ptr::null_mut());
            }
        }
    }

    /// A registered temporary file; dropping it takes the path out of the registry.
    pub(super) struct Registered(Option<usize>);

    impl Registered {
        pub(super) fn new(path: &Path) -> Self {
            INSTALL.call_once(install);
            let Ok(c) = CString::new(path.as_os_str().as_bytes()) else { return Registered(None) };
            let raw = c.into_raw();
            for (i, slot) in REGISTRY.iter().enumerate() {
                if slot
                    .compare_exchange(ptr::null_mut(), raw, Ordering::SeqCst, Ordering::SeqCst)
                    .is_ok()
                {
                    return Registered(Some(i));
                }
            }
            // SAFETY: `raw` came from `into_raw` just above and was not stored.
            drop(unsafe { CString::from_raw(raw) });
            Registered(None)
        }
    }

    impl Drop for Registered {
        fn drop(&mut self) {
            if let Some(i) = self.0 {
                let p = REGISTRY[i].swap(ptr::null_mut(), Ordering::SeqCst);
                if !p.is_null() {
                    // SAFETY: stored by `new` from `into_raw`, swapped out here exactly once.
                    drop(unsafe { CString::from_raw(p) });
                }
            }
        }
    }
}

/// Elsewhere there is no signal handling; the guard does nothing.
#[cfg(not(unix))]
mod signals {
    pub(super) struct Registered;
    impl Registered {
        pub(super) fn new(_: &std::path::Path) -> Self {
            Registered
        }
    }
}

/// How large a replaced file must be for its release to get a thread of its own.
const RELEASE_APART: u64 = 4 << 20;

/// The file the rename is about to replace, held open so that the rename does not free it:
/// the last close does, and [`sync_dir_releasing`] closes it while the directory is synced.
/// Freeing a file's blocks is not free (on ext4 mounted with `discard` and no journal, the
/// freed blocks are discarded on the spot: about 5 ms for a 23 MB mesh, as long again as
/// the directory's sync). Only a large regular file on Linux, opened read-only without
/// following a link and without blocking (a FIFO that took its place since it was checked
/// does not hang the write); `None` when it cannot be opened, and then the rename frees it
/// as before.
fn hold_replaced(path: &Path, m: &fs::Metadata) -> Option<File> {
    #[cfg(target_os = "linux")]
    if m.is_file() && m.len() >= RELEASE_APART {
        use std::os::unix::fs::OpenOptionsExt;
        return fs::OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW)
            .open(path)
            .ok();
    }
    let _ = (path, m);
    None
}

/// Syncs `dir` (the rename's durability, [`sync_dir`]) while a helper thread closes the
/// replaced file, so that its release overlaps the sync instead of following it. Both are
/// done when this returns. Without a thread the file is closed first, as the rename would
/// have freed it.
fn sync_dir_releasing(dir: &Path, replaced: Option<File>) {
    let Some(replaced) = replaced else { return sync_dir(dir) };
    std::thread::scope(|s| {
        // A failed spawn drops the closure, and the file with it, before the sync.
        let _release = std::thread::Builder::new()
            .name("release".into())
            .spawn_scoped(s, move || drop(replaced));
        sync_dir(dir);
    });
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

    #[cfg(unix)]
    #[test]
    fn replacing_keeps_the_mode_and_refuses_read_only_targets() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("secret.ply");
        write(&path, b"one").unwrap();
        fs::set_permissions(&path, fs::Permissions::from_mode(0o600)).unwrap();
        write(&path, b"two").unwrap();
        assert_eq!(fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o600);
        assert_eq!(fs::read(&path).unwrap(), b"two");
        fs::set_permissions(&path, fs::Permissions::from_mode(0o444)).unwrap();
        let e = write(&path, b"three").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::PermissionDenied);
        assert!(e.to_string().contains("read-only"), "{e}");
        assert_eq!(fs::read(&path).unwrap(), b"two");
        assert_eq!(listing(dir.path()), ["secret.ply"]);
    }

    #[cfg(unix)]
    #[test]
    fn links_are_written_through_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("real");
        fs::create_dir(&sub).unwrap();
        let file = sub.join("mesh.ply");
        write(&file, b"old").unwrap();
        let link = dir.path().join("link.ply");
        std::os::unix::fs::symlink("real/mesh.ply", &link).unwrap();
        let link2 = dir.path().join("link2.ply");
        std::os::unix::fs::symlink(&link, &link2).unwrap();
        write(&link2, b"new").unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert!(fs::symlink_metadata(&link2).unwrap().file_type().is_symlink());
        assert_eq!(fs::read(&file).unwrap(), b"new");
        assert_eq!(listing(&sub), ["mesh.ply"]);
        // A dangling link creates the file it names.
        let dangling = dir.path().join("dangling.ply");
        std::os::unix::fs::symlink("real/new.ply", &dangling).unwrap();
        write(&dangling, b"made").unwrap();
        assert_eq!(fs::read(sub.join("new.ply")).unwrap(), b"made");
        // A loop is an error, not a hang.
        let a = dir.path().join("a");
        std::os::unix::fs::symlink("b", &a).unwrap();
        std::os::unix::fs::symlink("a", dir.path().join("b")).unwrap();
        assert!(write(&a, b"x").unwrap_err().to_string().contains("symbolic links"));
    }

    /// A target large enough to be held open across the rename and released beside the
    /// directory's sync is replaced whole, like a small one.
    #[test]
    fn a_large_target_is_replaced_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.ply");
        let big = |seed: usize| -> Vec<u8> {
            (0..RELEASE_APART as usize + 4097).map(|i| (i * seed % 253) as u8).collect()
        };
        write(&path, &big(3)).unwrap();
        let m = fs::metadata(&path).unwrap();
        assert_eq!(hold_replaced(&path, &m).is_some(), cfg!(target_os = "linux"));
        write(&path, &big(5)).unwrap();
        assert!(fs::read(&path).unwrap() == big(5));
        write(&path, b"small").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"small");
        assert_eq!(listing(dir.path()), ["big.ply"]);
    }

    #[test]
    fn writing_ahead_writes_every_byte_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.bin");
        // Odd-sized writes across several write-out steps, and a tail after the last.
        let step = WriteAhead::STEP as usize;
        let bytes: Vec<u8> = (0..3 * step + 12_345).map(|i| (i * 7 % 251) as u8).collect();
        write_with(&path, |file| {
            let mut w = WriteAhead::new(file);
            bytes.chunks(65_537).try_for_each(|c| w.write_all(c))?;
            assert_eq!((w.written, w.started), (bytes.len() as u64, 3 * 65_537 * 16));
            w.flush()
        })
        .unwrap();
        assert!(fs::read(&path).unwrap() == bytes);
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_not_replaced() {
        let e = write(Path::new("/dev/null"), b"x").unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        use std::os::unix::fs::FileTypeExt;
        assert!(fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    }
}
