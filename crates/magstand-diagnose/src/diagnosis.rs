//! The diagnosis file (`D.json`): format `magstand-diagnosis`, version 1. Documented in the
//! README; the keys below are the public contract.
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::DiagnoseError;
use crate::effects::Param;
use crate::locate::Location;

/// Format name written in every diagnosis file.
pub const FORMAT: &str = "magstand-diagnosis";
/// Format version.
pub const VERSION: u32 = 1;
/// Verdict entry for structure no catalog term explains.
pub const UNEXPLAINED: &str = "unexplained";

/// The baseline: the nominal simulation of the recording, calibrated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Baseline {
    /// Held-out RMSE per axis (x, y, z), µT.
    pub holdout_rmse_ut: [f64; 3],
    /// Whether its held-out residuals are structured (not white noise with the
    /// throttle-dependent variance).
    pub structured: bool,
    /// Ljung-Box p-value of the held-out standardized residuals per axis.
    pub whiteness_p: [f64; 3],
    /// Where its mismatch lives (present when structured or when a term was accepted).
    pub located: Option<Location>,
    /// The calibrated free parameters: coefficient of each nominal regressor per axis.
    pub calibration: Vec<Param>,
}

impl Baseline {
    /// The calibrated stand constants the scenario leaves out (those of `calibration` named by
    /// their scenario key, e.g. `motors.dead_zone`), without the regressors' coefficients.
    pub fn stand_constants(&self) -> impl Iterator<Item = &Param> {
        self.calibration.iter().filter(|p| p.name.contains('.'))
    }
}

/// One accepted effect (or the "unexplained" remainder).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EffectReport {
    /// Catalog name, or "unexplained".
    pub name: String,
    /// The effect's richer form where one was kept (`free_discharge`, `drawn_charge`, ...:
    /// see `Effect::richer`); absent for the catalog's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<String>,
    /// Fitted parameters with units and uncertainties (from the final joint fit).
    pub params: Vec<Param>,
    /// One sentence of physics.
    pub explanation: String,
    /// Where the effect changes the prediction (for "unexplained": where the structure is).
    pub located: Location,
    /// Held-out RMSE per axis before the term, µT.
    pub holdout_rmse_before_ut: [f64; 3],
    /// Held-out RMSE per axis after the term, µT.
    pub holdout_rmse_after_ut: [f64; 3],
    /// p-value of the held-out improvement test (for "unexplained": of the whiteness test).
    pub p_value: f64,
}

/// One candidate tried in one round.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateResult {
    /// Catalog name.
    pub name: String,
    /// The effect's richer form this candidate is; absent for the catalog's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form: Option<String>,
    /// Held-out RMSE per axis with the candidate, µT (None when it could not be fitted).
    pub holdout_rmse_ut: Option<[f64; 3]>,
    /// Mean drop of the weighted squared held-out residual per row (positive is better).
    pub improvement: Option<f64>,
    /// One-sided p-value of the improvement over held-out blocks.
    pub p_value: Option<f64>,
    /// Why it was not tried or could not be fitted.
    pub note: Option<String>,
}

/// One round of the forward search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Round {
    /// Significance each candidate had to reach (the family significance over candidates).
    pub threshold: f64,
    /// Every candidate tried.
    pub candidates: Vec<CandidateResult>,
    /// The one accepted, if any.
    pub accepted: Option<String>,
    /// Whiteness (Ljung-Box) p-value per axis of the held-out residual the round started
    /// from. In the first round a candidate is accepted only when one axis is below the
    /// whiteness threshold: a recording whose residual is white has nothing to name. Absent
    /// in older files.
    #[serde(default)]
    pub whiteness_p: Option<[f64; 3]>,
}

/// Simulation against recording: the replayed simulation of the nominal scenario and of the
/// augmented one, each calibrated only in the nominal free parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimulationAgreement {
    /// Held-out RMSE of the nominal simulation, µT.
    pub holdout_rmse_before_ut: [f64; 3],
    /// Held-out RMSE of the augmented simulation, µT.
    pub holdout_rmse_after_ut: [f64; 3],
}

/// One stage's residuals for plots.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage {
    /// "baseline", or "+ name" after each accepted term.
    pub label: String,
    /// Residual at each plotted row, µT.
    pub residual_ut: Vec<[f64; 3]>,
}

/// Held-out residuals at a bounded number of rows, for figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Series {
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Overall throttle.
    pub throttle: Vec<f64>,
    /// Residuals, one stage per model.
    pub stages: Vec<Stage>,
}

/// The settings used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// Family-wise significance of each decision.
    pub significance: f64,
    /// Every n-th block held out.
    pub holdout_every: usize,
    /// Block length, s.
    pub block_s: f64,
    /// Rows used to fit and rows held out.
    pub rows: [usize; 2],
}

