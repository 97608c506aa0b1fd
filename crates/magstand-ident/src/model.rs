//! The fitted model, its versioned JSON file, prediction and compensation.
//!
//! # Model file (`M.json`, format `magstand-model`, version 1)
//!
//! ```text
//! {
//!   "format": "magstand-model", "version": 1,
//!   "method": "global-weighted",          // how it was fitted (informational; see method_name)
//!   "input": {"kind": "throttle"|"motors"|"current", "lo": 0, "hi": 1, "motors": 4, "off_raw": 0},
//!   "reference_ut": [x, y, z],            // eq. 9 motors-off reading of the identification data
//!   "structure": {"kind": "local_linear", "partition": {"centers": [...], "widths": [...]},
//!                 "coefficients": [[[a, b], ...], [...], [...]]}     // per axis, per local model
//!              | {"kind": "polynomial", "coefficients": [[c0, c1, ...], [...], [...]]},
//!   "sd": {"knots": [...], "sd_ut": [[...], [...], [...]]} | null,   // noise sd per axis
//!   "summary": {...} | null,
//!   "identified": {"lo": u0, "hi": u1, "quantiles": [q0, q5, ..., q100]},  // optional
//!   "choice": {"chosen": "automatic", "reason": "...", "rule": "...",      // optional: only
//!              "holdout_rows": n, "holdout_blocks": b,                     // when `fit` chose
//!              "families": [{"family": "physics", "parameters": 19,        // the family
//!                            "holdout_rmse_ut": [x, y, z], "excess_ut2": d,
//!                            "excess_se_ut2": se, "note": null}, ...]}
//! }
//! ```
//! `choice` records the automatic choice among model families ([`crate::family_choice`]).
//! `identified` is the normalized input range the model was identified on, with the 21
//! quantiles (every 5 %) of the identification rows' input with the motors running. Beyond
//! that range a model continues linearly from its edge: a local-linear net keeps the
//! validity weights of the edge (so its blended local models continue as straight lines), a
//! polynomial continues along its tangent at the edge. Without it (files written before it
//! existed) the model is evaluated as fitted everywhere.
//! The input is normalized, `u = (raw - lo) / (hi - lo)`; local coefficients are in µT per unit of
//! normalized input (slopes) and µT (intercepts). The predicted disturbance is the model output
//! minus its output with the motors off, so it is exactly zero with the motors off (eq. 9).
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::IdentError;
use crate::dataset::InputSpec;
use crate::local_linear::LocalLinearNet;
use crate::noise_model::SdModel;
use magstand_core::recording_csv::format_extra;
use magstand_core::{AXES, Recording, Vec3, atomic_file};

/// Format name in every model file.
pub const FORMAT: &str = "magstand-model";
/// Current model file version.
pub const VERSION: u32 = 1;

/// Largest motor count a model file may declare.
pub const MAX_MOTORS: usize = 32;
/// Largest magnitude of a raw input bound (`lo`, `hi`, `off_raw`): a current of 1e5 A.
pub const MAX_RAW_INPUT: f64 = 1e5;
/// Smallest raw input span `hi - lo`.
pub const MIN_INPUT_SPAN: f64 = 1e-6;
/// Largest magnitude of a field value (reference, noise sd), µT: 0.1 T.
pub const MAX_FIELD_UT: f64 = 1e5;
/// Largest magnitude of a model coefficient, µT per unit of normalized input.
pub const MAX_COEFFICIENT_UT: f64 = 1e6;
/// Largest number of local models.
pub const MAX_LOCAL_MODELS: usize = 100;
/// Largest magnitude of a centre or knot on the normalized input.
pub const MAX_CENTER: f64 = 10.0;
/// Largest RBF width parameter.
pub const MAX_WIDTH: f64 = 1e4;
/// Largest number of polynomial coefficients per axis.
pub const MAX_POLYNOMIAL_TERMS: usize = 21;
/// Largest number of noise-model knots.
pub const MAX_SD_KNOTS: usize = 1000;

