//! From a recording to identification data: the scheduling input, the regressors of the local
//! models, and the deviation from the motors-off reading (eq. 9).
use serde::{Deserialize, Serialize};

use std::sync::Arc;

use crate::IdentError;
use magstand_core::{Recording, Vec3};

/// What drives the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputKind {
    /// The overall throttle (mean motor command), as in the paper.
    Throttle,
    /// Each motor's command as a separate regressor, scheduled on the overall throttle.
    Motors,
    /// The supply current `bat_a`.
    Current,
}

impl std::str::FromStr for InputKind {
    type Err = IdentError;
    fn from_str(s: &str) -> Result<Self, IdentError> {
        match s {
            "throttle" => Ok(InputKind::Throttle),
            "motors" => Ok(InputKind::Motors),
            "current" => Ok(InputKind::Current),
            _ => Err(IdentError::InvalidSetting {
                setting: crate::FitSetting::Input,
                value: s.into(),
                expected: "throttle, motors or current".into(),
            }),
        }
    }
}

/// The model's input: which signal, how it is normalized to 0..1 (the paper normalizes its
/// input; the scaling is stored with the model and undone on use), and its motors-off value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputSpec {
    /// Which signal.
    pub kind: InputKind,
    /// Raw value mapped to 0.
    pub lo: f64,
    /// Raw value mapped to 1.
    pub hi: f64,
    /// Motor count of the recordings the model applies to.
    pub motors: usize,
    /// Raw input with the motors off (0 for commands; the avionics current for `current`).
    pub off_raw: f64,
}

impl InputSpec {
    /// Normalized scheduling value of a raw input.
    pub fn normalize(&self, raw: f64) -> f64 {
        (raw - self.lo) / (self.hi - self.lo)
    }

    /// The raw input of a normalized one (the inverse of [`InputSpec::normalize`]).
    pub fn denormalize(&self, u: f64) -> f64 {
        self.lo + u * (self.hi - self.lo)
    }

    /// Raw scheduling input at a row.
    pub fn raw(&self, rec: &Recording, row: usize) -> f64 {
        match self.kind {
            InputKind::Throttle | InputKind::Motors => rec.overall_throttle(row),
            InputKind::Current => rec.bat_a.as_ref().map(|a| a[row]).unwrap_or(f64::NAN),
        }
    }

    /// Number of regressors of each local model (inputs plus the intercept).
    pub fn regressor_count(&self) -> usize {
        match self.kind {
            InputKind::Motors => self.motors + 1,
            _ => 2,
        }
    }

    /// Regressors at a row: `[u, 1]`, or `[thr_1 .. thr_N, 1]` for per-motor inputs.
    pub fn regressors(&self, rec: &Recording, row: usize, out: &mut [f64]) {
        match self.kind {
            InputKind::Motors => {
                for (m, o) in out.iter_mut().take(self.motors).enumerate() {
                    *o = rec.thr[m][row];
                }
            }
            _ => out[0] = self.normalize(self.raw(rec, row)),
        }
        out[out.len() - 1] = 1.0;
    }

    /// Regressors with the motors off.
    pub fn off_regressors(&self, out: &mut [f64]) {
        out.fill(0.0);
        if self.kind != InputKind::Motors {
            out[0] = self.normalize(self.off_raw);
        }
        out[out.len() - 1] = 1.0;
    }

    /// Checks that a recording can feed this input.
    pub fn check_recording(&self, rec: &Recording, origin: &str) -> Result<(), IdentError> {
        if self.kind == InputKind::Current && rec.bat_a.is_none() {
            return Err(IdentError::Data { origin: origin.into(), message: "the model's input is the supply current, but the recording has no `bat_a` column".into() });
        }
        if self.kind == InputKind::Motors && rec.motor_count() != self.motors {
            return Err(IdentError::Data {
                origin: origin.into(),
                message: format!(
                    "the model has per-motor inputs for {} motors, the recording has {} motor columns",
                    self.motors,
                    rec.motor_count()
                ),
            });
        }
        Ok(())
    }
}

