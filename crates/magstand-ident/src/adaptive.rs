//! Recursive estimation, the paper's future work: the local linear model's coefficients
//! updated row by row while it compensates, so that it follows a disturbance that drifts
//! (a battery, heat, a wire that moved).
//!
//! The model is linear in its coefficients: the disturbance is `z(u)ᵀ θ - z(u_off)ᵀ θ` with
//! `z = [φ_1(u) u, φ_1(u), ..., φ_m(u) u, φ_m(u)]`, the normalized RBF memberships `φ_i`
//! times each local model's regressors `[u, 1]` (eq. 12). Each row with the motors running
//! updates `θ` by recursive least squares on the row's deviation from the motors-off field:
//!
//! ```text
//! P ← D P D,   D = diag(d_j),  d_j = λ^-1/2 while P_jj < P_0, else 1
//! k = P z / (1 + zᵀ P z),   θ ← θ + k (y - zᵀ θ),   P ← P - k zᵀ P
//! ```
//!
//! The statistics `z zᵀ` of each local model are weighted by its membership, so a row updates
//! mostly the models responsible for its throttle. The forgetting stops where a coefficient's
//! variance reaches its starting value `P_0`: plain exponential forgetting lets the variance of
//! a model whose range is not visited grow without bound, and the first row back there throws
//! the model about (a first version without the stop diverged at λ = 0.9 on the drifting run
//! of `tests/tests/adaptive_compensation.rs`; a forgetting weighted by membership, with the
//! stop, followed the drift there two to three times more slowly than this one). `P` starts at `P_0 = m (1 - λ) I`: the identified coefficients
//! count as about one memory length `1 / (1 - λ)` of rows per model.
//!
//! The prediction a row is compensated with is made *before* the row updates the
//! coefficients, as a flight controller would: the row's own noise never removes itself.
//! The exported C and `no_std` Rust code runs the same recursion (`magstand export --to
//! c-adaptive|rust-adaptive`).
use magstand_core::{Recording, Vec3};

use crate::model::{Model, Structure};
use crate::{FitSetting, IdentError, InputKind};

/// Settings of the recursion, not yet checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptConfig {
    /// Forgetting factor λ per row: the memory is about `1 / (1 - λ)` rows.
    pub forgetting: f64,
}

impl Default for AdaptConfig {
    /// λ = 0.99: a memory of about 100 rows, 1 s at 100 Hz, the time a throttle step takes to
    /// settle on a stand.
    fn default() -> Self {
        Self { forgetting: 0.99 }
    }
}

/// Checked settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidAdaptConfig(AdaptConfig);

impl ValidAdaptConfig {
    /// The settings.
    pub fn params(&self) -> &AdaptConfig {
        &self.0
    }
}

impl AdaptConfig {
    /// Checks the forgetting factor: in [0.9, 0.999999] (a memory of 10 to a million rows).
    pub fn check(self) -> Result<ValidAdaptConfig, IdentError> {
        if !(self.forgetting.is_finite() && (0.9..=0.999_999).contains(&self.forgetting)) {
            return Err(IdentError::InvalidSetting {
                setting: FitSetting::Forgetting,
                value: self.forgetting.to_string(),
                expected:
                    "a forgetting factor in [0.9, 0.999999] (a memory of 10 to a million rows)"
                        .into(),
            });
        }
        Ok(ValidAdaptConfig(self))
    }
}

/// The starting variance `P_0` of every coefficient of `models` local models under
/// `forgetting`: also the ceiling forgetting stops at.
pub fn start_variance(models: usize, forgetting: f64) -> f64 {
    models as f64 * (1.0 - forgetting)
}

/// The factor `λ^-1/2` each forgetting step scales a row and column of `P` by.
pub fn growth(forgetting: f64) -> f64 {
    forgetting.powf(-0.5)
}

/// The recursion's state: the coefficients and their scaled covariance.
#[derive(Debug, Clone)]
pub struct Adaptive {
    partition: magstand_core::rbf::RbfPartition,
    lo: f64,
    hi: f64,
    off_u: f64,
    /// Identified input range (normalized): the memberships are those of the edge beyond it.
    edge: (f64, f64),
    /// `theta[axis][2 i + 0]` slope, `[2 i + 1]` intercept of model i.
    theta: [Vec<f64>; 3],
    /// Row-major `n × n`, n = 2 m.
    p: Vec<f64>,
    /// `λ^-1/2`.
    grow: f64,
    /// The starting variance of every coefficient: forgetting never takes one beyond it.
    p_max: f64,
    z: Vec<f64>,
    z_off: Vec<f64>,
    phi: Vec<f64>,
    pz: Vec<f64>,
}

