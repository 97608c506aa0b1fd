//! Progress of a running diagnosis, kept apart from it (as argmin keeps its observers apart
//! from its solvers): a command line shows what the diagnosis is doing while it runs, which on
//! a long recording takes tens of seconds, and a library caller ignores it ([`Silent`]).
//!
//! An observer only watches: the diagnosis is the same, bit for bit, whatever observes it.
//!
//! # Example
//! ```
//! use std::sync::atomic::{AtomicUsize, Ordering};
//! use magstand_diagnose::{DiagnoseObserver, Stage};
//!
//! /// Counts the rounds of a diagnosis (pass it to `diagnose_observed`).
//! #[derive(Default)]
//! struct Rounds(AtomicUsize);
//!
//! impl DiagnoseObserver for Rounds {
//!     fn stage(&self, stage: Stage) {
//!         if let Stage::Round { .. } = stage {
//!             self.0.fetch_add(1, Ordering::Relaxed);
//!         }
//!     }
//! }
//!
//! let rounds = Rounds::default();
//! rounds.stage(Stage::Baseline);
//! rounds.stage(Stage::Round { number: 1, calibration: true, candidates: vec!["dead_zone".into()] });
//! assert_eq!(rounds.0.load(Ordering::Relaxed), 1);
//! ```

/// What a running diagnosis reports to a [`DiagnoseObserver`], in the order it happens.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Stage {
    /// The baseline is being calibrated: a flight's Earth field, offset and delays taken out,
    /// the nominal physics replayed on the recording's commands, and the stand constants
    /// nobody stated fitted to it.
    Baseline,
    /// A round of the forward search begins.
    Round {
        /// The round's number, from 1 (the `rounds` of the diagnosis, in order).
        number: usize,
        /// Whether only the stand constants nobody stated (and the effects that can pass for
        /// them) are tried: a calibration round, before the whole catalog.
        calibration: bool,
        /// The candidates the round fits, by name.
        candidates: Vec<String>,
    },
    /// One candidate of the current round has been fitted (candidates are fitted in
    /// parallel, so they finish in any order).
    CandidateFitted {
        /// The candidate's name.
        name: String,
        /// How many of the round's candidates have been fitted, this one included.
        done: usize,
        /// How many the round fits.
        of: usize,
    },
    /// The round's best candidate is taken into the model and every term refitted with it.
    /// It stays unless its refitted parameters end at an edge of their range, where the
    /// round records it refused and is tried again without it.
    Refining {
        /// The candidate's name.
        candidate: String,
    },
    /// The search is over: the final joint model, the augmented scenario and its simulation
    /// are being assembled.
    Assembling,
}

/// Receives the [`Stage`]s of a running diagnosis. Called from worker threads.
pub trait DiagnoseObserver: Sync {
    /// The diagnosis reached `stage`.
    fn stage(&self, stage: Stage);
}

/// An observer that ignores everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl DiagnoseObserver for Silent {
    fn stage(&self, _: Stage) {}
}