/// Rows used for identification, with their inputs and eq. 9 deviations.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Where the data came from (for error messages).
    pub origin: String,
    /// The input specification.
    pub spec: InputSpec,
    /// Normalized scheduling input per row.
    pub u: Vec<f64>,
    /// Regressors, row-major, [`InputSpec::regressor_count`] per row.
    pub x: Vec<f64>,
    /// Deviation from the motors-off reference per row (eq. 9), µT: shared by the datasets of
    /// one recording's inputs ([`Dataset::with_input`]).
    pub y: Arc<[Vec3]>,
    /// Time per row, s (shared like `y`).
    pub t_s: Arc<[f64]>,
    /// The motors-off reference reading, µT.
    pub reference_ut: Vec3,
    /// Rows with all motors off.
    pub off_rows: usize,
    /// Rows of equal input and regressors, indexed on first use ([`crate::row_groups`]); the
    /// rows' `u` and `x` must not change after it.
    groups: std::sync::OnceLock<Option<std::sync::Arc<crate::row_groups::GroupIndex>>>,
    /// The identification split of the rows' times, made on first use; `t_s` must not change
    /// after it.
    split: std::sync::OnceLock<Arc<magstand_core::held_out::Split>>,
}

/// The motors-off rows of a recording.
pub fn motors_off_rows(rec: &Recording) -> Vec<usize> {
    (0..rec.len()).filter(|&r| rec.motors_off(r)).collect()
}

/// The eq. 9 reference: the mean field over the motors-off rows, or `None` without any.
pub fn motors_off_reference(rec: &Recording, off_rows: &[usize]) -> Option<Vec3> {
    (!off_rows.is_empty())
        .then(|| off_rows.iter().map(|&r| rec.mag_ut[r]).sum::<Vec3>() / off_rows.len() as f64)
}

/// Every how many time blocks the identification split holds one out.
pub const HOLDOUT_EVERY: usize = 5;

/// Which block of every [`HOLDOUT_EVERY`] the automatic structure search scores its
/// candidates on: the one before the held-out block (the last), so the search never sees the
/// held-out rows.
pub const STRUCTURE_SCORE_BLOCK: usize = HOLDOUT_EVERY - 2;

/// The identification split's block length for the times `t_s` (ascending), s: 1 s, or
/// shorter so that the span holds at least 50 blocks.
pub fn identification_block_s(t_s: &[f64]) -> f64 {
    let span = t_s.last().copied().unwrap_or(0.0) - t_s.first().copied().unwrap_or(0.0);
    (span / 50.0).clamp(1e-6, 1.0)
}

/// The identification's held-out split of the times `t_s` (ascending): blocks of
/// [`identification_block_s`], every [`HOLDOUT_EVERY`]th held out, a gap in the data a block
/// boundary ([`magstand_core::held_out::Split`], the split the diagnosis uses too).
pub fn identification_split(t_s: &[f64]) -> magstand_core::held_out::Split {
    magstand_core::held_out::Split::new(t_s, identification_block_s(t_s), HOLDOUT_EVERY)
}

/// Whether `rec` has what input `kind` needs: the missing column first, since it is the
/// user's choice of input that cannot work.
fn check_input(rec: &Recording, kind: InputKind, origin: &str) -> Result<(), IdentError> {
    let data_err = |message: &str| IdentError::Data {
        origin: origin.into(),
        message: message.into(),
    };
    if kind == InputKind::Motors && rec.overall_only {
        return Err(data_err(
            "per-motor inputs need thr_1..thr_N columns; the recording has only the overall `thr`",
        ));
    }
    if kind == InputKind::Current && rec.bat_a.is_none() {
        return Err(data_err(
            "the current `input` needs a `bat_a` column; the recording has none (use the throttle)",
        ));
    }
    Ok(())
}

