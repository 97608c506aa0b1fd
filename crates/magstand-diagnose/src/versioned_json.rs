//! The diagnosis file and the augmented model file are both pretty JSON with a `format` name
//! and a `version`: one reader refuses other formats and versions by name, one writer writes
//! atomically.
use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::DiagnoseError;

/// A malformed-file error for `path`.
pub(crate) fn malformed(path: &Path, message: String) -> DiagnoseError {
    DiagnoseError::Malformed {
        path: path.to_path_buf(),
        message,
    }
}

/// Reads `path` as a `T` whose `(format, version)` (given by `head`) must be the expected ones.
pub(crate) fn read<T: DeserializeOwned>(
    path: &Path,
    format: &str,
    version: u32,
    head: impl Fn(&T) -> (&str, u32),
) -> Result<T, DiagnoseError> {
    let text =
        magstand_core::input_file::read_document(path).map_err(|source| DiagnoseError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    parse(&text, path, format, version, head)
}

/// Parses `text`, read from `path`, as [`read`] does.
pub(crate) fn parse<T: DeserializeOwned>(
    text: &str,
    path: &Path,
    format: &str,
    version: u32,
    head: impl Fn(&T) -> (&str, u32),
) -> Result<T, DiagnoseError> {
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| malformed(path, e.to_string()))?;
    parse_value(value, path, format, version, head)
}

/// A document already parsed as JSON, read as [`parse`] reads text. A document of another
/// format (a model file given for a diagnosis) is named as such before its fields are read:
/// the first field it lacks would say less.
pub(crate) fn parse_value<T: DeserializeOwned>(
    value: serde_json::Value,
    path: &Path,
    format: &str,
    version: u32,
    head: impl Fn(&T) -> (&str, u32),
) -> Result<T, DiagnoseError> {
    match value.get("format").and_then(serde_json::Value::as_str) {
        Some(f) if f != format => {
            return Err(malformed(
                path,
                format!("this is a `{f}` document: expected a `{format}` one"),
            ));
        }
        None => {
            return Err(malformed(
                path,
                format!(
                    "no `format` field: expected a `{format}` document (JSON with \"format\": \"{format}\")"
                ),
            ));
        }
        Some(_) => {}
    }
    let value: T = serde_json::from_value(value).map_err(|e| malformed(path, e.to_string()))?;
    checked(value, path, format, version, head)
}

/// `value` if its `(format, version)` are the expected ones.
fn checked<T>(
    value: T,
    path: &Path,
    format: &str,
    version: u32,
    head: impl Fn(&T) -> (&str, u32),
) -> Result<T, DiagnoseError> {
    let (f, v) = head(&value);
    if f != format || v != version {
        return Err(malformed(
            path,
            format!("format {f} version {v}: expected {format} version {version}"),
        ));
    }
    Ok(value)
}

/// Writes `value` as pretty JSON, atomically.
pub(crate) fn write<T: Serialize>(value: &T, path: &Path) -> Result<(), DiagnoseError> {
    let text = serde_json::to_string_pretty(value).expect("plain data always serializes");
    magstand_core::atomic_file::write_bytes(path, text.as_bytes())?;
    Ok(())
}
