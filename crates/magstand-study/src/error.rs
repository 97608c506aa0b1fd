use std::path::PathBuf;

/// A setting of a study, named as [`crate::StudyConfig`] and [`crate::run_study`] name it
/// (a command line maps it to its own flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum StudySetting {
    /// The number of runs of the whole study.
    Runs,
    /// The slice of the runs this process runs.
    Shard,
    /// The methods compared.
    Methods,
    /// The worker threads.
    Threads,
    /// A procedure sweep (`key=v1,v2,...`).
    Sweep,
}

impl StudySetting {
    /// The setting's name (`runs`, `shard`, `methods`, `threads`, `sweep`).
    pub fn name(self) -> &'static str {
        match self {
            StudySetting::Runs => "runs",
            StudySetting::Shard => "shard",
            StudySetting::Methods => "methods",
            StudySetting::Threads => "threads",
            StudySetting::Sweep => "sweep",
        }
    }
}

impl std::fmt::Display for StudySetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Everything that can go wrong in a study.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StudyError {
    /// A study setting is not allowed.
    #[error("study setting `{setting}` = {value} is not allowed: expected {expected}")]
    InvalidSetting {
        /// The setting.
        setting: StudySetting,
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
    /// A method's fit could not be made.
    #[error(transparent)]
    Fit(#[from] magstand_ident::IdentError),
    /// The choice among model families could not be made.
    #[error(transparent)]
    Choice(#[from] magstand_diagnose::DiagnoseError),
}
