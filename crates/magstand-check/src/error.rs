use std::path::PathBuf;

/// Everything that can stop a check file from running.
///
/// A limit that is not met is not an error: it is a failed [`crate::LimitResult`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CheckError {
    /// The check file is not valid TOML, or has no `[[check]]` entry.
    #[error("{origin}: {message}")]
    File {
        /// The check file.
        origin: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// One entry of the check file cannot run: a missing or wrong key, an unknown figure, a
    /// limit on a figure the method does not have, a scenario that does not load.
    #[error("{origin}: check {index} (\"{name}\"): `{key}`: {message}")]
    Entry {
        /// The check file.
        origin: String,
        /// The entry's position in the file, from 1.
        index: usize,
        /// The entry's name (empty when it has none).
        name: String,
        /// The key at fault.
        key: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The check file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The study behind a check could not run (thread pool, scenario draws).
    #[error("check \"{check}\": {source}")]
    Study {
        /// The check.
        check: String,
        /// What the study said (boxed: a study error is large, and rare).
        source: Box<magstand_study::StudyError>,
    },
    /// The JUnit report could not be serialised.
    #[error("JUnit report: {0}")]
    Junit(String),
}
