/// Everything that can go wrong while identifying or applying a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentError {
    /// A hyper-parameter is outside its allowed range.
    #[error("invalid setting `{key}` = {value}: expected {expected}")]
    InvalidSetting {
        /// Name of the setting (as on the command line).
        key: String,
        /// Value given.
        value: String,
        /// Allowed range.
        expected: String,
    },
    /// The recording lacks what the fit needs.
    #[error("{origin}: {message}")]
    Data {
        /// File or description of the recording.
        origin: String,
        /// What is missing or wrong.
        message: String,
    },
    /// The data cannot determine the model (e.g. the throttle never varies).
    #[error("{origin}: the data cannot determine the {what}: {why}")]
    Singular {
        /// File or description of the recording.
        origin: String,
        /// Which fit.
        what: String,
        /// Why, in terms of the data.
        why: String,
    },
    /// A model file is malformed or of an unknown version.
    #[error("{origin}: {message}")]
    ModelFile {
        /// File name.
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error(transparent)]
    Core(#[from] magstand_core::CoreError),
}
