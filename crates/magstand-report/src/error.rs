use std::path::PathBuf;

/// Everything that can go wrong while drawing figures or writing a report.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// plotters could not draw a figure.
    #[error("figure `{figure}`: {message}")]
    Draw {
        /// The figure's name.
        figure: String,
        /// What plotters said.
        message: String,
    },
    /// There is nothing to draw (e.g. no finite values).
    #[error("figure `{figure}`: {message}")]
    Empty {
        /// The figure's name.
        figure: String,
        /// Why.
        message: String,
    },
    /// An output file could not be written.
    #[error(transparent)]
    Output(#[from] magstand_core::CoreError),
    /// A physics model cannot predict this recording.
    #[error(transparent)]
    Model(#[from] magstand_diagnose::DiagnoseError),
    /// An input file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
}
