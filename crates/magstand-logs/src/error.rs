use std::path::PathBuf;

/// Everything that can go wrong while importing logs or exporting a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LogsError {
    /// The model cannot be exported in the requested form.
    #[error("cannot export: {0}")]
    Export(String),
    /// The Earth-field models have no field for the place or date asked.
    #[error("Earth field: {0}")]
    EarthModel(String),
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The bytes are not a log of the expected format, or break off before any usable data.
    #[error("{path}: not a readable {format} log: {what}")]
    Corrupt {
        /// The file concerned.
        path: PathBuf,
        /// "ULog" or "DataFlash".
        format: &'static str,
        /// What was wrong, and where.
        what: String,
    },
    /// A message, field or parameter the import needs is not in the log.
    #[error("{path}: {what} is missing; {hint}")]
    Missing {
        /// The file concerned.
        path: PathBuf,
        /// What was looked for.
        what: String,
        /// What the user can do about it.
        hint: String,
    },
    /// The log holds data, but not enough of it, or not in a usable shape.
    #[error("{path}: {what}")]
    Unusable {
        /// The file concerned.
        path: PathBuf,
        /// What was wrong.
        what: String,
    },
    /// A recording could not be built or written.
    #[error(transparent)]
    Recording(#[from] magstand_core::CoreError),
}

impl LogsError {
    /// The same error, saying that the file was damaged: what is missing may be missing
    /// because of it.
    pub(crate) fn on_damaged_file(self, damage: &str) -> Self {
        match self {
            LogsError::Missing { path, what, hint } => LogsError::Missing {
                path,
                what,
                hint: format!("{hint} (the file is damaged: {damage})"),
            },
            LogsError::Unusable { path, what } => LogsError::Unusable {
                path,
                what: format!("{what} (the file is damaged: {damage})"),
            },
            other => other,
        }
    }
}
