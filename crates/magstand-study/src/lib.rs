//! Monte Carlo accuracy studies of disturbance identification, against the Cramer-Rao bound.
//!
//! A user choosing a calibration procedure (how many stair levels, how long a dwell, which
//! rate, throttle or current as input, which model) needs to know how accurate the identified
//! compensation will be, and how close that is to the best any unbiased method could do.
//!
//! Each run simulates an identification series and a separate validation series with fresh
//! seeds (and, when the scenario's `[study]` table declares them, freshly drawn vehicle
//! parameters), fits every method of [`magstand_ident::methods`], and judges each on the
//! validation series against the simulator's truth ([`run`]). For the paper's fixed structure
//! it also compares the parameter errors with the Cramer-Rao bound ([`crlb`]).
//!
//! Runs are spread over threads with rayon; each run's seeds derive from the study seed and the
//! run index only, so the results do not depend on the thread count, and a study split into
//! shards ([`Shard`]) and merged ([`merge`]) gives the same summary as one machine.
//!
//! # Example
//! ```
//! use magstand_sim::Scenario;
//! use magstand_study::{FigureId, StudyConfig, Summary, run_study, Silent};
//!
//! let text = r#"
//!     name = "quick stair"
//!     [program]
//!     kind = "stair"
//!     off_s = 2.0
//!     steps = 6
//!     dwell_s = 2.0
//!     [stand]
//!     enabled = false
//!     [study]
//!     validation = ['program.direction="down"']
//! "#;
//! let scenario = Scenario::from_toml_str(text, "inline")?.check("inline", None)?;
//! let mut config = StudyConfig::new(4, 1);
//! config.methods = vec!["px4".into(), "global".into()];
//! let study = config.check(&scenario)?;
//! let result = run_study(&study, Some(1), &Silent)?;
//! let summary = Summary::new(result.info.clone(), &result.outcomes);
//! let px4 = summary.method("px4").unwrap().figure(FigureId::RmseUt).unwrap();
//! let rbf = summary.method("global").unwrap().figure(FigureId::RmseUt).unwrap();
//! // A straight line cannot follow the convex disturbance; three local lines can.
//! assert!(rbf.mean < px4.mean);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod comparison;
mod config;
pub mod crlb;
mod error;
pub mod run;
pub mod runs_csv;
mod study_info;
pub mod summary;
pub mod sweep;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

pub use config::{Shard, StudyConfig, ValidStudy};
pub use error::{StudyError, StudySetting};
pub use run::{MethodOutcome, identification_series};
pub use study_info::StudyInfo;
pub use summary::{FIGURE_NAMES, FigureId, Summary, format_figure};
pub use sweep::{SWEEP_FILE, ValidSweep, sweep_csv, sweep_rows};

/// Receives progress from a running study; kept apart from the study so a command line can
/// show a bar and a library caller can ignore it. Called from worker threads.
pub trait StudyObserver: Sync {
    /// A run finished; `done` of `total` runs of this shard are finished.
    fn run_finished(&self, done: usize, total: usize);
}

/// An observer that ignores everything.
pub struct Silent;

impl StudyObserver for Silent {
    fn run_finished(&self, _: usize, _: usize) {}
}

/// The outcome of a study or shard: what ran and one row per run and method.
#[derive(Debug, Clone)]
pub struct StudyResult {
    /// What was run.
    pub info: StudyInfo,
    /// Outcomes sorted by run, then method order.
    pub outcomes: Vec<MethodOutcome>,
}

/// Runs a study on `threads` worker threads (all cores when `None`).
pub fn run_study(
    study: &ValidStudy,
    threads: Option<usize>,
    observer: &dyn StudyObserver,
) -> Result<StudyResult, StudyError> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        if t == 0 {
            return Err(StudyError::InvalidSetting {
                setting: StudySetting::Threads,
                value: "0".into(),
                expected: "at least one thread".into(),
            });
        }
        builder = builder.num_threads(t);
    }
    let pool = builder
        .build()
        .map_err(|e| StudyError::Threads(e.to_string()))?;
    let runs: Vec<usize> = study.run_indices().collect();
    let done = AtomicUsize::new(0);
    // One run at a time per thread: its stands no longer share anything with other runs' (see
    // `magstand_sim::StandWorld`), and a run's two recordings stay in cache while it is fitted.
    let per_run: Vec<Result<Vec<MethodOutcome>, StudyError>> = pool.install(|| {
        runs.par_iter()
            .map(|&run| {
                let outcome = run::run_one(study, run);
                observer.run_finished(done.fetch_add(1, Ordering::Relaxed) + 1, runs.len());
                outcome
            })
            .collect()
    });
    let mut outcomes = Vec::with_capacity(runs.len() * study.methods().len());
    for r in per_run {
        outcomes.extend(r?);
    }
    Ok(StudyResult {
        info: StudyInfo::of(study),
        outcomes,
    })
}

/// The table of a study folder: one row per run and method.
pub const RUNS_FILE: &str = "runs.csv";
/// What a study folder holds: the study's settings and its shard.
pub const INFO_FILE: &str = "study.json";
/// The summary of a whole study.
pub const SUMMARY_FILE: &str = "SUMMARY.json";

