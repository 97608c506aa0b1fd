//! `study.json`: what a study (or one shard of it) ran, so shards can be checked before they
//! are merged and a result can be reproduced.
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::StudyError;
use crate::config::ValidStudy;
use magstand_core::atomic_file;

/// Format name of `study.json`.
pub const FORMAT: &str = "magstand-montecarlo";
/// Current version of the study files.
pub const VERSION: u32 = 1;

/// What was run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyInfo {
    /// Always the study file's format name, `magstand-montecarlo`.
    pub format: String,
    /// The study file's format version: the current one when written by this version.
    pub version: u32,
    /// magstand version that ran it.
    pub magstand_version: String,
    /// Scenario name.
    pub scenario: String,
    /// The fully resolved scenario, as TOML.
    pub scenario_toml: String,
    /// Overrides applied to the identification series only.
    pub identification_overrides: Vec<String>,
    /// Runs of the whole study.
    pub runs: usize,
    /// Study seed.
    pub seed: u64,
    /// Method ids, in table order.
    pub methods: Vec<String>,
    /// Shard of this file: index (1-based) and count; 1/1 for a whole or merged study.
    pub shard: [usize; 2],
    /// Runs in this file: `run_range[0]..run_range[1]`.
    pub run_range: [usize; 2],
}

impl StudyInfo {
    /// The description of a study.
    pub fn of(study: &ValidStudy) -> Self {
        let c = study.config();
        let r = study.run_indices();
        Self {
            format: FORMAT.into(),
            version: VERSION,
            magstand_version: env!("CARGO_PKG_VERSION").into(),
            scenario: study.scenario().params().name.clone(),
            scenario_toml: study.scenario().to_toml(),
            identification_overrides: c.identification_overrides.clone(),
            runs: c.runs,
            seed: c.seed,
            methods: study.methods().iter().map(|m| m.id.to_string()).collect(),
            shard: [c.shard.index, c.shard.count],
            run_range: [r.start, r.end],
        }
    }

    /// Writes `study.json` atomically.
    pub fn write(&self, path: &Path) -> Result<(), StudyError> {
        let text = serde_json::to_string_pretty(self).expect("study info serializes");
        Ok(atomic_file::write_bytes(path, text.as_bytes())?)
    }

    /// Reads and checks `study.json`.
    pub fn read(path: &Path) -> Result<Self, StudyError> {
        let text =
            magstand_core::input_file::read_document(path).map_err(|source| StudyError::Io {
                path: path.into(),
                source,
            })?;
        let info: StudyInfo = serde_json::from_str(&text).map_err(|e| StudyError::Malformed {
            path: path.into(),
            message: e.to_string(),
        })?;
        if info.format != FORMAT || info.version != VERSION {
            return Err(StudyError::Malformed {
                path: path.into(),
                message: format!(
                    "format `{}` version {}; expected `{FORMAT}` version {VERSION}",
                    info.format, info.version
                ),
            });
        }
        Ok(info)
    }

    /// Whether two files belong to the same study: everything but the shard agrees, including
    /// the magstand version (another version may simulate or fit differently).
    pub fn same_study(&self, other: &Self) -> bool {
        self.scenario_toml == other.scenario_toml
            && self.identification_overrides == other.identification_overrides
            && self.runs == other.runs
            && self.seed == other.seed
            && self.methods == other.methods
            && self.magstand_version == other.magstand_version
    }
}
