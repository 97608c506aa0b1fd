//! Write-then-rename output, so that a failed or interrupted run never leaves a half-written
//! file behind and never touches an existing file until the new one is complete.
//!
//! The rules every output of magstand follows:
//! - the new content goes to a hidden temporary `.NAME.PID.tmp` beside the target, is synced,
//!   and is renamed over the target only when complete;
//! - a target that already exists keeps its permission bits (a 0600 file stays 0600);
//! - a target that is a symbolic link to a regular file is replaced at the link's target, so the
//!   link stays;
//! - a target that exists and is not a regular file (a device such as `/dev/null` or
//!   `/dev/stdout`, a FIFO, a socket, a folder) is refused: renaming over it would replace the
//!   special file with a regular one;
//! - once [`crate::input_file::protect_inputs`] is on, a target that is a file this process has
//!   read is refused, whatever path names it;
//! - temporaries of this process are listed while they exist, so that a handler of SIGINT and
//!   SIGTERM can remove them ([`remove_pending_temporaries`]); temporaries of the same target
//!   left by a process that no longer runs (SIGKILL, power loss) are removed before writing.
//!
//! Several files that belong together are staged first and renamed one after the other
//! ([`stage_with`], [`Staged::commit`]), so a failure while writing any of them changes none.
//!
//! ```
//! use magstand_core::atomic_file;
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("a.txt");
//! atomic_file::write_bytes(&path, b"first").unwrap();
//! atomic_file::write_bytes(&path, b"second").unwrap();
//! assert_eq!(std::fs::read(&path).unwrap(), b"second");
//! assert!(atomic_file::write_bytes(std::path::Path::new("/dev/null"), b"x").is_err());
//! ```
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::CoreError;

/// Temporaries this process is writing; removed by [`remove_pending_temporaries`].
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding the lock leaves a valid list; keep using it.
    PENDING.lock().unwrap_or_else(|p| p.into_inner())
}

/// Removes every temporary this process is still writing. Meant for a SIGINT/SIGTERM handler,
/// just before the process exits; the targets are left as they were.
pub fn remove_pending_temporaries() {
    for tmp in pending().drain(..) {
        let _ = std::fs::remove_file(tmp);
    }
}

/// The temporary path used while `path` is being written (same directory, so rename is atomic).
pub fn temporary_path(path: &Path) -> PathBuf {
    path.with_file_name(format!(".{}.{}.tmp", file_name(path), std::process::id()))
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn refused(path: &Path, why: &str) -> CoreError {
    CoreError::io(
        path,
        std::io::Error::new(std::io::ErrorKind::InvalidInput, why.to_string()),
    )
}

/// Where the content for `path` really goes: the path itself, or the file a symbolic link
/// names. Refuses special files and inputs of this process.
fn resolve_target(path: &Path) -> Result<PathBuf, CoreError> {
    if file_name(path).is_empty() {
        return Err(refused(path, "names no file; expected a file path"));
    }
    // `/dev/stdout` resolves to whatever stdout is, a regular file included: never replace it.
    if cfg!(unix) && (path.starts_with("/dev") || path.starts_with("/proc")) {
        return Err(refused(
            path,
            "is a device or process file; magstand writes only regular files, so name a file",
        ));
    }
    let target = match std::fs::metadata(path) {
        Ok(meta) if meta.is_file() => {
            std::fs::canonicalize(path).map_err(|e| CoreError::io(path, e))?
        }
        Ok(meta) if meta.is_dir() => {
            return Err(refused(path, "is a folder; expected a file path"));
        }
        Ok(_) => {
            return Err(refused(
                path,
                "is a device, FIFO or socket; magstand writes only regular files, so name a file",
            ));
        }
        // A link that points nowhere would be replaced by a file: refuse it too.
        Err(_) if std::fs::symlink_metadata(path).is_ok() => {
            return Err(refused(
                path,
                "is a symbolic link to nothing; expected a file path",
            ));
        }
        Err(_) => path.to_path_buf(),
    };
    if crate::input_file::is_protected(&target) {
        return Err(refused(
            path,
            "is one of this command's inputs; refusing to overwrite an input (choose another output path)",
        ));
    }
    Ok(target)
}

/// Removes `.NAME.PID.tmp` beside `target` whose process no longer runs.
fn remove_stale_temporaries(target: &Path) {
    let Some(dir) = target.parent() else { return };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{}.", file_name(target));
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = name
            .strip_prefix(&prefix)
            .and_then(|rest| rest.strip_suffix(".tmp"))
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !process_runs(pid) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

#[cfg(unix)]
fn process_runs(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return true;
    };
    // SAFETY: kill with signal 0 sends nothing; it only asks whether the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

#[cfg(not(unix))]
fn process_runs(_pid: u32) -> bool {
    // Without a way to ask, a temporary is never taken for stale.
    true
}

/// A complete file written beside its target, waiting to be renamed into place.
///
/// [`Staged::commit`] renames it; dropping it uncommitted removes it and leaves the target as
/// it was.
#[must_use = "a staged file is removed unless committed"]
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    target: PathBuf,
    shown: PathBuf,
    committed: bool,
}

impl Staged {
    /// Renames the staged file over its target, keeping the target's permission bits.
    pub fn commit(mut self) -> Result<(), CoreError> {
        if let Ok(meta) = std::fs::metadata(&self.target) {
            std::fs::set_permissions(&self.tmp, meta.permissions())
                .map_err(|e| CoreError::io(&self.shown, e))?;
        }
        std::fs::rename(&self.tmp, &self.target).map_err(|e| CoreError::io(&self.shown, e))?;
        self.committed = true;
        pending().retain(|p| p != &self.tmp);
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
            pending().retain(|p| p != &self.tmp);
        }
    }
}