impl StudyResult {
    /// The files of a study folder [`StudyResult::read`] reads.
    pub fn files_read(dir: &Path) -> [PathBuf; 2] {
        [dir.join(RUNS_FILE), dir.join(INFO_FILE)]
    }

    /// The files [`StudyResult::write`] writes into `dir` (the summary only for a whole study).
    pub fn files_written(dir: &Path) -> [PathBuf; 3] {
        [
            dir.join(RUNS_FILE),
            dir.join(INFO_FILE),
            dir.join(SUMMARY_FILE),
        ]
    }

    /// Writes `runs.csv` and `study.json` into `dir` (which must exist), and `SUMMARY.json`
    /// when the result covers the whole study. Returns the summary when written.
    pub fn write(&self, dir: &Path) -> Result<Option<Summary>, StudyError> {
        runs_csv::write(&self.outcomes, &dir.join(RUNS_FILE))?;
        self.info.write(&dir.join(INFO_FILE))?;
        if self.info.run_range != [0, self.info.runs] {
            return Ok(None);
        }
        let summary = Summary::new(self.info.clone(), &self.outcomes);
        write_summary(&summary, &dir.join(SUMMARY_FILE))?;
        Ok(Some(summary))
    }

    /// Reads a result written by [`StudyResult::write`].
    pub fn read(dir: &Path) -> Result<Self, StudyError> {
        let info = StudyInfo::read(&dir.join(INFO_FILE))?;
        let path = dir.join(RUNS_FILE);
        let outcomes = runs_csv::read(&path)?;
        let malformed = |message: String| StudyError::Malformed {
            path: path.clone(),
            message,
        };
        // Each (run, method) exactly once: a repeated row would count twice in the summary.
        let mut seen = std::collections::HashMap::new();
        for (row, o) in outcomes.iter().enumerate() {
            if let Some(first) = seen.insert((o.run, o.method.as_str()), row + 1) {
                return Err(malformed(format!(
                    "row {}: run {} method `{}` repeats row {first}; each run has one row per method",
                    row + 1,
                    o.run,
                    o.method
                )));
            }
        }
        for run in info.run_range[0]..info.run_range[1] {
            if let Some(m) = info
                .methods
                .iter()
                .find(|m| !seen.contains_key(&(run, m.as_str())))
            {
                return Err(malformed(format!(
                    "run {run} has no row for method `{m}`; each run has one row per method (did the shard finish?)"
                )));
            }
        }
        for o in &outcomes {
            let in_range = (info.run_range[0]..info.run_range[1]).contains(&o.run);
            if !in_range || !info.methods.contains(&o.method) {
                return Err(StudyError::Malformed {
                    path,
                    message: format!(
                        "run {} method `{}` does not belong to this shard (runs {}..{}, methods {})",
                        o.run,
                        o.method,
                        info.run_range[0],
                        info.run_range[1],
                        info.methods.join(", ")
                    ),
                });
            }
        }
        Ok(Self { info, outcomes })
    }
}

/// Writes a summary as JSON, atomically.
pub fn write_summary(summary: &Summary, path: &Path) -> Result<(), StudyError> {
    Ok(magstand_core::atomic_file::write_bytes(
        path,
        summary.to_json().as_bytes(),
    )?)
}

/// Merges the shards of one study into the whole. Every shard must belong to the same study,
/// and together they must cover every run exactly once with a row per method.
pub fn merge(shards: Vec<StudyResult>) -> Result<StudyResult, StudyError> {
    let first = shards
        .first()
        .ok_or_else(|| StudyError::Merge("no shards given".into()))?
        .info
        .clone();
    let mut ranges = Vec::new();
    for s in &shards {
        if !s.info.same_study(&first) {
            return Err(StudyError::Merge(format!(
                "shard {}/{} belongs to another study than shard {}/{} (scenario, runs, seed, methods or magstand version differ)",
                s.info.shard[0], s.info.shard[1], first.shard[0], first.shard[1]
            )));
        }
        ranges.push((s.info.run_range, s.info.shard));
    }
    ranges.sort();
    let mut next = 0;
    for (range, shard) in &ranges {
        if range[0] < next {
            return Err(StudyError::Merge(format!(
                "shard {}/{} repeats runs from {} (given twice?)",
                shard[0], shard[1], range[0]
            )));
        }
        if range[0] > next {
            return Err(StudyError::Merge(format!(
                "runs {next}..{} are missing: a shard was not given or did not finish",
                range[0]
            )));
        }
        next = range[1];
    }
    if next != first.runs {
        return Err(StudyError::Merge(format!(
            "runs {next}..{} are missing: a shard was not given or did not finish",
            first.runs
        )));
    }
    let mut outcomes: Vec<MethodOutcome> = shards.into_iter().flat_map(|s| s.outcomes).collect();
    let order = |m: &str| {
        first
            .methods
            .iter()
            .position(|x| x == m)
            .unwrap_or(usize::MAX)
    };
    outcomes.sort_by_key(|o| (o.run, order(&o.method)));
    let expected = first.runs * first.methods.len();
    if outcomes.len() != expected {
        return Err(StudyError::Merge(format!(
            "{} rows where {} runs x {} methods = {expected} were expected",
            outcomes.len(),
            first.runs,
            first.methods.len()
        )));
    }
    let mut info = first;
    info.shard = [1, 1];
    info.run_range = [0, info.runs];
    Ok(StudyResult { info, outcomes })
}
