use std::path::PathBuf;

/// Everything that can go wrong in a diagnosis.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// A diagnosis setting is not allowed.
    #[error("`{key}` = {value} is not allowed: expected {expected}")]
    InvalidSetting {
        /// The setting.
        key: String,
        /// The value given.
        value: String,
        /// What is allowed.
        expected: String,
    },
    /// The recording cannot be diagnosed against this scenario.
    #[error("{origin}: {message}")]
    Recording {
        /// The recording.
        origin: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The baseline calibration has no unique solution on this recording.
    #[error("{origin}: the baseline fit is singular ({message})")]
    Singular {
        /// The recording.
        origin: String,
        /// Which regressor and why.
        message: String,
    },
    /// A diagnosis file is malformed.
    #[error("{path}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The augmented scenario is out of the simulator's ranges.
    #[error(transparent)]
    Scenario(#[from] magstand_sim::SimError),
    /// An output file could not be written.
    #[error(transparent)]
    Output(#[from] magstand_core::CoreError),
    /// A local linear family of the automatic choice could not be fitted.
    #[error(transparent)]
    Identification(#[from] magstand_ident::IdentError),
}