/// The functional form of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Structure {
    /// RBF-blended local linear models.
    LocalLinear(LocalLinearNet),
    /// A polynomial `sum_k c_k u^k` of the normalized input per axis (the autopilots' lines and
    /// a cubic).
    Polynomial {
        /// `coefficients[axis][k]`, µT per unit of `u^k`.
        coefficients: [Vec<f64>; 3],
    },
}

/// Fit statistics stored with a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitSummary {
    /// Rows used.
    pub rows: usize,
    /// Rows held out of the fit that gave `holdout_rmse_ut`.
    pub holdout_rows: usize,
    /// RMSE of the fit on all rows, per axis, µT.
    pub rmse_ut: [f64; 3],
    /// Coefficient of determination on all rows, per axis.
    pub r2: [f64; 3],
    /// RMSE on held-out time blocks of a fit that did not see them, per axis, µT.
    pub holdout_rmse_ut: [f64; 3],
    /// Number of local models (or polynomial terms).
    pub terms: usize,
}

/// A fitted disturbance model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Model {
    /// Always [`FORMAT`].
    pub format: String,
    /// File version.
    pub version: u32,
    /// How it was fitted.
    pub method: String,
    /// The input and its normalization.
    pub input: InputSpec,
    /// Motors-off reference of the identification data, µT.
    pub reference_ut: [f64; 3],
    /// The functional form.
    pub structure: Structure,
    /// Noise standard deviation against the normalized input.
    pub sd: Option<SdModel>,
    /// Fit statistics.
    pub summary: Option<FitSummary>,
    /// The input range it was identified on; beyond it the model continues linearly.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identified: Option<IdentifiedRange>,
    /// When the family was chosen automatically: what was tried and why this one won.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choice: Option<crate::family_choice::FamilyChoice>,
    /// The firmware's parameter set of the magnetometer it was fitted on (the recording's
    /// `mag_slot`, which `import` writes), so that `export` writes that one's parameters.
    /// Absent where the recording did not say (a test stand's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magnetometer: Option<magstand_core::magnetometer_slot::MagnetometerSlot>,
    /// The transform that took that magnetometer's readings to the recording's body frame
    /// (the recording's `mag_to_body`, which `import` writes from PX4's calibration): PX4
    /// adds its compensation before it, so `export --to px4` maps the coefficients back
    /// through it. Absent where the recording did not say (the sensor read in the body frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magnetometer_to_body: Option<magstand_core::magnetometer_frame::SensorToBody>,
}

/// The normalized input range a model was identified on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifiedRange {
    /// Lowest normalized input with the motors running.
    pub lo: f64,
    /// Highest normalized input.
    pub hi: f64,
    /// Quantiles of the normalized input over the rows with the motors running, every 5 %
    /// (21 values, `lo` to `hi`): where the identification data lie.
    pub quantiles: Vec<f64>,
}

impl IdentifiedRange {
    /// The range of the identification inputs `u` (normalized, every row), with the
    /// quantiles of those above `off_u` (the motors running); `None` without finite inputs.
    pub fn of(u: &[f64], off_u: f64) -> Option<Self> {
        Self::of_rows(u, |_| true, off_u)
    }

    /// As [`IdentifiedRange::of`], of the rows `rows` selects.
    pub fn of_rows(u: &[f64], rows: impl Fn(usize) -> bool, off_u: f64) -> Option<Self> {
        let finite = || {
            u.iter()
                .enumerate()
                .filter(|&(k, x)| x.is_finite() && rows(k))
                .map(|(_, x)| *x)
        };
        let lo = finite().min_by(f64::total_cmp)?;
        let hi = finite().max_by(f64::total_cmp)?;
        let on: Vec<f64> = finite().filter(|x| *x > off_u + 1e-9).collect();
        let mut v = if on.is_empty() {
            finite().collect()
        } else {
            on
        };
        let ranks: Vec<usize> = (0..=20)
            .map(|k| ((v.len() - 1) as f64 * (k as f64 / 20.0)).round() as usize)
            .collect();
        let quantiles = order_statistics(&mut v, &ranks, 0);
        Some(Self { lo, hi, quantiles })
    }

