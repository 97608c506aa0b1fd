use std::path::PathBuf;

/// Everything that can go wrong in a study.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StudyError {
    /// A study setting is not allowed.
    #[error("`{key}` = {value} is not allowed: expected {expected}")]
    InvalidSetting {
        /// The setting (flag or key).
        key: String,
        /// The value given.
        value: String,
        /// What is allowed.
        expected: String,
    },
    /// The scenario could not be loaded, changed or checked.
    #[error(transparent)]
    Scenario(#[from] magstand_sim::SimError),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A study file is malformed.
    #[error("{path}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the row and column where that applies.
        message: String,
    },
    /// An output file could not be written.
    #[error(transparent)]
    Output(#[from] magstand_core::CoreError),
    /// Shards cannot be merged.
    #[error("cannot merge: {0}")]
    Merge(String),
    /// The worker threads could not be started.
    #[error("thread pool: {0}")]
    Threads(String),
}
