use std::path::PathBuf;

/// Everything that can go wrong while loading, checking or running a scenario.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The scenario text is not valid TOML or does not match the scenario schema (unknown key,
    /// wrong type). The message from the TOML parser names the key and line.
    #[error("{origin}: {message}")]
    Parse {
        /// File or text the scenario came from.
        origin: String,
        /// What the parser said.
        message: String,
    },
    /// A setting has a value outside its allowed range.
    #[error("{origin}: `{key}` = {value} is not allowed: expected {expected}")]
    InvalidSetting {
        /// File or text the scenario came from.
        origin: String,
        /// Dotted key of the setting, e.g. `supply.capacity_ah`.
        key: String,
        /// The value given.
        value: String,
        /// The allowed range or form.
        expected: String,
    },
    /// A `--set key=value` override could not be applied.
    #[error("override `{text}`: {message}")]
    Override {
        /// The override as given.
        text: String,
        /// Why it failed.
        message: String,
    },
    /// The scenario file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A recording the scenario refers to (replay) could not be read.
    #[error(transparent)]
    Recording(#[from] magstand_core::CoreError),
}

/// Range checks with messages that name the dotted key, shared by every parameter block.
pub(crate) struct Checker<'a> {
    pub origin: &'a str,
    /// The table the keys are in (`thermal`), written before each key with a dot; empty for
    /// keys given in full.
    pub table: &'a str,
}

impl<'a> Checker<'a> {
    /// The same checks for the keys of `table`, given without it.
    pub fn in_table(&self, table: &'a str) -> Checker<'a> {
        Checker {
            origin: self.origin,
            table,
        }
    }

    pub fn fail(&self, key: &str, value: impl std::fmt::Display, expected: &str) -> SimError {
        SimError::InvalidSetting {
            origin: self.origin.to_string(),
            key: if self.table.is_empty() {
                key.to_string()
            } else {
                format!("{}.{key}", self.table)
            },
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }

    /// `value` must be finite and lie in `[lo, hi]`.
    pub fn range(&self, key: &str, value: f64, lo: f64, hi: f64) -> Result<(), SimError> {
        if value.is_finite() && value >= lo && value <= hi {
            Ok(())
        } else {
            let expected = match (lo == f64::NEG_INFINITY, hi == f64::INFINITY) {
                (true, true) => "a finite number".to_string(),
                (false, true) => format!("a finite number >= {lo}"),
                (true, false) => format!("a finite number <= {hi}"),
                (false, false) => format!("a number in {lo}..={hi}"),
            };
            Err(self.fail(key, value, &expected))
        }
    }

    /// `value` must be finite and strictly positive.
    pub fn positive(&self, key: &str, value: f64) -> Result<(), SimError> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(self.fail(key, value, "a finite number > 0"))
        }
    }

    /// Every component must be finite and of magnitude at most `max_abs`.
    pub fn within3(&self, key: &str, v: [f64; 3], max_abs: f64) -> Result<(), SimError> {
        if v.iter().all(|&x| magstand_core::within(x, max_abs)) {
            Ok(())
        } else {
            Err(self.fail(
                key,
                format!("{v:?}"),
                &format!("three finite numbers of magnitude at most {max_abs:e}"),
            ))
        }
    }
}