    /// Whether a normalized input lies inside the range widened on each side by `margin`
    /// times its width (and 1e-9).
    pub fn contains(&self, u: f64, margin: f64) -> bool {
        let m = margin * (self.hi - self.lo) + 1e-9;
        u >= self.lo - m && u <= self.hi + m
    }
}

/// The values of ranks `ranks` (ascending, counted from `base`) of `v` as if it were sorted by
/// [`f64::total_cmp`]: a selection around the middle rank, each half then taking its ranks,
/// so a million inputs cost a few passes rather than a sort.
fn order_statistics(v: &mut [f64], ranks: &[usize], base: usize) -> Vec<f64> {
    if ranks.is_empty() {
        return Vec::new();
    }
    let mid = ranks.len() / 2;
    let at = ranks[mid] - base;
    let (below, value, above) = v.select_nth_unstable_by(at, f64::total_cmp);
    let value = *value;
    // Ranks equal to the middle one (a short input repeats ranks) take its value.
    let lower_end = ranks[..mid].partition_point(|&r| r < ranks[mid]);
    let upper_start = mid + ranks[mid..].partition_point(|&r| r <= ranks[mid]);
    let mut out = order_statistics(below, &ranks[..lower_end], base);
    out.extend(std::iter::repeat_n(value, upper_start - lower_end));
    out.extend(order_statistics(
        above,
        &ranks[upper_start..],
        base + at + 1,
    ));
    out
}

/// Scratch space for repeated predictions.
pub struct Scratch {
    x: Vec<f64>,
    phi: Vec<f64>,
}

/// Fewest rows a task of [`Model::residuals_at`] evaluates: enough that handing out the work
/// costs little beside the rows.
const RESIDUAL_ROWS_PER_TASK: usize = 4096;

/// The one spelling of a model file's `method`: files written before the names were unified
/// spelled weighting with `+` and the automatic structure `auto-...`
/// (`global+weighted`, `auto-global+weighted`); they read as `global-weighted` and
/// `automatic`, the names `runs.csv` and `--methods` use. Other names pass unchanged.
pub fn method_name(written: &str) -> &str {
    match written {
        "local+weighted" => "local-weighted",
        "global+weighted" => "global-weighted",
        "auto-global+weighted" => "automatic",
        "auto-global" => "automatic-unweighted",
        "auto-local+weighted" => "automatic-local",
        "auto-local" => "automatic-local-unweighted",
        other => other,
    }
}

impl Model {
    /// The numbers the fit chose: every coefficient of every axis, the motors-off reference,
    /// and a local linear structure's centres and widths. What a comparison of model families
    /// counts as a model's size.
    pub fn parameter_count(&self) -> usize {
        let structure = match &self.structure {
            Structure::LocalLinear(n) => {
                2 * n.partition.len()
                    + n.coefficients
                        .iter()
                        .flatten()
                        .map(|c| c.len())
                        .sum::<usize>()
            }
            Structure::Polynomial { coefficients } => {
                coefficients.iter().flatten().filter(|c| **c != 0.0).count()
            }
        };
        structure + 3
    }