/// A complete diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnosis {
    /// Always [`FORMAT`].
    pub format: String,
    /// Always [`VERSION`].
    pub version: u32,
    /// The recording diagnosed.
    pub recording: String,
    /// The nominal scenario (file, or "default nominal stand").
    pub scenario: String,
    /// Accepted effect names in order of acceptance, then "unexplained" if structure remains;
    /// empty when no significant mismatch.
    pub verdict: Vec<String>,
    /// The calibrated nominal simulation.
    pub baseline: Baseline,
    /// One entry per verdict entry.
    pub effects: Vec<EffectReport>,
    /// Simulation against recording before and after.
    pub simulation: SimulationAgreement,
    /// Every round of the forward search.
    pub rounds: Vec<Round>,
    /// Residuals for figures.
    pub series: Series,
    /// Settings used.
    pub settings: Settings,
    /// The augmented scenario (TOML), with every accepted effect switched on.
    pub augmented_scenario: String,
    /// What makes the diagnosis doubtful, in words (a flight's preparation: rows left out, an
    /// Earth field poorly determined, a delay at its limit). Absent in older files.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The calibrated augmented physics as a model `compensate` can use (written to its own
    /// file, not into the diagnosis file).
    #[serde(skip)]
    pub model: Option<crate::augmented_model::AugmentedModel>,
    /// The calibrated nominal physics alone, for comparison (not written either).
    #[serde(skip)]
    pub baseline_model: Option<crate::augmented_model::AugmentedModel>,
}

/// `value ± sd` with two significant digits of the uncertainty (four of the value without one).
pub fn value_with_sd(value: f64, sd: Option<f64>) -> String {
    match sd.filter(|s| *s > 0.0 && s.is_finite()) {
        Some(sd) => {
            let decimals = (1.0 - sd.log10().floor()).clamp(0.0, 9.0) as usize;
            format!("{value:.decimals$} ± {sd:.decimals$}")
        }
        None => format!("{value:.4}"),
    }
}

impl Diagnosis {
    /// Reads a diagnosis file.
    pub fn load(path: &Path) -> Result<Diagnosis, DiagnoseError> {
        crate::versioned_json::read(path, FORMAT, VERSION, |d: &Self| {
            (d.format.as_str(), d.version)
        })
    }

    /// Writes the diagnosis as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), DiagnoseError> {
        crate::versioned_json::write(self, path)
    }

    /// A summary a person can read in ten seconds.
    pub fn summary(&self) -> String {
        let f3 = |v: [f64; 3]| format!("{:.3} {:.3} {:.3}", v[0], v[1], v[2]);
        let mut s = String::new();
        for w in &self.warnings {
            s.push_str(&format!("warning: {w}\n"));
        }
        if self.verdict.is_empty() {
            s.push_str("verdict: no significant mismatch (residuals are white noise)\n");
        } else {
            s.push_str(&format!("verdict: {}\n", self.verdict.join(", ")));
        }
        s.push_str(&format!(
            "held-out RMSE x y z (µT): baseline {}\n",
            f3(self.baseline.holdout_rmse_ut)
        ));
        let constants: Vec<&Param> = self.baseline.stand_constants().collect();
        if !constants.is_empty() {
            let shown: Vec<String> = constants.iter().map(|p| p.shown()).collect();
            s.push_str(&format!("calibrated, not stated: {}\n", shown.join(", ")));
            push_bases(&mut s, constants);
        }
        for e in &self.effects {
            let params: Vec<String> = e.params.iter().map(Param::shown).collect();
            let form = e
                .form
                .as_ref()
                .map_or(String::new(), |f| format!(" (form `{f}`)"));
            s.push_str(&format!(
                "  {}{form}: {} -> {} (p = {:.2e}); throttle {:.2}..{:.2}, t {:.0}..{:.0} s, axes {}, {} ramps, {}, {}\n",
                e.name,
                f3(e.holdout_rmse_before_ut),
                f3(e.holdout_rmse_after_ut),
                e.p_value,
                e.located.throttle_range[0],
                e.located.throttle_range[1],
                e.located.time_span_s[0],
                e.located.time_span_s[1],
                if e.located.axes.is_empty() { "-".into() } else { e.located.axes.join("") },
                e.located.direction,
                e.located.phase,
                e.located.motors
            ));
            if !params.is_empty() {
                s.push_str(&format!("    {}\n", params.join(", ")));
            }
            push_bases(&mut s, &e.params);
        }
        s.push_str(&format!(
            "simulation vs recording, held-out RMSE: {} -> {} µT\n",
            f3(self.simulation.holdout_rmse_before_ut),
            f3(self.simulation.holdout_rmse_after_ut)
        ));
        s
    }
}

/// Each basis of `params` once, with the names resting on it ([`Param::bases_in_words`]).
fn push_bases<'a>(s: &mut String, params: impl IntoIterator<Item = &'a Param>) {
    for line in Param::bases_in_words(params) {
        s.push_str(&format!("    {line}\n"));
    }
}
