//! `[study]`: what a Monte Carlo study changes from run to run.
//!
//! A study simulates, per run, an identification series and a separate validation series (the
//! paper identified on one stair and validated on another). `validation` lists the `key=value`
//! overrides that turn the scenario into its validation series (for a stair, e.g.
//! `program.direction="down"`); `vary` declares scenario parameters drawn afresh in every run
//! (wiring position, motor constants, battery, noise levels), so a study covers a population
//! of vehicles rather than one.
//!
//! ```toml
//! [study]
//! validation = ['program.direction="down"']
//! [[study.vary]]
//! key = "motors.kv_rpm_per_v"
//! normal = [920.0, 30.0]          # mean, sd
//! [[study.vary]]
//! key = "magnetometer.position_m[0]"
//! uniform = [-0.01, 0.01]         # low, high
//! ```
//!
//! Draws are applied to the fully resolved scenario and checked again, so a draw outside a
//! parameter's allowed range is an error naming the key, never a silent clamp.
use rand::Rng;
use rand_distr::{Distribution, LogNormal, Normal, Uniform};
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};

/// One parameter drawn per run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VaryParam {
    /// Dotted scenario key, with `[i]` for an array element.
    pub key: String,
    /// Normal distribution: mean and standard deviation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f64; 2]>,
    /// Uniform distribution: low and high.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uniform: Option<[f64; 2]>,
    /// Log-normal distribution: median and the sd of the logarithm (a spread in ratio, for
    /// positive quantities such as resistances and noise levels).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lognormal: Option<[f64; 2]>,
}

/// `[study]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct StudyParams {
    /// Overrides that make the validation series from the scenario (empty: the same program
    /// with another seed).
    pub validation: Vec<String>,
    /// Parameters drawn per run.
    pub vary: Vec<VaryParam>,
}

impl VaryParam {
    fn check(&self, c: &Checker, at: &str) -> Result<(), SimError> {
        let given = [self.normal, self.uniform, self.lognormal]
            .iter()
            .filter(|d| d.is_some())
            .count();
        if given != 1 || self.key.trim().is_empty() {
            return Err(c.fail(
                at,
                &self.key,
                "a `key` and exactly one of `normal`, `uniform`, `lognormal`",
            ));
        }
        if let Some([_, sd]) = self.normal {
            c.range(&format!("{at}.normal[1]"), sd, 0.0, f64::INFINITY)?;
        }
        if let Some([lo, hi]) = self.uniform {
            c.range(&format!("{at}.uniform[0]"), lo, f64::MIN, f64::MAX)?;
            c.range(&format!("{at}.uniform[1]"), hi, lo, f64::MAX)?;
        }
        if let Some([median, s]) = self.lognormal {
            c.positive(&format!("{at}.lognormal[0]"), median)?;
            c.range(&format!("{at}.lognormal[1]"), s, 0.0, 5.0)?;
        }
        Ok(())
    }

    /// Draws a value and returns it as a `key=value` override.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> String {
        // Distributions were checked with the scenario, so construction cannot fail; a zero
        // spread gives the centre value.
        let v = if let Some([m, sd]) = self.normal {
            Normal::new(m, sd).map_or(m, |d| d.sample(rng))
        } else if let Some([lo, hi]) = self.uniform {
            if hi > lo {
                Uniform::new(lo, hi).map_or(lo, |d| d.sample(rng))
            } else {
                lo
            }
        } else if let Some([median, s]) = self.lognormal {
            LogNormal::new(median.ln(), s).map_or(median, |d| d.sample(rng))
        } else {
            f64::NAN
        };
        // `{:?}` keeps a decimal point, so the TOML value stays a float.
        format!("{}={v:?}", self.key)
    }
}

impl StudyParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        for (i, v) in self.vary.iter().enumerate() {
            v.check(c, &format!("study.vary[{i}]"))?;
        }
        for (i, o) in self.validation.iter().enumerate() {
            if !o.contains('=') {
                return Err(c.fail(
                    &format!("study.validation[{i}]"),
                    o,
                    "a `key=value` override",
                ));
            }
        }
        Ok(())
    }

    /// One draw of every varied parameter, as overrides, in declaration order.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<String> {
        self.vary.iter().map(|v| v.draw(rng)).collect()
    }
}
