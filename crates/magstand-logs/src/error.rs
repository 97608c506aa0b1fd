/// Everything that can go wrong while importing logs or exporting a model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LogsError {
    /// The model cannot be exported in the requested form.
    #[error("cannot export: {0}")]
    Export(String),
}
