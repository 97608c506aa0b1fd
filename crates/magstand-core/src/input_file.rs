//! Reading an input file with its cost bounded by a size limit, not by what the file claims.
//!
//! Every reader of a user's file goes through here: a device such as `/dev/zero`, a FIFO or a
//! directory is refused by name before anything is read, and a regular file larger than the
//! reader's limit is refused before it is loaded. The errors are `std::io::Error`s with a
//! sentence a person can act on, so each crate keeps its own error type around them.
//!
//! ```
//! use magstand_core::input_file;
//! let e = input_file::read_to_string(std::path::Path::new("/"), 1024).unwrap_err();
//! assert!(e.to_string().contains("is a directory"));
//! ```
use std::collections::HashSet;
use std::io::{self, Read};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// The first bytes of a PX4 ULog file: `magstand import --ulog` reads it, and a reader of
/// another format names it by them.
pub const ULOG_MAGIC: &[u8] = b"ULog";
/// The first bytes of an ArduPilot DataFlash log (a message header): `magstand import
/// --dataflash` reads it, and a reader of another format names it by them.
pub const DATAFLASH_MAGIC: &[u8] = &[0xA3, 0x95];

/// Whether files opened here are remembered as inputs (see [`protect_inputs`]).
static PROTECTING: AtomicBool = AtomicBool::new(false);
/// The canonical paths of the inputs opened so far.
static INPUTS: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// From now on, every file this process opens through [`open`] is an input that
/// [`crate::atomic_file`] refuses to replace, under whatever path an output names it.
///
/// A program turns this on once at start (magstand's command-line tool does); libraries leave
/// it off, so a program that reads a file and then deliberately rewrites it is not hindered.
pub fn protect_inputs() {
    PROTECTING.store(true, Ordering::SeqCst);
}

fn remember(path: &Path) {
    if PROTECTING.load(Ordering::SeqCst)
        && let Ok(canonical) = std::fs::canonicalize(path)
    {
        INPUTS
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get_or_insert_with(HashSet::new)
            .insert(canonical);
    }
}

/// Whether `canonical` (a canonical path) is an input this process has opened while
/// [`protect_inputs`] was on.
pub fn is_protected(canonical: &Path) -> bool {
    INPUTS
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .as_ref()
        .is_some_and(|set| set.contains(canonical))
}

/// Largest recording CSV read, bytes (2 GiB: tens of millions of rows).
pub const MAX_RECORDING_BYTES: u64 = 2 << 30;
/// Largest log file read, bytes (2 GiB).
pub const MAX_LOG_BYTES: u64 = 2 << 30;
/// Largest model, diagnosis, study or scenario file read, bytes (64 MiB).
pub const MAX_DOCUMENT_BYTES: u64 = 64 << 20;

/// Opens `path` for reading after checking that it is a regular file of at most `max_bytes`.
pub fn open(path: &Path, max_bytes: u64) -> io::Result<std::fs::File> {
    let meta = std::fs::metadata(path)?;
    if meta.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is a directory; expected a file",
        ));
    }
    if !meta.is_file() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is not a regular file (a device, FIFO or socket); expected a file",
        ));
    }
    if meta.len() > max_bytes {
        return Err(too_large(meta.len(), max_bytes));
    }
    let file = std::fs::File::open(path)?;
    remember(path);
    Ok(file)
}

fn too_large(len: u64, max_bytes: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("is {len} bytes, more than the {max_bytes} bytes this input may have"),
    )
}

/// Reads all of `path` (see [`open`]); a file that grows past the limit while being read is
/// refused too.
pub fn read(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let file = open(path, max_bytes)?;
    #[cfg(unix)]
    if let Some(whole) = read_in_halves(&file, max_bytes) {
        return Ok(whole);
    }
    // The whole size up front: `take` hides it from `read_to_end`, which would otherwise grow
    // the buffer by doubling and copy the file several times over.
    let size = file.metadata().map_or(0, |m| m.len().min(max_bytes));
    let mut out = Vec::with_capacity(usize::try_from(size).unwrap_or(0).saturating_add(1));
    file.take(max_bytes + 1).read_to_end(&mut out)?;
    if out.len() as u64 > max_bytes {
        return Err(too_large(out.len() as u64, max_bytes));
    }
    Ok(out)
}

/// Files at least this large are read by two threads, each its half (a long recording: the
/// page-cache copy is a third of the time it takes to read one).
const HALVES_FROM_BYTES: u64 = 16 << 20;

/// A large file read as two halves at once, or `None` (a small file, a file whose size
/// changed while it was read, or any error: the caller reads it in order instead).
#[cfg(unix)]
fn read_in_halves(file: &std::fs::File, max_bytes: u64) -> Option<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    let size = file.metadata().ok()?.len();
    if !(HALVES_FROM_BYTES..=max_bytes).contains(&size) {
        return None;
    }
    let mut whole = vec![0u8; usize::try_from(size).ok()?];
    let half = whole.len() / 2;
    let (first, second) = whole.split_at_mut(half);
    let (a, b) = rayon::join(
        || file.read_exact_at(first, 0),
        || file.read_exact_at(second, half as u64),
    );
    let mut beyond = [0u8; 1];
    (a.is_ok() && b.is_ok() && file.read_at(&mut beyond, size).ok()? == 0).then_some(whole)
}

/// Reads all of `path` as UTF-8 text (see [`read`]).
pub fn read_to_string(path: &Path, max_bytes: u64) -> io::Result<String> {
    String::from_utf8(read(path, max_bytes)?).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "is not UTF-8 text (byte {} is not); expected a text file",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Reads a model, diagnosis, study or scenario file as text, bounded by
/// [`MAX_DOCUMENT_BYTES`] (see [`read_to_string`]).
pub fn read_document(path: &Path) -> io::Result<String> {
    read_to_string(path, MAX_DOCUMENT_BYTES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_large_file_read_in_halves_is_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("long.csv");
        let bytes: Vec<u8> = (0..(HALVES_FROM_BYTES + 12_345))
            .map(|k| (k % 251) as u8)
            .collect();
        std::fs::write(&p, &bytes).unwrap();
        assert!(read(&p, HALVES_FROM_BYTES + 12_345).unwrap() == bytes);
        let e = read(&p, HALVES_FROM_BYTES).unwrap_err().to_string();
        assert!(e.contains("more than"), "{e}");
    }

    #[test]
    fn devices_directories_and_large_files_are_refused_by_name() {
        let e = read(Path::new("/dev/zero"), 1 << 20)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
        let e = read(Path::new("/tmp"), 1 << 20).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.csv");
        std::fs::write(&p, vec![b'1'; 2000]).unwrap();
        let e = read(&p, 1000).unwrap_err().to_string();
        assert!(e.contains("2000 bytes") && e.contains("1000"), "{e}");
        assert_eq!(read(&p, 2000).unwrap().len(), 2000);
        std::fs::write(&p, [0xff, 0xfe]).unwrap();
        let e = read_to_string(&p, 10).unwrap_err().to_string();
        assert!(e.contains("not UTF-8"), "{e}");
    }
}