/// Input `kind`'s specification, normalized input and regressors (row-major) for every row
/// of `rec`, whose motors-off rows are `off`; refused when the input never varies.
fn inputs(
    rec: &Recording,
    kind: InputKind,
    off: &[usize],
    origin: &str,
) -> Result<(InputSpec, Vec<f64>, Vec<f64>), IdentError> {
    let (lo, hi, off_raw) = match kind {
        InputKind::Throttle | InputKind::Motors => (0.0, 1.0, 0.0),
        InputKind::Current => {
            let a = rec.bat_a.as_ref().ok_or_else(|| IdentError::Data {
                origin: origin.into(),
                message: "the current `input` needs a `bat_a` column".into(),
            })?;
            let off_a = if off.is_empty() {
                0.0
            } else {
                off.iter().map(|&r| a[r]).sum::<f64>() / off.len() as f64
            };
            let max = a.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            (0.0, if max > 0.0 { max } else { 1.0 }, off_a)
        }
    };
    let spec = InputSpec {
        kind,
        lo,
        hi,
        motors: rec.motor_count(),
        off_raw,
    };
    let p = spec.regressor_count();
    let mut x = vec![0.0; rec.len() * p];
    let mut u = Vec::with_capacity(rec.len());
    for r in 0..rec.len() {
        spec.regressors(rec, r, &mut x[r * p..(r + 1) * p]);
        u.push(spec.normalize(spec.raw(rec, r)));
    }
    let (umin, umax) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if umax - umin < 1e-9 {
        return Err(IdentError::Singular {
            origin: origin.into(),
            what: "disturbance model".into(),
            why: format!(
                "the input never varies (always {umin:.4}); record the motors over a range of throttle"
            ),
        });
    }
    if kind == InputKind::Motors
        && let Some(why) = dependent_motor(rec)
    {
        return Err(IdentError::Singular {
            origin: origin.into(),
            what: "per-motor model".into(),
            why: format!(
                "{why}, so the motors' own fields cannot be told apart; a per-motor model needs \
                 commands that move each motor on its own (a `per_motor_steps` program), or use \
                 `--inputs throttle`"
            ),
        });
    }
    Ok((spec, u, x))
}

/// How far a motor's commands must stand from the span of the earlier motors' and a constant,
/// as the sine of the angle between them, to count as a regressor of their own: far below a
/// one-percent differential command, far above rounding.
const INDEPENDENT_COMMAND_SINE: f64 = 1e-8;

/// Rows per block of the QR in [`dependent_motor`]: the triangle of the rows so far and the
/// next block are factored together, so a ten-hour log is never copied whole.
const QR_BLOCK_ROWS: usize = 4096;

/// The first motor of `rec` whose commands are, on every row, a combination of the earlier
/// motors' and a constant (by a QR of `[1, thr_1 .. thr_N]`: the diagonal of `R` is each
/// column's distance from the span of those before it), described for an error; `None` where
/// every motor's commands are their own. The QR is taken a block of rows at a time (the `R`
/// of the rows so far stacked on the next block), in bounded memory.
fn dependent_motor(rec: &Recording) -> Option<String> {
    let (n, motors) = (rec.len(), rec.motor_count());
    let k = motors + 1;
    let column = |c: usize, r: usize| if c == 0 { 1.0 } else { rec.thr[c - 1][r] };
    let mut norms_sq = vec![0.0; k];
    let mut r_so_far: Option<nalgebra::DMatrix<f64>> = None;
    for start in (0..n).step_by(QR_BLOCK_ROWS) {
        let rows = start..(start + QR_BLOCK_ROWS).min(n);
        let above = r_so_far.as_ref().map_or(0, |r| r.nrows());
        let block = nalgebra::DMatrix::from_fn(above + rows.len(), k, |i, c| match &r_so_far {
            Some(r) if i < above => r[(i, c)],
            _ => column(c, rows.start + i - above),
        });
        for (c, sq) in norms_sq.iter_mut().enumerate() {
            *sq += rows.clone().map(|r| column(c, r).powi(2)).sum::<f64>();
        }
        r_so_far = Some(block.qr().r());
    }
    let r = r_so_far?;
    let m = (1..=motors).find(|&c| {
        let diagonal = if c < r.nrows() { r[(c, c)].abs() } else { 0.0 };
        diagonal <= INDEPENDENT_COMMAND_SINE * norms_sq[c].sqrt()
    })?;
    let same = (0..m - 1).find(|&j| rec.thr[j] == rec.thr[m - 1]);
    Some(match same {
        Some(j) => format!("motor {m} gets motor {}'s command on every row", j + 1),
        None => format!(
            "motor {m}'s command is on every row a combination of motors 1..{}'s and a constant",
            m - 1
        ),
    })
}

