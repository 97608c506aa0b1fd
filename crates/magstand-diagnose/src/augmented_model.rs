//! The diagnosis as a model `magstand compensate` can use: the nominal physics with the
//! accepted effects switched on, as the diagnosis calibrated it.
//!
//! # File (`format` `"magstand-augmented-model"`, version 1)
//!
//! ```text
//! {
//!   "format": "magstand-augmented-model", "version": 1,
//!   "recording": "R.csv",                 // what it was fitted on
//!   "nominal_scenario": "...",            // TOML of the nominal stand the effects modify
//!   "command_lead": 0.5,                  // when within a row interval a command change acts
//!   "block_s": 2.0, "holdout_every": 3,   // the diagnosis's time blocks
//!   "effects": [{"name": "current_lag", "theta": [0.3]}, ...],   // in order of acceptance
//!   "columns": ["reference", "driven", "speed^1", ...],          // regressor names
//!   "coefficients": [[x, y, z], ...]      // µT per unit of each column
//! }
//! ```
//!
//! To predict, the recording's commands are replayed through the nominal stand with the
//! effects' nonlinear parameters (`theta`) applied, the same regressor columns are built and
//! weighted by the stored coefficients; the disturbance is that prediction minus the
//! `reference` column (the motors-off field). A recording that cannot produce the same columns
//! (one without the `bat_v` or `temp_c` the diagnosed one had, say) is refused by name.
use std::path::Path;

use serde::{Deserialize, Serialize};

use magstand_core::recording_csv::format_extra;
use magstand_core::{AXES, Recording, Vec3};
use magstand_sim::Scenario;
use magstand_sim::replay::replay;

use crate::DiagnoseError;
use crate::effects::{Context, Effect, catalog};
use crate::search::build_with_lead;
use crate::split::Split;
use crate::versioned_json;

/// Format name of the file.
pub const FORMAT: &str = "magstand-augmented-model";
/// File version.
pub const VERSION: u32 = 1;

/// One accepted effect and its nonlinear parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentedTerm {
    /// Catalog name.
    pub name: String,
    /// Nonlinear parameters, in the effect's search order.
    pub theta: Vec<f64>,
}

/// The calibrated augmented physics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentedModel {
    /// Always [`FORMAT`].
    pub format: String,
    /// File version.
    pub version: u32,
    /// The recording it was fitted on.
    pub recording: String,
    /// TOML of the nominal scenario.
    pub nominal_scenario: String,
    /// Moment within a row interval at which a logged command change acts (0..1).
    pub command_lead: f64,
    /// Time block length of the diagnosis, s.
    pub block_s: f64,
    /// Every how many blocks one was held out.
    pub holdout_every: usize,
    /// Accepted effects in order of acceptance.
    pub effects: Vec<AugmentedTerm>,
    /// Regressor column names.
    pub columns: Vec<String>,
    /// Coefficient of each column per axis, µT per unit.
    pub coefficients: Vec<[f64; 3]>,
}

impl AugmentedModel {
    /// Reads a model file, refusing other formats and versions by name.
    pub fn load(path: &Path) -> Result<Self, DiagnoseError> {
        let text = std::fs::read_to_string(path).map_err(|source| DiagnoseError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text, path)
    }

    /// Parses a model from the JSON text of the file `path`.
    pub fn from_json(text: &str, path: &Path) -> Result<Self, DiagnoseError> {
        let m: AugmentedModel = versioned_json::parse(text, path, FORMAT, VERSION, |m: &Self| {
            (m.format.as_str(), m.version)
        })?;
        if m.columns.len() != m.coefficients.len()
            || m.coefficients.iter().flatten().any(|c| !c.is_finite())
        {
            return Err(versioned_json::malformed(
                path,
                "expected one finite coefficient triple per column".into(),
            ));
        }
        Ok(m)
    }

    /// Writes the model as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), DiagnoseError> {
        versioned_json::write(self, path)
    }

    /// Predicted disturbance at every row of `rec` (named `origin` in errors), µT.
    pub fn dist_column(&self, rec: &Recording, origin: &str) -> Result<Vec<Vec3>, DiagnoseError> {
        rec.check()?;
        let bad = |message: String| DiagnoseError::Recording {
            origin: origin.into(),
            message,
        };
        let scenario =
            Scenario::from_toml_str(&self.nominal_scenario, "the model's nominal scenario")?
                .check("the model's nominal scenario", None)?;
        let mut nominal = scenario.params().clone();
        nominal.study = Default::default();
        let motors = nominal.motors.count;
        if rec.motor_count() != motors && rec.motor_count() != 1 {
            return Err(bad(format!(
                "{} motor command columns; the model's stand has {motors} motors",
                rec.motor_count()
            )));
        }
        let effects: Vec<Box<dyn Effect>> = catalog();
        let mut terms: Vec<(&dyn Effect, &[f64])> = Vec::new();
        for t in &self.effects {
            let e = effects
                .iter()
                .find(|e| e.name() == t.name)
                .ok_or_else(|| bad(format!("the model names an unknown effect `{}`", t.name)))?;
            terms.push((e.as_ref(), t.theta.as_slice()));
        }
        let split = Split::new(&rec.t_s, Some(self.block_s), self.holdout_every);
        let nominal_trace = replay(&nominal, &rec.t_s, &rec.thr, None, 0.5);
        let ctx = Context {
            rec,
            nominal: &nominal,
            split: &split,
            nominal_trace: &nominal_trace,
            rec_origin: origin.into(),
            command_lead: self.command_lead,
        };
        let built = build_with_lead(&ctx, &terms, self.command_lead);
        if built.design.names != self.columns {
            return Err(bad(format!(
                "the model's regressors are [{}], this recording gives [{}]: it lacks a column the diagnosed recording had (bat_v or temp_c?)",
                self.columns.join(", "),
                built.design.names.join(", ")
            )));
        }
        let reference = self
            .columns
            .iter()
            .position(|c| c == "reference")
            .map_or(Vec3::zeros(), |i| Vec3::from(self.coefficients[i]));
        Ok(built
            .design
            .predict(&self.coefficients)
            .into_iter()
            .zip(&built.fixed)
            .map(|(p, f)| p + f - reference)
            .collect())
    }

    /// The recording with the predicted disturbance removed from `mag_*_ut` and the columns
    /// `dist_{x,y,z}_ut` added (replacing any of that name).
    pub fn compensate(&self, rec: &Recording, origin: &str) -> Result<Recording, DiagnoseError> {
        let dist = self.dist_column(rec, origin)?;
        let mut out = rec.clone();
        for (m, d) in out.mag_ut.iter_mut().zip(&dist) {
            *m -= d;
        }
        for (a, axis) in AXES.iter().enumerate() {
            let name = format!("dist_{axis}_ut");
            out.extra.retain(|(n, _)| *n != name);
            out.extra
                .push((name, dist.iter().map(|d| format_extra(d[a])).collect()));
        }
        Ok(out)
    }
}