    /// Builds a model from its parts.
    pub fn new(
        method: &str,
        input: InputSpec,
        reference_ut: Vec3,
        structure: Structure,
        sd: Option<SdModel>,
    ) -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            method: method.into(),
            input,
            reference_ut: reference_ut.into(),
            structure,
            sd,
            summary: None,
            identified: None,
            choice: None,
            magnetometer: None,
            magnetometer_to_body: None,
        }
    }

    /// Scratch buffers sized for this model.
    pub fn scratch(&self) -> Scratch {
        let m = match &self.structure {
            Structure::LocalLinear(n) => n.partition.len(),
            Structure::Polynomial { .. } => 0,
        };
        Scratch {
            x: vec![0.0; self.input.regressor_count()],
            phi: vec![0.0; m],
        }
    }

    /// Raw model output at normalized input `u` and regressors `x`; beyond the identified
    /// range, the linear continuation from its edge (see the module documentation).
    pub fn output(&self, u: f64, x: &[f64], phi: &mut [f64]) -> Vec3 {
        let edge = match &self.identified {
            Some(r) if u.is_finite() => u.clamp(r.lo, r.hi),
            _ => u,
        };
        match &self.structure {
            // The edge's validity weights with the row's own regressors: the blended local
            // models continue as the straight lines they are.
            Structure::LocalLinear(net) => net.eval(edge, x, phi),
            Structure::Polynomial { coefficients } => Vec3::from_fn(|a, _| {
                let c = &coefficients[a];
                let value = c.iter().rev().fold(0.0, |acc, c| acc * edge + c);
                if edge == u {
                    return value;
                }
                let slope = c
                    .iter()
                    .enumerate()
                    .skip(1)
                    .rev()
                    .fold(0.0, |acc, (k, c)| acc * edge + k as f64 * c);
                value + slope * (u - edge)
            }),
        }
    }

    /// Model output with the motors off.
    pub fn off_output(&self, s: &mut Scratch) -> Vec3 {
        self.input.off_regressors(&mut s.x);
        let u = self.input.normalize(self.input.off_raw);
        self.output(u, &s.x, &mut s.phi)
    }

    /// Residuals of identification data, `y - (output - off output)`: what the model leaves
    /// of the eq. 9 deviations.
    pub fn residuals(&self, data: &crate::Dataset) -> Vec<Vec3> {
        let Some(index) = data.group_index() else {
            return self.residuals_at(data, &|_| true);
        };
        let mut s = self.scratch();
        let off = self.off_output(&mut s);
        // Rows of equal input and regressors have equal outputs: one evaluation per group.
        let fitted: Vec<Vec3> = index
            .first_row
            .iter()
            .map(|&k| {
                let k = k as usize;
                self.output(data.u[k], data.regressors(k), &mut s.phi) - off
            })
            .collect();
        (0..data.len())
            .map(|k| data.y[k] - fitted[index.of_row[k] as usize])
            .collect()
    }

    /// As [`Model::residuals`] on the rows `rows` selects only; the others are left zero.
    /// The rows are evaluated on every core, each exactly as alone.
    pub fn residuals_at(
        &self,
        data: &crate::Dataset,
        rows: &(dyn Fn(usize) -> bool + Sync),
    ) -> Vec<Vec3> {
        use rayon::prelude::*;
        self.selected_residuals(data, rows)
            .map(|r| r.unwrap_or_else(Vec3::zeros))
            .collect()
    }

    /// The residuals at the rows `rows` selects only, in row order: [`Model::residuals_at`]
    /// without the zeros elsewhere.
    pub fn residuals_where(
        &self,
        data: &crate::Dataset,
        rows: &(dyn Fn(usize) -> bool + Sync),
    ) -> Vec<Vec3> {
        use rayon::prelude::*;
        self.selected_residuals(data, rows).flatten().collect()
    }

    /// Each row's residual where `rows` selects it (`None` elsewhere), on every core.
    fn selected_residuals<'a>(
        &'a self,
        data: &'a crate::Dataset,
        rows: &'a (dyn Fn(usize) -> bool + Sync),
    ) -> impl rayon::iter::IndexedParallelIterator<Item = Option<Vec3>> + 'a {
        use rayon::prelude::*;
        let off = self.off_output(&mut self.scratch());
        (0..data.len())
            .into_par_iter()
            .with_min_len(RESIDUAL_ROWS_PER_TASK)
            .map_init(
                || self.scratch(),
                move |s, k| {
                    rows(k).then(|| {
                        data.y[k] - (self.output(data.u[k], data.regressors(k), &mut s.phi) - off)
                    })
                },
            )
    }

    /// Predicted disturbance at a row of a recording: zero with the motors off.
    pub fn dist(&self, rec: &Recording, row: usize, off: Vec3, s: &mut Scratch) -> Vec3 {
        let u = self.inputs_into(rec, row, s);
        self.output(u, &s.x, &mut s.phi) - off
    }

    /// Writes a row's regressors into `s.x` and returns its normalized input.
    fn inputs_into(&self, rec: &Recording, row: usize, s: &mut Scratch) -> f64 {
        self.input.regressors(rec, row, &mut s.x);
        self.input.normalize(self.input.raw(rec, row))
    }

    /// Predicted noise standard deviation at a row (zero if the model has no noise model).
    pub fn sd_at(&self, rec: &Recording, row: usize) -> Vec3 {
        match &self.sd {
            Some(m) => m.sd(self.input.normalize(self.input.raw(rec, row))),
            None => Vec3::zeros(),
        }
    }

    /// Predicted disturbance at a raw input value (throttle or amperes; every motor at that
    /// command for a per-motor model), for curves along the input.
    pub fn dist_at_input(&self, raw: f64, s: &mut Scratch) -> Vec3 {
        let off = self.off_output(s);
        let u = self.input.normalize(raw);
        if self.input.kind == crate::InputKind::Motors {
            s.x.fill(raw);
        } else {
            s.x[0] = u;
        }
        let last = s.x.len() - 1;
        s.x[last] = 1.0;
        self.output(u, &s.x, &mut s.phi) - off
    }

    /// Predicted disturbance for every row.
    pub fn dist_column(&self, rec: &Recording) -> Vec<Vec3> {
        let mut s = self.scratch();
        let off = self.off_output(&mut s);
        // A stair holds its input for many rows: a row whose input and regressors have the
        // bits of the row before it has its output too (the model is a function of them).
        let mut last_u = 0u64;
        let mut last_x = vec![0.0f64; s.x.len()];
        let mut last: Option<Vec3> = None;
        (0..rec.len())
            .map(|r| {
                let u = self.inputs_into(rec, r, &mut s);
                match last {
                    Some(out)
                        if u.to_bits() == last_u
                            && s.x
                                .iter()
                                .zip(&last_x)
                                .all(|(a, b)| a.to_bits() == b.to_bits()) =>
                    {
                        out
                    }
                    _ => {
                        let out = self.output(u, &s.x, &mut s.phi) - off;
                        (last, last_u) = (Some(out), u.to_bits());
                        last_x.copy_from_slice(&s.x);
                        out
                    }
                }
            })
            .collect()
    }

    /// The recording with the predicted disturbance removed from `mag_*_ut`, and the columns
    /// `dist_{x,y,z}_ut` (predicted disturbance) and `sd_{x,y,z}_ut` (predicted noise sd) added
    /// (replacing any of those names already present).
    pub fn compensate(&self, rec: &Recording, origin: &str) -> Result<Recording, IdentError> {
        rec.check()?;
        self.input.check_recording(rec, origin)?;
        let dist = self.dist_column(rec);
        Ok(self.compensate_with(rec, &dist))
    }

    /// The recording with `dist` (one prediction per row, µT) removed from `mag_*_ut`, and
    /// `dist_{x,y,z}_ut` and this model's `sd_{x,y,z}_ut` added: what [`Model::compensate`]
    /// writes, for a prediction made otherwise (the recursive estimation's).
    pub fn compensate_with(&self, rec: &Recording, dist: &[Vec3]) -> Recording {
        let mut out = rec.clone();
        for (m, d) in out.mag_ut.iter_mut().zip(dist) {
            *m -= d;
        }
        let names: Vec<String> = ["dist", "sd"]
            .iter()
            .flat_map(|g| AXES.iter().map(move |a| format!("{g}_{a}_ut")))
            .collect();
        out.extra.retain(|(n, _)| !names.contains(n));
        for a in 0..3 {
            out.extra.push((
                names[a].clone(),
                dist.iter().map(|d| format_extra(d[a])).collect(),
            ));
        }
        for a in 0..3 {
            out.extra.push((
                names[3 + a].clone(),
                (0..rec.len())
                    .map(|r| format_extra(self.sd_at(rec, r)[a]))
                    .collect(),
            ));
        }
        out
    }

    /// Writes the model as pretty JSON, atomically.
    pub fn save(&self, path: &Path) -> Result<(), IdentError> {
        // Never write what `load` would refuse: a model of non-finite or absurd numbers is a
        // failed fit, not a result.
        let summary_finite = self.summary.as_ref().is_none_or(|s| {
            s.rmse_ut
                .iter()
                .chain(&s.r2)
                .chain(&s.holdout_rmse_ut)
                .all(|v| v.is_finite())
        });
        if let Err(why) = self.validate().and_then(|()| {
            summary_finite
                .then_some(())
                .ok_or_else(|| "its fit statistics are not finite".to_string())
        }) {
            return Err(IdentError::ModelFile {
                origin: path.display().to_string(),
                message: format!("the fitted model is not written: {why}"),
            });
        }
        let text = serde_json::to_string_pretty(self).expect("a model always serializes") + "\n";
        atomic_file::write_bytes(path, text.as_bytes())?;
        Ok(())
    }

    /// Reads a model file and checks its format, version and consistency.
    pub fn load(path: &Path) -> Result<Self, IdentError> {
        let origin = path.display().to_string();
        let text =
            magstand_core::input_file::read_document(path).map_err(|e| IdentError::ModelFile {
                origin: origin.clone(),
                message: e.to_string(),
            })?;
        Self::from_json(&text, &origin)
    }

    /// Parses a model from JSON text.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, IdentError> {
        let v: serde_json::Value =
            serde_json::from_str(text).map_err(|e| IdentError::ModelFile {
                origin: origin.into(),
                message: format!("not JSON: {e}"),
            })?;
        Self::from_value(v, origin)
    }

    /// [`Model::from_json`] on a document already parsed.
    pub fn from_value(v: serde_json::Value, origin: &str) -> Result<Self, IdentError> {
        let err = |message: String| IdentError::ModelFile {
            origin: origin.into(),
            message,
        };
        if v.get("format").and_then(|f| f.as_str()) != Some(FORMAT) {
            return Err(err(format!(
                "not a magstand model (expected \"format\": \"{FORMAT}\")"
            )));
        }
        match v.get("version").and_then(|f| f.as_u64()) {
            Some(1) => {}
            other => {
                return Err(err(format!(
                    "model version {other:?} is not supported (this magstand reads version {VERSION})"
                )));
            }
        }
        let mut m: Model =
            serde_json::from_value(v).map_err(|e| err(format!("malformed model: {e}")))?;
        m.validate().map_err(err)?;
        m.method = method_name(&m.method).to_string();
        Ok(m)
    }

    fn validate(&self) -> Result<(), String> {
        let i = &self.input;
        // The same bounds the fit keeps: inputs of a real vehicle (a current of at most
        // 1e5 A), a span that normalizes without overflow, values whose products stay finite.
        use magstand_core::within;
        if !(within(i.lo, MAX_RAW_INPUT)
            && within(i.hi, MAX_RAW_INPUT)
            && i.hi - i.lo >= MIN_INPUT_SPAN
            && within(i.off_raw, MAX_RAW_INPUT))
        {
            return Err(format!(
                "input range lo={} hi={} off_raw={}: expected finite values of magnitude at most {MAX_RAW_INPUT:e} with hi - lo at least {MIN_INPUT_SPAN:e}",
                i.lo, i.hi, i.off_raw
            ));
        }
        if !(1..=MAX_MOTORS).contains(&i.motors) {
            return Err(format!(
                "input.motors = {}: expected 1..{MAX_MOTORS}",
                i.motors
            ));
        }
        if !self.reference_ut.iter().all(|v| within(*v, MAX_FIELD_UT)) {
            return Err(format!(
                "reference_ut = {:?}: expected finite values of magnitude at most {MAX_FIELD_UT:e} µT",
                self.reference_ut
            ));
        }
        if let Some(r) = &self.identified
            && !(r.lo.is_finite()
                && r.hi.is_finite()
                && r.lo <= r.hi
                && r.quantiles.len() == 21
                && r.quantiles
                    .iter()
                    .all(|q| q.is_finite() && (r.lo..=r.hi).contains(q))
                && r.quantiles.windows(2).all(|w| w[0] <= w[1]))
        {
            return Err(format!(
                "identified: lo={} hi={} with {} quantiles; expected finite lo <= hi and 21 ascending quantiles between them",
                r.lo,
                r.hi,
                r.quantiles.len()
            ));
        }
        let p = i.regressor_count();
        match &self.structure {
            Structure::LocalLinear(net) => {
                let part = &net.partition;
                if part.len() > MAX_LOCAL_MODELS
                    || !part.centers().iter().all(|c| within(*c, MAX_CENTER))
                    || !part.widths().iter().all(|w| within(*w, MAX_WIDTH))
                {
                    return Err(format!(
                        "partition: {} local models, centres {:?}, widths {:?}; expected at most {MAX_LOCAL_MODELS}, centres within +-{MAX_CENTER} and widths at most {MAX_WIDTH} on the normalized input",
                        part.len(),
                        part.centers(),
                        part.widths()
                    ));
                }
                if net.coefficients.len() != 3 {
                    return Err(format!(
                        "coefficients: {} axes; expected 3",
                        net.coefficients.len()
                    ));
                }
                if magstand_core::rbf::RbfPartition::new(
                    part.centers().to_vec(),
                    part.widths().to_vec(),
                )
                .is_none()
                {
                    return Err(
                        "partition needs as many finite centres as positive finite widths".into(),
                    );
                }
                for (a, per_axis) in net.coefficients.iter().enumerate() {
                    if per_axis.len() != net.partition.len()
                        || per_axis.iter().any(|c| {
                            c.len() != p || c.iter().any(|v| !within(*v, MAX_COEFFICIENT_UT))
                        })
                    {
                        return Err(format!(
                            "axis {}: expected {} local models of {p} finite coefficients of magnitude at most {MAX_COEFFICIENT_UT:e} µT",
                            AXES[a],
                            net.partition.len()
                        ));
                    }
                }
            }
            Structure::Polynomial { coefficients } => {
                if coefficients.len() != 3
                    || coefficients.iter().any(|c| {
                        c.is_empty()
                            || c.len() > MAX_POLYNOMIAL_TERMS
                            || c.iter().any(|v| !within(*v, MAX_COEFFICIENT_UT))
                    })
                {
                    return Err(format!(
                        "polynomial coefficients: expected 3 axes of 1..{MAX_POLYNOMIAL_TERMS} finite coefficients of magnitude at most {MAX_COEFFICIENT_UT:e} µT"
                    ));
                }
            }
        }
        if let Some(sd) = &self.sd
            && (sd.knots.len() < 2
                || sd.knots.len() > MAX_SD_KNOTS
                || !sd.knots.iter().all(|k| within(*k, MAX_CENTER))
                || sd.knots.windows(2).any(|w| w[0] >= w[1])
                || sd.sd_ut.len() != 3
                || sd.sd_ut.iter().any(|s| {
                    s.len() != sd.knots.len()
                        || s.iter().any(|v| !(within(*v, MAX_FIELD_UT) && *v >= 0.0))
                }))
        {
            return Err(format!(
                "sd model needs 2..{MAX_SD_KNOTS} ascending knots within +-{MAX_CENTER} and, per axis, one non-negative sd of at most {MAX_FIELD_UT:e} µT per knot"
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_statistics_are_the_sorted_values_at_their_ranks() {
        // Repeats, ties, signed zeros and a short input (whose ranks repeat).
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 97) as f64 / 7.0 - 6.0
        };
        for n in [1usize, 2, 3, 5, 20, 21, 22, 1000] {
            let mut v: Vec<f64> = (0..n).map(|_| next()).collect();
            if n > 3 {
                v[1] = -0.0;
                v[2] = 0.0;
            }
            let mut sorted = v.clone();
            sorted.sort_unstable_by(f64::total_cmp);
            let ranks: Vec<usize> = (0..=20)
                .map(|k| ((n - 1) as f64 * (k as f64 / 20.0)).round() as usize)
                .collect();
            let want: Vec<u64> = ranks.iter().map(|&r| sorted[r].to_bits()).collect();
            let got: Vec<u64> = order_statistics(&mut v, &ranks, 0)
                .iter()
                .map(|x| x.to_bits())
                .collect();
            assert_eq!(got, want, "n = {n}, ranks {ranks:?}");
        }
    }
}