impl Adaptive {
    /// The recursion started from a fitted one-input local linear model (throttle or
    /// current); other models are refused with the reason.
    pub fn new(model: &Model, config: &ValidAdaptConfig) -> Result<Self, IdentError> {
        let refuse = |why: &str| IdentError::ModelFile {
            origin: format!("model `{}`", model.method),
            message: why.into(),
        };
        let Structure::LocalLinear(net) = &model.structure else {
            return Err(refuse(
                "the recursive estimation updates local linear models; this one is a polynomial",
            ));
        };
        if model.input.kind == InputKind::Motors {
            return Err(refuse(
                "the recursive estimation takes one input (throttle or current); this model takes every motor's command",
            ));
        }
        let m = net.partition.len();
        let n = 2 * m;
        let lambda = config.params().forgetting;
        let mut p = vec![0.0; n * n];
        for j in 0..n {
            p[j * n + j] = start_variance(m, lambda);
        }
        let theta = std::array::from_fn(|a| {
            net.coefficients[a]
                .iter()
                .flat_map(|c| [c[0], c[1]])
                .collect()
        });
        let edge = model
            .identified
            .as_ref()
            .map_or((f64::NEG_INFINITY, f64::INFINITY), |r| (r.lo, r.hi));
        let mut s = Self {
            partition: net.partition.clone(),
            lo: model.input.lo,
            hi: model.input.hi,
            off_u: model.input.normalize(model.input.off_raw),
            edge,
            theta,
            p,
            grow: growth(lambda),
            p_max: start_variance(m, lambda),
            z: vec![0.0; n],
            z_off: vec![0.0; n],
            phi: vec![0.0; m],
            pz: vec![0.0; n],
        };
        let mut z_off = std::mem::take(&mut s.z_off);
        s.regressors(s.off_u, &mut z_off);
        s.z_off = z_off;
        Ok(s)
    }

    /// Normalized memberships at `u` (the edge's beyond the identified range), into `phi`.
    fn memberships(&mut self, u: f64) {
        let e = if u.is_finite() {
            u.clamp(self.edge.0, self.edge.1)
        } else {
            u
        };
        self.partition.weights_into(e, &mut self.phi);
    }

    /// `z(u)` into `z`, leaving the memberships in `self.phi`.
    fn regressors(&mut self, u: f64, z: &mut [f64]) {
        self.memberships(u);
        for (i, w) in self.phi.iter().enumerate() {
            z[2 * i] = w * u;
            z[2 * i + 1] = *w;
        }
    }

    /// The disturbance predicted at a raw input (throttle 0..1 or amperes) before this row,
    /// µT; then, when the motors run, the update with the row's deviation from the motors-off
    /// field (`deviation_ut`: the reading less the motors-off reference).
    pub fn step(&mut self, raw: f64, deviation_ut: Vec3) -> Vec3 {
        let u = (raw - self.lo) / (self.hi - self.lo);
        let mut z = std::mem::take(&mut self.z);
        self.regressors(u, &mut z);
        for (zj, off) in z.iter_mut().zip(&self.z_off) {
            *zj -= off;
        }
        let predicted = Vec3::from_fn(|a, _| dot(&z, &self.theta[a]));
        let n = z.len();
        if dot(&z, &z) > 1e-24 && deviation_ut.iter().all(|v| v.is_finite()) {
            // Forgetting, D P D, only while a coefficient's variance is below its starting
            // value: a direction the rows do not excite (a local model whose throttle range is
            // not visited) cannot wind up, and the first row back there adapts it no harder
            // than the first row after the start.
            let grow = self.grow;
            let scale: Vec<f64> = (0..n)
                .map(|j| {
                    if self.p[j * n + j] >= self.p_max {
                        1.0
                    } else {
                        grow
                    }
                })
                .collect();
            for r in 0..n {
                for c in 0..n {
                    self.p[r * n + c] *= scale[r] * scale[c];
                }
            }
            for r in 0..n {
                self.pz[r] = dot(&self.p[r * n..(r + 1) * n], &z);
            }
            let s = 1.0 + dot(&z, &self.pz);
            for (a, th) in self.theta.iter_mut().enumerate() {
                let e = deviation_ut[a] - predicted[a];
                for (t, k) in th.iter_mut().zip(&self.pz) {
                    *t += k * e / s;
                }
            }
            // P - Pz Pzᵀ / s, kept symmetric.
            for r in 0..n {
                for c in r..n {
                    let v = self.p[r * n + c] - self.pz[r] * self.pz[c] / s;
                    self.p[r * n + c] = v;
                    self.p[c * n + r] = v;
                }
            }
        }
        self.z = z;
        predicted
    }

