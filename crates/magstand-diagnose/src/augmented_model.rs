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
//!   "stated_keys": ["motors.dead_zone"],  // optional: the keys its author wrote out (absent
//!                                         // in older files: every key counts as stated)
//!   "command_lead": 0.5,                  // when within a row interval a command change acts
//!   "block_s": 2.0, "holdout_every": 3,   // the diagnosis's time blocks
//!   "effects": [{"name": "current_lag", "theta": [0.3]}, ...],   // in order of acceptance;
//!                                         // "variant": "free_discharge" where an effect's
//!                                         // richer form was kept (absent: the catalog's)
//!   "columns": ["reference", "driven", "speed^1", ...],          // regressor names
//!   "coefficients": [[x, y, z], ...],     // µT per unit of each column
//!   "noise": {                            // optional (absent in older files)
//!     "variance_ut2": [[c0x, c0y, c0z], [c1x, ...], [c2x, ...]],
//!     "floor_ut2": [x, y, z],
//!     "full_load_a": 48.0
//!   },
//!   "method": "physics",                  // optional: written by `magstand fit`
//!   "follow_recorded_voltage": true,      // optional: the replay follows the logged bat_v
//!   "choice": {...}                       // optional: `fit`'s automatic choice, as in the
//!                                         // local linear model file
//! }
//! ```
//!
//! `noise` is the variance of what the model leaves on the diagnosed recording's held-out rows
//! (what it promises for a recording it has not seen), growing with the load (eq. 8):
//! `max(c0 + c1 q + c2 q², floor)` µT² per axis, with `q` the motor current (total current
//! less the avionics) over `full_load_a`, the largest motor current of the diagnosed
//! recording. `compensate` writes its square root as `sd_{x,y,z}_ut`.
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
use magstand_sim::replay::{Logged, replay_logged};

use crate::DiagnoseError;
use crate::effects::{Context, Effect};
use crate::fit::variance_at;
use crate::pipeline::design::build_with_lead;
use crate::versioned_json;
use magstand_core::held_out::Split;

/// Format name of the file.
pub const FORMAT: &str = "magstand-augmented-model";
/// File version.
pub const VERSION: u32 = 1;

/// One accepted effect and its nonlinear parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentedTerm {
    /// Catalog name.
    pub name: String,
    /// The effect's richer form, where that was kept (`free_discharge`: a battery whose
    /// discharge shape is free); absent for the catalog's own form.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variant: Option<String>,
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
    /// The keys of `nominal_scenario` its author wrote out (the rest were defaults, unknown
    /// to the diagnosis, which may treat them otherwise: a slow current lag replaces only an
    /// unstated spin-up). Absent in files of earlier versions, where every key counts as
    /// stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stated_keys: Option<Vec<String>>,
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
    /// Noise variance law of the residual; `None` in files written before it was stored.
    #[serde(default)]
    pub noise: Option<NoiseLaw>,
    /// `"physics"` when written by `magstand fit` (absent from a diagnosis's model file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<String>,
    /// When `fit` chose the family automatically: what was tried and why this one won.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choice: Option<magstand_ident::family_choice::FamilyChoice>,
    /// The firmware's parameter set of the magnetometer it was fitted on (the recording's
    /// `mag_slot`): `export` writes that set's parameters, and `compensate` refuses a
    /// recording of another sensor. Absent where the recording did not say.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magnetometer: Option<magstand_core::magnetometer_slot::MagnetometerSlot>,
    /// The transform that took that magnetometer's readings to the recording's body frame
    /// (the recording's `mag_to_body`, which `import` writes from PX4's calibration): PX4
    /// adds its compensation before it, so `export --to px4` maps the coefficients back
    /// through it. Absent where the recording did not say (the sensor read in the body frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magnetometer_to_body: Option<magstand_core::magnetometer_frame::SensorToBody>,
    /// Whether the replay follows the recording's logged supply voltage (`bat_v`): a
    /// recording to compensate then needs that column. Absent (false) in older files.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub follow_recorded_voltage: bool,
    /// Whether the replay's supply current is the recording's logged one (`bat_a`), as a
    /// diagnosis of a flight with its current logged has it: a recording to compensate then
    /// needs that column. Absent (false) in older files.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub follow_recorded_current: bool,
    /// The motors in the groups the diagnosed recording could tell apart (0-based, each motor
    /// once), where some motors were commanded alike on every row: per-motor terms were
    /// fitted per group, and are evaluated so on any recording. Absent where every motor was
    /// its own group, as in older files.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motor_groups: Option<Vec<Vec<usize>>>,
    /// Each motor's current as the calibrated law has it, which per-motor terms follow.
    /// Absent in older files and where the law could not be told (the nominal motor's current
    /// is followed then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motor_current_law: Option<MotorCurrentLaw>,
    /// The stand's current as the calibrated law has it, which a hysteresis term's play and a
    /// thermal drift's heating without `temp_c` follow. Absent in older files, in models
    /// without such a term, and where the law could not be told (the replayed current is
    /// followed then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub current_law: Option<MotorCurrentLaw>,
    /// What the calibration this model came from warned of, beyond the recording's own
    /// doubts: a supply nobody stated replayed as a constant voltage, commands logged held, a
    /// flight's preparation, structure too small to name. Whoever compensates with the model
    /// should know them, and `fit` prints them whichever way it came to the physics. Absent
    /// where there were none, and in older files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub calibration_warnings: Vec<String>,
}

