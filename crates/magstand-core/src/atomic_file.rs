//! Write-then-rename output, so that a failed run never leaves a half-written file behind and
//! never touches an existing file until the new one is complete.
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::CoreError;

/// The temporary path used while `path` is being written (same directory, so rename is atomic).
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
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
    let tmp = temporary_path(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp).map_err(|e| CoreError::io(&tmp, e))?;
        let mut w = BufWriter::new(file);
        body(&mut w)?;
        let file = w
            .into_inner()
            .map_err(|e| CoreError::io(&tmp, e.into_error()))?;
        file.sync_all().map_err(|e| CoreError::io(&tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| CoreError::io(path, e))?;
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes bytes to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), CoreError> {
    write_with(path, |w| {
        w.write_all(bytes).map_err(|e| CoreError::io(path, e))
    })
}