/// Writes the content for `path` with `body` into a temporary beside it and returns it staged:
/// nothing at `path` changes until [`Staged::commit`].
pub fn stage_with<E>(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> Result<(), E>,
) -> Result<Staged, E>
where
    E: From<CoreError>,
{
    let target = resolve_target(path)?;
    remove_stale_temporaries(&target);
    let tmp = temporary_path(&target);
    pending().push(tmp.clone());
    // From here on, dropping `staged` removes the temporary.
    let staged = Staged {
        tmp,
        target,
        shown: path.to_path_buf(),
        committed: false,
    };
    let file = std::fs::File::create(&staged.tmp).map_err(|e| CoreError::io(path, e))?;
    let mut w = BufWriter::new(file);
    body(&mut w)?;
    let file = w
        .into_inner()
        .map_err(|e| CoreError::io(path, e.into_error()))?;
    file.sync_all().map_err(|e| CoreError::io(path, e))?;
    Ok(staged)
}

/// Calls `body` with a buffered writer to a temporary file beside `path`, then renames it into
/// place. On any error the temporary file is removed and `path` is left as it was.
pub fn write_with<E>(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> Result<(), E>,
) -> Result<(), E>
where
    E: From<CoreError>,
{
    Ok(stage_with(path, body)?.commit()?)
}

/// Writes bytes to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), CoreError> {
    stage_bytes(path, bytes)?.commit()
}

/// Writes bytes beside `path`, staged: nothing at `path` changes until [`Staged::commit`].
pub fn stage_bytes(path: &Path, bytes: &[u8]) -> Result<Staged, CoreError> {
    stage_with(path, |w| {
        w.write_all(bytes).map_err(|e| CoreError::io(path, e))
    })
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_replaced_file_keeps_its_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("secret.csv");
        std::fs::write(&path, "old").unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
        write_bytes(&path, b"new").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "mode {mode:o} after replacing a 0600 file");
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
    }

    #[test]
    fn special_files_and_folders_are_refused_and_left_alone() {
        let dir = tempfile::tempdir().unwrap();
        for p in ["/dev/null", "/dev/stdout", "/proc/self/fd/1"] {
            let e = write_bytes(Path::new(p), b"x").unwrap_err().to_string();
            assert!(e.contains(p) && e.contains("regular files"), "{p}: {e}");
        }
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: mkfifo on a path in a fresh temporary folder.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
        let e = write_bytes(&fifo, b"x").unwrap_err().to_string();
        assert!(e.contains("FIFO"), "{e}");
        let e = write_bytes(dir.path(), b"x").unwrap_err().to_string();
        assert!(e.contains("folder"), "{e}");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "left behind: {names:?}");
    }

    #[test]
    fn a_link_to_a_file_stays_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.txt");
        let link = dir.path().join("link.txt");
        std::fs::write(&real, "old").unwrap();
        std::os::unix::fs::symlink(&real, &link).unwrap();
        write_bytes(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
    }

    #[test]
    fn stale_temporaries_of_gone_processes_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("runs.csv");
        // PID 1 runs on every unix system; a PID above pid_max cannot run.
        let live = dir.path().join(".runs.csv.1.tmp");
        let stale = dir.path().join(".runs.csv.999999999.tmp");
        let other = dir.path().join(".other.csv.999999999.tmp");
        for p in [&live, &stale, &other] {
            std::fs::write(p, "partial").unwrap();
        }
        write_bytes(&path, b"new").unwrap();
        assert!(live.exists(), "a live process's temporary was removed");
        assert!(!stale.exists(), "a stale temporary was kept");
        assert!(other.exists(), "another file's temporary was removed");
    }

    #[test]
    fn a_staged_file_changes_nothing_until_committed_and_vanishes_when_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        let staged = stage_with::<CoreError>(&path, |w| {
            w.write_all(b"new").map_err(|e| CoreError::io(&path, e))
        })
        .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert!(pending().contains(&temporary_path(&path.canonicalize().unwrap())));
        drop(staged);
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1, "left behind: {names:?}");
    }
}