/// A motor's current as the calibrated current law has it: `sum_j a_per_unit[j] * x_j`, where
/// `x_j` is the motor's part of the baseline column `columns[j]` (`driven`,
/// `armed_in_dead_zone`, `speed^k`), A. Per-motor terms follow this current rather than the
/// nominal motor's, whose shape at low commands may be another stand's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotorCurrentLaw {
    /// Baseline current-law columns.
    pub columns: Vec<String>,
    /// Amperes per unit of each column.
    pub a_per_unit: Vec<f64>,
}

/// Largest noise-law coefficient or floor a model file may carry, µT² ((1e5 µT)²).
pub const MAX_VARIANCE_UT2: f64 = 1e10;

/// Residual noise variance growing with the load: `max(c0 + c1 q + c2 q², floor)` per axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseLaw {
    /// Rows c0, c1, c2; each per axis x, y, z; µT².
    pub variance_ut2: [[f64; 3]; 3],
    /// Lowest variance per axis, µT².
    pub floor_ut2: [f64; 3],
    /// Motor current that `q = 1` stands for, A.
    pub full_load_a: f64,
}

impl NoiseLaw {
    /// Noise sd per axis at a motor current of `load_a`, µT.
    pub fn sd_ut(&self, load_a: f64) -> Vec3 {
        let var = variance_at(
            &self.variance_ut2,
            &self.floor_ut2,
            load_a / self.full_load_a,
        );
        Vec3::from(var.map(f64::sqrt))
    }

    /// Within the bounds that keep every predicted sd finite: a motor current of at most
    /// 1e5 A (the recording's limit) over a full load of at least 1 µA is q ≤ 1e11, and
    /// coefficients of at most (1e5 µT)² then give at most 1e32 µT².
    fn is_valid(&self) -> bool {
        (1e-6..=1e5).contains(&self.full_load_a)
            && self
                .variance_ut2
                .iter()
                .flatten()
                .all(|c| c.abs() <= MAX_VARIANCE_UT2)
            && self
                .floor_ut2
                .iter()
                .all(|f| *f > 0.0 && *f <= MAX_VARIANCE_UT2)
    }
}

