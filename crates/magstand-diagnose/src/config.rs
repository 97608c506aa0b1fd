//! Settings of a diagnosis, checked before anything is fitted.
use crate::DiagnoseError;

/// Settings as given, not yet checked.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseConfig {
    /// Family-wise significance of each decision (accepting a term, calling the residual
    /// structured), split over the candidates tried (Bonferroni).
    pub significance: f64,
    /// Every `holdout_every`-th time block is held out from all fits and used only to judge.
    pub holdout_every: usize,
    /// Length of a time block, s, at most [`MAX_BLOCK_S`]; `None` picks 1/150 of the
    /// recording, kept in 0.5..10 s.
    pub block_s: Option<f64>,
    /// Most terms accepted before the search stops.
    pub max_terms: usize,
}

/// Longest time block, s: five held-out blocks of an hour already take fifteen hours of
/// recording, and a longer one is a unit slip (milliseconds for seconds), not a plan.
pub const MAX_BLOCK_S: f64 = 3600.0;

impl Default for DiagnoseConfig {
    fn default() -> Self {
        Self {
            significance: 0.01,
            holdout_every: 3,
            block_s: None,
            max_terms: 4,
        }
    }
}

/// Checked settings: the only form [`crate::diagnose`] accepts.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidConfig(pub(crate) DiagnoseConfig);

impl ValidConfig {
    /// The checked settings.
    pub fn params(&self) -> &DiagnoseConfig {
        &self.0
    }
}

fn invalid(key: &str, value: impl ToString, expected: &str) -> DiagnoseError {
    DiagnoseError::InvalidSetting {
        key: key.into(),
        value: value.to_string(),
        expected: expected.into(),
    }
}

impl DiagnoseConfig {
    /// Checks every setting, naming the first one that is not allowed.
    pub fn check(self) -> Result<ValidConfig, DiagnoseError> {
        if !(self.significance > 0.0 && self.significance < 0.5) {
            return Err(invalid(
                "significance",
                self.significance,
                "a probability in (0, 0.5)",
            ));
        }
        if !(2..=20).contains(&self.holdout_every) {
            return Err(invalid(
                "holdout_every",
                self.holdout_every,
                "an integer in 2..=20",
            ));
        }
        if let Some(b) = self.block_s
            && !(b > 0.0 && b <= MAX_BLOCK_S)
        {
            return Err(invalid(
                "block_s",
                b,
                &format!("a positive number of seconds up to {MAX_BLOCK_S}"),
            ));
        }
        if !(1..=16).contains(&self.max_terms) {
            return Err(invalid("max_terms", self.max_terms, "an integer in 1..=16"));
        }
        Ok(ValidConfig(self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_check_and_bad_values_are_named() {
        assert!(DiagnoseConfig::default().check().is_ok());
        let e = DiagnoseConfig {
            significance: 0.7,
            ..Default::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("significance") && e.contains("0.7"), "{e}");
        let e = DiagnoseConfig {
            block_s: Some(f64::NAN),
            ..Default::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("block_s"), "{e}");
        for too_long in [3600.5, 1e308, f64::INFINITY] {
            let e = DiagnoseConfig {
                block_s: Some(too_long),
                ..Default::default()
            }
            .check()
            .unwrap_err()
            .to_string();
            assert!(
                e.contains("block_s") && e.contains("3600"),
                "{too_long}: {e}"
            );
        }
        let hour = DiagnoseConfig {
            block_s: Some(MAX_BLOCK_S),
            ..Default::default()
        };
        assert!(
            hour.check().is_ok(),
            "a block of {MAX_BLOCK_S} s is allowed"
        );
    }
}