    /// The current coefficients, `[axis][model][slope, intercept]`.
    pub fn coefficients(&self) -> [Vec<Vec<f64>>; 3] {
        std::array::from_fn(|a| self.theta[a].chunks(2).map(|c| c.to_vec()).collect())
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// What an adaptive compensation gives.
#[derive(Debug, Clone)]
pub struct AdaptiveCompensation {
    /// The recording with the prediction removed and `dist_*_ut`, `sd_*_ut` added, as
    /// [`Model::compensate`] writes them.
    pub recording: Recording,
    /// The prediction each row was compensated with, µT.
    pub dist_ut: Vec<Vec3>,
    /// The coefficients after the last row.
    pub final_coefficients: [Vec<Vec<f64>>; 3],
}

/// Compensates `rec` (named `origin`) with `model`, updating its coefficients row by row. The
/// motors-off reference of each row's deviation is `model.reference_ut`.
pub fn compensate_adaptive(
    model: &Model,
    rec: &Recording,
    origin: &str,
    config: &ValidAdaptConfig,
) -> Result<AdaptiveCompensation, IdentError> {
    rec.check()?;
    model.input.check_recording(rec, origin)?;
    let mut state = Adaptive::new(model, config)?;
    let reference = Vec3::from(model.reference_ut);
    let dist: Vec<Vec3> = (0..rec.len())
        .map(|r| state.step(model.input.raw(rec, r), rec.mag_ut[r] - reference))
        .collect();
    if dist.iter().any(|d| !d.iter().all(|v| v.is_finite())) {
        return Err(IdentError::Data {
            origin: origin.into(),
            message: "the recursive estimation diverged (a prediction is not finite)".into(),
        });
    }
    let recording = model.compensate_with(rec, &dist);
    Ok(AdaptiveCompensation {
        recording,
        dist_ut: dist,
        final_coefficients: state.coefficients(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Fit, FitConfig};

    /// A stair whose disturbance is `gain · (2 u + u²)` µT on x, the gain stepping from 1 to
    /// 1.2 halfway, noise-free: the recursion must follow the step, and with no step it must
    /// reproduce the fixed model exactly where nothing informs it otherwise.
    fn stair(gain_after: f64) -> (Recording, Vec<Vec3>) {
        let n = 4000;
        let mut rec = Recording::default();
        let mut truth = Vec::new();
        for r in 0..n {
            let level = ((r % 2000) / 100) as f64 / 19.0;
            let g = if r < n / 2 { 1.0 } else { gain_after };
            let d = g * (2.0 * level + level * level);
            rec.t_s.push(r as f64 * 0.01);
            truth.push(Vec3::new(d, -0.5 * d, 0.2 * d));
            rec.mag_ut.push(Vec3::new(20.0, 1.0, 40.0) + truth[r]);
        }
        rec.thr = vec![(0..n).map(|r| ((r % 2000) / 100) as f64 / 19.0).collect()];
        rec.overall_only = true;
        (rec, truth)
    }

    #[test]
    fn it_follows_a_gain_step_that_the_fixed_model_cannot() {
        let (ident, _) = stair(1.0);
        let model = FitConfig::evenly_spaced(3, crate::Estimation::Global)
            .check()
            .unwrap()
            .fit(&crate::Dataset::from_recording(&ident, InputKind::Throttle, "ident").unwrap())
            .unwrap();
        let (valid, truth) = stair(1.2);
        // A memory of about 20 rows, short against a level (100 rows).
        let cfg = AdaptConfig { forgetting: 0.95 }.check().unwrap();
        let adapted = compensate_adaptive(&model, &valid, "valid", &cfg).unwrap();
        let fixed = model.dist_column(&valid);
        // The last levels of the second half, each after its first half second: settled.
        let tail: Vec<usize> = (3600..4000).filter(|r| r % 100 >= 50).collect();
        let err = |d: &[Vec3]| {
            (tail
                .iter()
                .map(|&r| (d[r] - truth[r]).norm_squared())
                .sum::<f64>()
                / tail.len() as f64)
                .sqrt()
        };
        let (e_fixed, e_adapt) = (err(&fixed), err(&adapted.dist_ut));
        assert!(
            e_adapt < 0.2 * e_fixed,
            "adaptive {e_adapt} µT, fixed {e_fixed} µT"
        );
        let bad = AdaptConfig { forgetting: 1.5 }
            .check()
            .unwrap_err()
            .to_string();
        assert!(bad.contains("forgetting") && bad.contains("1.5"), "{bad}");
    }
}