/// Minimum rows a fit accepts.
pub const MIN_ROWS: usize = 20;

impl Dataset {
    /// Builds identification data from a recording; the eq. 9 reference is the mean reading
    /// over its motors-off rows.
    pub fn from_recording(
        rec: &Recording,
        kind: InputKind,
        origin: &str,
    ) -> Result<Self, IdentError> {
        Self::from_recording_or(rec, kind, origin, None)
    }

    /// As [`Dataset::from_recording`], with a reference to use when the recording has no
    /// motors-off rows (a flight's, from [`crate::flight::FlightPrep::reference_ut`]); the
    /// motors-off reading at input zero is then taken as 0 A for a current input.
    pub fn from_recording_or(
        rec: &Recording,
        kind: InputKind,
        origin: &str,
        fallback_reference_ut: Option<Vec3>,
    ) -> Result<Self, IdentError> {
        let data_err = |message: String| IdentError::Data {
            origin: origin.into(),
            message,
        };
        rec.check()?;
        if rec.len() < MIN_ROWS {
            return Err(data_err(format!(
                "{} rows; a fit needs at least {MIN_ROWS}",
                rec.len()
            )));
        }
        check_input(rec, kind, origin)?;
        let off = motors_off_rows(rec);
        let reference_ut = motors_off_reference(rec, &off).or(fallback_reference_ut).ok_or_else(|| data_err("no motors-off rows (rows whose every thr is 0) to take the eq. 9 reference from; record a few seconds with the motors off (for a flight with its Earth field taken out, one whose input comes down near zero will do)".into()))?;
        let (spec, u, x) = inputs(rec, kind, &off, origin)?;
        Ok(Dataset {
            origin: origin.into(),
            spec,
            u,
            x,
            y: rec.mag_ut.iter().map(|m| m - reference_ut).collect(),
            t_s: rec.t_s.as_slice().into(),
            reference_ut,
            off_rows: off.len(),
            groups: std::sync::OnceLock::new(),
            split: std::sync::OnceLock::new(),
        })
    }

    /// The dataset of another input of the same recording `rec` (the one this dataset was built
    /// from): its own inputs and regressors, this one's deviations, times, reference and
    /// identification split shared rather than copied (a long log's families then hold one
    /// copy of them).
    pub fn with_input(&self, rec: &Recording, kind: InputKind) -> Result<Self, IdentError> {
        if rec.len() != self.len() || rec.t_s.first() != self.t_s.first() {
            return Err(IdentError::Data {
                origin: self.origin.clone(),
                message: format!(
                    "another input's data must come from the same recording ({} rows here, {} given)",
                    self.len(),
                    rec.len()
                ),
            });
        }
        check_input(rec, kind, &self.origin)?;
        let off = motors_off_rows(rec);
        let (spec, u, x) = inputs(rec, kind, &off, &self.origin)?;
        // Made here once, so both datasets hold the same split.
        self.split();
        Ok(Dataset {
            origin: self.origin.clone(),
            spec,
            u,
            x,
            y: Arc::clone(&self.y),
            t_s: Arc::clone(&self.t_s),
            reference_ut: self.reference_ut,
            off_rows: self.off_rows,
            groups: std::sync::OnceLock::new(),
            split: self.split.clone(),
        })
    }

