//! Study settings: an unchecked [`StudyConfig`] becomes a [`ValidStudy`], and only a valid study
//! runs.
use magstand_ident::methods::{self, Method};
use magstand_sim::ValidScenario;

use crate::{StudyError, StudySetting};

/// One slice of a study's runs: shard `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// Which slice, 1..=count.
    pub index: usize,
    /// How many slices.
    pub count: usize,
}

impl Shard {
    /// The whole study.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Parses `K/M`.
    pub fn parse(text: &str) -> Result<Self, StudyError> {
        let bad = || StudyError::InvalidSetting {
            setting: StudySetting::Shard,
            value: text.into(),
            expected: "K/M with 1 <= K <= M, e.g. 3/10".into(),
        };
        let (k, m) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse().map_err(|_| bad())?,
            m.trim().parse().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The run indices of this shard out of `runs`: contiguous, disjoint, covering all runs
    /// over the shards.
    pub fn runs(&self, runs: usize) -> std::ops::Range<usize> {
        let lo = runs * (self.index - 1) / self.count;
        let hi = runs * self.index / self.count;
        lo..hi
    }
}

/// What a study does, not yet checked.
#[derive(Debug, Clone)]
pub struct StudyConfig {
    /// Runs in the whole study (over all shards).
    pub runs: usize,
    /// Seed of the study; run `r` uses seeds derived from it and `r`.
    pub seed: u64,
    /// Method ids (see [`magstand_ident::methods`]); empty for every method the scenario
    /// allows.
    pub methods: Vec<String>,
    /// The slice of runs to do.
    pub shard: Shard,
    /// Overrides for the identification series only (a procedure setting being swept).
    pub identification_overrides: Vec<String>,
}

impl StudyConfig {
    /// A whole study of `runs` runs with every method.
    pub fn new(runs: usize, seed: u64) -> Self {
        Self {
            runs,
            seed,
            methods: Vec::new(),
            shard: Shard::ALL,
            identification_overrides: Vec::new(),
        }
    }

    /// Checks the settings against the scenario.
    pub fn check(self, scenario: &ValidScenario) -> Result<ValidStudy, StudyError> {
        if self.runs < 2 || self.runs > 10_000_000 {
            return Err(StudyError::InvalidSetting {
                setting: StudySetting::Runs,
                value: self.runs.to_string(),
                expected: "between 2 and 10,000,000 runs (a spread needs at least two)".into(),
            });
        }
        if self.shard.count > self.runs {
            return Err(StudyError::InvalidSetting {
                setting: StudySetting::Shard,
                value: format!("{}/{}", self.shard.index, self.shard.count),
                expected: format!("at most as many shards as runs ({})", self.runs),
            });
        }
        let has_current = scenario.params().logging.record_power;
        let methods: Vec<Method> = if self.methods.is_empty() {
            methods::catalog()
                .into_iter()
                .filter(|m| has_current || m.config.input != magstand_ident::InputKind::Current)
                .collect()
        } else {
            let mut out: Vec<Method> = Vec::new();
            for id in &self.methods {
                let m = methods::by_id(id).ok_or_else(|| StudyError::InvalidSetting {
                    setting: StudySetting::Methods,
                    value: id.clone(),
                    expected: format!("one of {}", methods::ids()),
                })?;
                if m.config.input == magstand_ident::InputKind::Current && !has_current {
                    return Err(StudyError::InvalidSetting {
                        setting: StudySetting::Methods,
                        value: id.clone(),
                        expected: "a method the scenario can feed: current input needs `logging.record_power = true`".into(),
                    });
                }
                if !out.iter().any(|o| o.id == m.id) {
                    out.push(m);
                }
            }
            out
        };
        let identification = scenario.with_overrides(&self.identification_overrides)?;
        // Check the validation series and every declared distribution once up front, so that a
        // bad setting fails before hours of runs rather than in run 4,711.
        let validation = scenario.validation()?;
        Ok(ValidStudy {
            config: self,
            scenario: scenario.clone(),
            identification,
            validation,
            methods,
        })
    }
}

/// A checked study, ready to run.
#[derive(Debug, Clone)]
pub struct ValidStudy {
    pub(crate) config: StudyConfig,
    pub(crate) scenario: ValidScenario,
    pub(crate) identification: ValidScenario,
    pub(crate) validation: ValidScenario,
    pub(crate) methods: Vec<Method>,
}

impl ValidStudy {
    /// The settings.
    pub fn config(&self) -> &StudyConfig {
        &self.config
    }

    /// The scenario as given.
    pub fn scenario(&self) -> &ValidScenario {
        &self.scenario
    }

    /// The methods compared, in table order.
    pub fn methods(&self) -> &[Method] {
        &self.methods
    }

    /// The run indices this study does.
    pub fn run_indices(&self) -> std::ops::Range<usize> {
        self.config.shard.runs(self.config.runs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_are_disjoint_and_cover_every_run() {
        for runs in [2usize, 7, 500, 1001] {
            for count in 1..=runs.min(13) {
                let mut next = 0;
                for index in 1..=count {
                    let r = Shard { index, count }.runs(runs);
                    assert_eq!(r.start, next, "runs {runs} shard {index}/{count}");
                    assert!(!r.is_empty(), "runs {runs} shard {index}/{count} is empty");
                    next = r.end;
                }
                assert_eq!(next, runs);
            }
        }
    }

    #[test]
    fn shard_text_is_checked() {
        assert_eq!(
            Shard::parse("3/10").unwrap(),
            Shard {
                index: 3,
                count: 10
            }
        );
        for bad in ["0/3", "4/3", "a/3", "3", "1/0"] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("`shard`") && e.contains(bad), "{bad}: {e}");
        }
    }
}
