use std::path::PathBuf;

/// Everything that can go wrong while reading, checking or writing a recording.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CoreError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The CSV layer could not parse a row (unbalanced quotes, wrong field count, ...).
    #[error("{path}: row {row}: malformed CSV: {message}")]
    Csv {
        /// The file concerned.
        path: PathBuf,
        /// 1-based data row (the header is row 0).
        row: usize,
        /// What the CSV parser said.
        message: String,
    },
    /// A required column is absent from the header.
    #[error("{path}: missing column `{column}` ({expected})")]
    MissingColumn {
        /// The file concerned.
        path: PathBuf,
        /// The column that was looked for.
        column: String,
        /// What the format expects.
        expected: String,
    },
    /// A column name appears twice.
    #[error("{path}: column `{column}` appears more than once in the header")]
    DuplicateColumn {
        /// The file concerned.
        path: PathBuf,
        /// The repeated column.
        column: String,
    },
    /// A cell could not be read as the number the column needs.
    #[error("{path}: row {row}, column `{column}`: {found:?} is not {expected}")]
    BadCell {
        /// The file concerned.
        path: PathBuf,
        /// 1-based data row.
        row: usize,
        /// Column name.
        column: String,
        /// The text found in the cell.
        found: String,
        /// What the column needs.
        expected: String,
    },
    /// Time does not strictly increase.
    #[error(
        "{path}: row {row}, column `t_s`: time {t_s} s is not after the previous row's {previous_s} s (time must strictly increase)"
    )]
    TimeNotIncreasing {
        /// The file concerned.
        path: PathBuf,
        /// 1-based data row.
        row: usize,
        /// Time at that row.
        t_s: f64,
        /// Time at the row before.
        previous_s: f64,
    },
    /// Not enough rows for what was asked.
    #[error("{path}: {rows} data rows, at least {needed} needed {why}")]
    TooFewRows {
        /// The file concerned.
        path: PathBuf,
        /// Rows found.
        rows: usize,
        /// Rows needed.
        needed: usize,
        /// Why they are needed.
        why: String,
    },
    /// The file is binary: a flight log or something else, where a recording (CSV text) was
    /// expected.
    #[error("{path}: {what}, not a recording (CSV text){hint}")]
    NotText {
        /// The file concerned.
        path: PathBuf,
        /// What the file looks like.
        what: String,
        /// How to make a recording of it, where magstand can.
        hint: String,
    },
    /// Columns inside one in-memory recording have different lengths.
    #[error("recording column `{column}` has {found} values but the recording has {expected} rows")]
    ColumnLength {
        /// Column name.
        column: String,
        /// Values in the column.
        found: usize,
        /// Rows in the recording.
        expected: usize,
    },
}

impl CoreError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CoreError::Io {
            path: path.into(),
            source,
        }
    }
}