    /// Which rows share their input and regressors exactly, indexed once per dataset; `None`
    /// when the inputs hardly repeat ([`crate::row_groups`]).
    pub fn group_index(&self) -> Option<std::sync::Arc<crate::row_groups::GroupIndex>> {
        self.groups
            .get_or_init(|| {
                crate::row_groups::inputs_repeat(self)
                    .then(|| std::sync::Arc::new(crate::row_groups::GroupIndex::of(self)))
            })
            .clone()
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }

    /// Regressors of a row.
    pub fn regressors(&self, row: usize) -> &[f64] {
        let p = self.spec.regressor_count();
        &self.x[row * p..(row + 1) * p]
    }

    /// Index of the time block of each row: blocks of 1 s, or shorter so that a recording has
    /// at least 50 of them.
    pub fn time_blocks(&self) -> Vec<u64> {
        self.split().block.iter().map(|&b| b as u64).collect()
    }

    /// The identification split of the rows ([`identification_split`]), made once.
    pub(crate) fn split(&self) -> &magstand_core::held_out::Split {
        self.split
            .get_or_init(|| Arc::new(identification_split(&self.t_s)))
    }

    /// Splits rows into identification and held-out sets by time blocks: every fifth block is
    /// held out, so that held-out samples are not neighbours of fitted ones.
    pub fn holdout_mask(&self) -> Vec<bool> {
        self.split().holdout.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stair of three levels on four motors with unequal commands (each motor's own small
    /// wobble on its share of the level), its supply current and a field growing with the
    /// commands; motors off at both ends.
    fn stair() -> Recording {
        let n = 600;
        let level = |r: usize| match r {
            0..100 | 500.. => 0.0,
            _ => 0.2 + 0.2 * ((r - 100) / 134) as f64,
        };
        let wobble = |m: usize, r: usize| 0.005 * (r as f64 * (0.37 + 0.23 * m as f64)).sin();
        let mut rec = Recording {
            t_s: (0..n).map(|r| r as f64 * 0.02).collect(),
            thr: (0..4)
                .map(|m| {
                    (0..n)
                        .map(|r| match level(r) {
                            0.0 => 0.0,
                            l => l * (1.0 + 0.05 * m as f64) + wobble(m, r),
                        })
                        .collect()
                })
                .collect(),
            mag_ut: (0..n)
                .map(|r| Vec3::new(20.0 + 3.0 * level(r), -5.0, 45.0 - level(r).powi(2)))
                .collect(),
            ..Recording::default()
        };
        rec.bat_a = Some((0..n).map(|r| 0.5 + 40.0 * level(r).powi(2)).collect());
        rec
    }

    /// Regression: on a hexacopter whose motors 1 and 5 (and 2 and 6) always got the same
    /// command, `fit --inputs motors` stopped with "regressor `thr_5` of local model 1 is not
    /// independent ... the input does not vary enough where that model is responsible": true
    /// of no local model in particular, and silent on why. The per-motor inputs are now
    /// checked before any fit, and the error names the motors that cannot be told apart.
    #[test]
    fn per_motor_inputs_that_cannot_be_told_apart_are_refused_by_name() {
        let why = |rec: &Recording| match Dataset::from_recording(rec, InputKind::Motors, "t") {
            Err(IdentError::Singular { why, .. }) => why,
            other => panic!("expected a singular per-motor model, got {other:?}"),
        };
        let base = stair();
        // Motor 4 given motor 2's commands.
        let mut paired = base.clone();
        paired.thr[3] = paired.thr[1].clone();
        let text = why(&paired);
        assert!(
            text.contains("motor 4 gets motor 2's command on every row"),
            "{text}"
        );
        // Motor 3 a mix of motors 1 and 2 and a constant offset while running (as a mixer
        // makes a hexacopter's six commands from four inputs) is refused by combination.
        let mut mixed = base.clone();
        mixed.thr[2] = (0..base.len())
            .map(|r| 0.5 * base.thr[0][r] + 0.7 * base.thr[1][r])
            .collect();
        let text = why(&mixed);
        assert!(
            text.contains("motor 3's command is on every row a combination of motors 1..2's"),
            "{text}"
        );
        // Differential commands of under a percent still tell the motors apart.
        assert!(Dataset::from_recording(&base, InputKind::Motors, "t").is_ok());
        // Over several of the QR's blocks (the stair repeated), the same answers.
        let long = |rec: &Recording| {
            let mut out = rec.clone();
            let span = rec.t_s.last().unwrap() + 0.02;
            for k in 1..(3 * QR_BLOCK_ROWS / rec.len() + 2) {
                out.t_s.extend(rec.t_s.iter().map(|t| t + k as f64 * span));
                for (o, c) in out.thr.iter_mut().zip(&rec.thr) {
                    o.extend(c);
                }
                out.mag_ut.extend(&rec.mag_ut);
                if let (Some(o), Some(a)) = (out.bat_a.as_mut(), rec.bat_a.as_ref()) {
                    o.extend(a);
                }
            }
            assert!(out.len() > 3 * QR_BLOCK_ROWS, "{} rows", out.len());
            out
        };
        assert_eq!(dependent_motor(&long(&paired)), dependent_motor(&paired));
        assert_eq!(dependent_motor(&long(&mixed)), dependent_motor(&mixed));
        assert_eq!(dependent_motor(&long(&base)), None);
    }

    #[test]
    fn another_input_shares_the_rows_and_equals_its_own_build() {
        let rec = stair();
        let base = Dataset::from_recording(&rec, InputKind::Throttle, "stair").unwrap();
        for kind in [InputKind::Current, InputKind::Motors] {
            let shared = base.with_input(&rec, kind).unwrap();
            let own = Dataset::from_recording(&rec, kind, "stair").unwrap();
            assert_eq!(shared.spec, own.spec, "{kind:?}");
            assert_eq!((&shared.u, &shared.x), (&own.u, &own.x), "{kind:?}");
            assert_eq!((&shared.y, &shared.t_s), (&own.y, &own.t_s), "{kind:?}");
            assert_eq!(shared.reference_ut, own.reference_ut, "{kind:?}");
            assert_eq!(shared.holdout_mask(), own.holdout_mask(), "{kind:?}");
            // One copy of the rows' deviations, times and split.
            assert!(Arc::ptr_eq(&shared.y, &base.y) && Arc::ptr_eq(&shared.t_s, &base.t_s));
            assert!(std::ptr::eq(shared.split(), base.split()), "{kind:?}");
        }
    }

    #[test]
    fn another_input_is_refused_as_its_own_build_would_be() {
        let mut rec = stair();
        let base = Dataset::from_recording(&rec, InputKind::Throttle, "stair").unwrap();
        rec.bat_a = None;
        let shared = base.with_input(&rec, InputKind::Current).unwrap_err();
        let own = Dataset::from_recording(&rec, InputKind::Current, "stair").unwrap_err();
        assert_eq!(shared.to_string(), own.to_string());
        // Another recording's rows are not this dataset's.
        let short = Recording {
            t_s: rec.t_s[..300].to_vec(),
            thr: rec.thr.iter().map(|c| c[..300].to_vec()).collect(),
            mag_ut: rec.mag_ut[..300].to_vec(),
            ..Recording::default()
        };
        let e = base.with_input(&short, InputKind::Motors).unwrap_err();
        assert!(e.to_string().contains("same recording"), "{e}");
    }
}