impl AugmentedModel {
    /// Reads a model file, refusing other formats and versions by name.
    pub fn load(path: &Path) -> Result<Self, DiagnoseError> {
        let text =
            magstand_core::input_file::read_document(path).map_err(|source| DiagnoseError::Io {
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
        m.validate(path)?;
        Ok(m)
    }

    /// [`AugmentedModel::from_json`] on a document already parsed.
    pub fn from_value(value: serde_json::Value, path: &Path) -> Result<Self, DiagnoseError> {
        let m: AugmentedModel =
            versioned_json::parse_value(value, path, FORMAT, VERSION, |m: &Self| {
                (m.format.as_str(), m.version)
            })?;
        m.validate(path)?;
        Ok(m)
    }

    /// The rules every model file follows, checked where it is read and where it is written.
    fn validate(&self, path: &Path) -> Result<(), DiagnoseError> {
        let m = self;
        if m.columns.len() != m.coefficients.len()
            || m.coefficients.iter().flatten().any(|c| !c.is_finite())
        {
            return Err(versioned_json::malformed(
                path,
                "expected one finite coefficient triple per column".into(),
            ));
        }
        if !(m.block_s.is_finite() && m.block_s > 0.0 && m.block_s <= 1e6) {
            return Err(versioned_json::malformed(
                path,
                format!(
                    "block_s = {}: expected a positive block length of at most 1e6 s",
                    m.block_s
                ),
            ));
        }
        if !(1..=1000).contains(&m.holdout_every) {
            return Err(versioned_json::malformed(
                path,
                format!("holdout_every = {}: expected 1..1000", m.holdout_every),
            ));
        }
        if !(m.command_lead.is_finite() && (0.0..=1.0).contains(&m.command_lead)) {
            return Err(versioned_json::malformed(
                path,
                format!("command_lead = {}: expected 0..1", m.command_lead),
            ));
        }
        if m.coefficients.iter().flatten().any(|c| c.abs() > 1e9) {
            return Err(versioned_json::malformed(
                path,
                "a coefficient beyond 1e9 µT per unit: not a physical model".into(),
            ));
        }
        if m.noise.as_ref().is_some_and(|n| !n.is_valid()) {
            return Err(versioned_json::malformed(
                path,
                format!(
                    "`noise` expects variance coefficients of magnitude at most {MAX_VARIANCE_UT2:e} µT², floors in (0, {MAX_VARIANCE_UT2:e}] µT² and full_load_a in [1e-6, 1e5] A"
                ),
            ));
        }
        Ok(())
    }

    /// Writes the model as pretty JSON, atomically; never a file [`AugmentedModel::load`]
    /// would refuse.
    pub fn save(&self, path: &Path) -> Result<(), DiagnoseError> {
        self.validate(path)?;
        versioned_json::write(self, path)
    }

    /// Predicted disturbance at every row of `rec` (named `origin` in errors), µT.
    pub fn dist_column(&self, rec: &Recording, origin: &str) -> Result<Vec<Vec3>, DiagnoseError> {
        Ok(self.predict(rec, origin)?.0)
    }

    /// Predicted noise sd at every row of `rec`, µT; `None` when the file has no noise law.
    pub fn sd_column(
        &self,
        rec: &Recording,
        origin: &str,
    ) -> Result<Option<Vec<Vec3>>, DiagnoseError> {
        let (_, load_a) = self.predict(rec, origin)?;
        Ok(self.sd_at_loads(&load_a))
    }

    /// The predicted reading at every row of `rec`: the motors-off field plus the
    /// disturbance, µT. Its difference from the recorded reading is the model's residual.
    pub fn reading_column(
        &self,
        rec: &Recording,
        origin: &str,
    ) -> Result<Vec<Vec3>, DiagnoseError> {
        let (dist, _) = self.predict(rec, origin)?;
        let reference = self.reference_ut();
        Ok(dist.into_iter().map(|d| d + reference).collect())
    }

    /// The motors-off field the model fitted, µT.
    pub fn reference_ut(&self) -> Vec3 {
        self.columns
            .iter()
            .position(|c| c == "reference")
            .map_or(Vec3::zeros(), |i| Vec3::from(self.coefficients[i]))
    }

    /// The numbers the calibration chose: every coefficient of every axis, each effect's
    /// nonlinear parameters, and the command timing. What a comparison of model families
    /// counts as a model's size.
    pub fn parameter_count(&self) -> usize {
        3 * self.coefficients.len() + self.effects.iter().map(|e| e.theta.len()).sum::<usize>() + 1
    }

    /// The noise law's sd at each motor current (A), µT.
    fn sd_at_loads(&self, load_a: &[f64]) -> Option<Vec<Vec3>> {
        let law = self.noise.as_ref()?;
        Some(load_a.iter().map(|&l| law.sd_ut(l)).collect())
    }

    /// The disturbance (µT) and the motor current (A) at every row.
    fn predict(
        &self,
        rec: &Recording,
        origin: &str,
    ) -> Result<(Vec<Vec3>, Vec<f64>), DiagnoseError> {
        rec.check()?;
        let bad = |message: String| DiagnoseError::Recording {
            origin: origin.into(),
            message,
        };
        let scenario =
            Scenario::from_toml_str(&self.nominal_scenario, "the model's nominal scenario")?
                .check("the model's nominal scenario", None)?;
        let mut nominal = scenario.params().clone();
        if let Some(keys) = &self.stated_keys {
            // The file writes every key out: what was stated is what it records.
            nominal = nominal.with_stated_keys(keys.iter().cloned());
        }
        nominal.study = Default::default();
        let motors = nominal.motors.count;
        if rec.motor_count() != motors && rec.motor_count() != 1 {
            return Err(bad(format!(
                "{} motor command columns; the model's stand has {motors} motors",
                rec.motor_count()
            )));
        }
        let motor_groups = match &self.motor_groups {
            None => (0..motors).map(|m| vec![m]).collect(),
            Some(groups) => {
                let mut seen: Vec<usize> = groups.iter().flatten().copied().collect();
                seen.sort_unstable();
                if groups.iter().any(Vec::is_empty) || seen != (0..motors).collect::<Vec<_>>() {
                    return Err(bad(format!(
                        "the model's motor_groups {groups:?} are not groups of its {motors} motors: expected each motor 0..{} in exactly one non-empty group",
                        motors.saturating_sub(1)
                    )));
                }
                groups.clone()
            }
        };
        for (key, law) in [
            ("motor_current_law", &self.motor_current_law),
            ("current_law", &self.current_law),
        ] {
            let Some(law) = law else { continue };
            let known =
                |c: &String| self.columns.contains(c) && crate::fit::LawColumn::parse(c).is_some();
            if law.columns.len() != law.a_per_unit.len()
                || law.columns.is_empty()
                || !law.columns.iter().all(known)
                || !law.a_per_unit.iter().all(|a| a.is_finite())
            {
                return Err(bad(format!(
                    "the model's {key} has columns {:?} and a_per_unit {:?}: expected as many finite values as columns, each column one of the model's current-law columns (driven, {}, speed^1..speed^{})",
                    law.columns,
                    law.a_per_unit,
                    crate::fit::ARMED_IN_DEAD_ZONE,
                    crate::fit::MAX_SPEED_POWERS
                )));
            }
        }
        if self.follow_recorded_voltage && rec.bat_v.is_none() {
            return Err(bad(
                "the model replays the logged supply voltage, and this recording has no `bat_v` column: expected one (the model was fitted on a recording that had it)".into(),
            ));
        }
        if self.follow_recorded_current && rec.bat_a.is_none() {
            return Err(bad(
                "the model follows the logged supply current, and this recording has no `bat_a` column: expected one (the model was fitted on a flight that had it)".into(),
            ));
        }
        let mut terms: Vec<(&dyn Effect, &[f64])> = Vec::new();
        for t in &self.effects {
            let e = crate::effects::find(&t.name, t.variant.as_deref()).ok_or_else(|| {
                bad(match &t.variant {
                    Some(v) => format!(
                        "the model names an unknown form `{v}` of effect `{}`",
                        t.name
                    ),
                    None => format!("the model names an unknown effect `{}`", t.name),
                })
            })?;
            terms.push((e, t.theta.as_slice()));
        }
        let split = Split::new(&rec.t_s, self.block_s, self.holdout_every);
        let logged = Logged::of(rec, false, self.follow_recorded_current);
        let nominal_trace = replay_logged(&nominal, &rec.t_s, &rec.thr, logged, 0.5);
        let ctx = Context {
            rec,
            nominal: &nominal,
            split: &split,
            nominal_trace: &nominal_trace,
            rec_origin: origin.into(),
            command_lead: self.command_lead,
            flight: false,
            follow_recorded_voltage: self.follow_recorded_voltage,
            follow_recorded_current: self.follow_recorded_current,
            // The law the model was calibrated with, whatever the new recording's levels.
            speed_powers: self
                .columns
                .iter()
                .filter(|c| c.starts_with("speed^"))
                .count(),
            armed_current: self
                .columns
                .iter()
                .any(|c| c == crate::fit::ARMED_IN_DEAD_ZONE),
            motor_groups,
            motor_current_law: self.motor_current_law.clone(),
            current_law: self.current_law.clone(),
            replays: Default::default(),
            series_lags: Default::default(),
        };
        // Each effect's parameters as its own search defines them: as many as it searches,
        // finite, positive where it searches on a log scale, and within ten times its range.
        for (e, theta) in &terms {
            let searches = e.search(&ctx);
            let fits = theta.len() == searches.len()
                && theta.iter().zip(&searches).all(|(v, s)| {
                    v.is_finite()
                        && (!s.log || *v > 0.0)
                        && v.abs() <= 10.0 * s.lo.abs().max(s.hi.abs())
                });
            if !fits {
                return Err(bad(format!(
                    "the model's effect `{}` has theta {:?}; expected {} value(s) [{}]",
                    e.name(),
                    theta,
                    searches.len(),
                    searches
                        .iter()
                        .map(|s| format!(
                            "{} {}..{} {}{}",
                            s.name,
                            s.lo,
                            s.hi,
                            s.unit,
                            if s.log { ", positive" } else { "" }
                        ))
                        .collect::<Vec<_>>()
                        .join("; ")
                )));
            }
        }
        let built = build_with_lead(&ctx, &terms, self.command_lead);
        if built.design.names != self.columns {
            return Err(bad(format!(
                "the model's regressors are [{}], this recording gives [{}]: it lacks a column the diagnosed recording had (bat_v or temp_c?), or the model was written by a magstand whose terms had other columns (diagnose the recording again)",
                self.columns.join(", "),
                built.design.names.join(", ")
            )));
        }
        let reference = self.reference_ut();
        let dist = built
            .design
            .predict(&self.coefficients)
            .into_iter()
            .zip(&built.fixed)
            .map(|(p, f)| p + f - reference)
            .collect();
        Ok((dist, built.load_a()))
    }

    /// The recording with the predicted disturbance removed from `mag_*_ut` and the columns
    /// `dist_{x,y,z}_ut` (and `sd_{x,y,z}_ut` when the model has a noise law) added; any columns
    /// of those names already present are dropped.
    pub fn compensate(&self, rec: &Recording, origin: &str) -> Result<Recording, DiagnoseError> {
        let (dist, load_a) = self.predict(rec, origin)?;
        let mut out = rec.clone();
        for (m, d) in out.mag_ut.iter_mut().zip(&dist) {
            *m -= d;
        }
        let sd = self.sd_at_loads(&load_a);
        // Stale columns of an earlier compensation go, whether or not they are rewritten.
        out.extra.retain(|(n, _)| {
            !["dist", "sd"]
                .iter()
                .any(|k| AXES.iter().any(|a| *n == format!("{k}_{a}_ut")))
        });
        for (kind, values) in [("dist", Some(&dist)), ("sd", sd.as_ref())] {
            let Some(values) = values else { continue };
            for (a, axis) in AXES.iter().enumerate() {
                out.extra.push((
                    format!("{kind}_{axis}_ut"),
                    values.iter().map(|v| format_extra(v[a])).collect(),
                ));
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(noise: &str) -> String {
        format!(
            r#"{{"format": "{FORMAT}", "version": {VERSION}, "recording": "r.csv",
                "nominal_scenario": "", "command_lead": 0.5, "block_s": 2.0,
                "holdout_every": 3, "effects": [], "columns": ["reference"],
                "coefficients": [[1.0, 2.0, 3.0]]{noise}}}"#
        )
    }

    #[test]
    fn noise_law_is_optional_and_checked() {
        let path = Path::new("A.json");
        // Files written before the noise law was stored still load.
        assert_eq!(
            AugmentedModel::from_json(&file(""), path).unwrap().noise,
            None
        );
        let law = |full: &str| {
            file(&format!(
                r#", "noise": {{"variance_ut2": [[0.04, 0.04, 0.04], [0.0, 0.0, 0.0], [0.32, 0.32, 0.32]],
                    "floor_ut2": [0.01, 0.01, 0.01], "full_load_a": {full}}}"#
            ))
        };
        let m = AugmentedModel::from_json(&law("40.0"), path).unwrap();
        let n = m.noise.unwrap();
        // sqrt(0.04) at rest, sqrt(0.04 + 0.32 * 0.25) = sqrt(0.12) at half load.
        assert!((n.sd_ut(0.0).x - 0.2).abs() < 1e-12, "{:?}", n.sd_ut(0.0));
        assert!(
            (n.sd_ut(20.0).z - 0.12f64.sqrt()).abs() < 1e-12,
            "{:?}",
            n.sd_ut(20.0)
        );
        let err = AugmentedModel::from_json(&law("0.0"), path)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("A.json") && err.contains("full_load_a"),
            "{err}"
        );
    }
}
