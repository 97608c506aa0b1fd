//! Zero-mean noise: the sensor's own noise mu, constant, and the motor-related noise eta whose
//! standard deviation grows with the load (eq. 8: "variance grows with control input").
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};

/// How the standard deviation of eta grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EtaLaw {
    /// `sd = eta_sd_per_a_ut * total current`.
    Current,
    /// `sd = eta_sd_full_ut * throttle ^ eta_exponent` (throttle = mean motor command).
    Throttle,
}

/// Noise parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseParams {
    /// Switch for both noise terms.
    pub enabled: bool,
    /// Standard deviation of the sensor noise mu on each axis, µT.
    pub sensor_sd_ut: f64,
    /// Law for the standard deviation of eta.
    pub eta_law: EtaLaw,
    /// For `current`: µT of standard deviation per ampere of supply current.
    pub eta_sd_per_a_ut: f64,
    /// For `throttle`: standard deviation at full throttle, µT.
    pub eta_sd_full_ut: f64,
    /// For `throttle`: exponent of the law.
    pub eta_exponent: f64,
    /// Per-axis scale of eta (x, y, z).
    pub eta_axis_scale: [f64; 3],
}

impl Default for NoiseParams {
    fn default() -> Self {
        Self {
            enabled: true,
            sensor_sd_ut: 0.15,
            eta_law: EtaLaw::Current,
            eta_sd_per_a_ut: 0.02,
            eta_sd_full_ut: 1.2,
            eta_exponent: 1.5,
            eta_axis_scale: [1.0, 1.0, 1.0],
        }
    }
}

impl NoiseParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        c.range("noise.sensor_sd_ut", self.sensor_sd_ut, 0.0, 1e3)?;
        c.range("noise.eta_sd_per_a_ut", self.eta_sd_per_a_ut, 0.0, 1e2)?;
        c.range("noise.eta_sd_full_ut", self.eta_sd_full_ut, 0.0, 1e3)?;
        c.range("noise.eta_exponent", self.eta_exponent, 0.0, 10.0)?;
        for (k, s) in self.eta_axis_scale.iter().enumerate() {
            c.range(&format!("noise.eta_axis_scale[{k}]"), *s, 0.0, 100.0)?;
        }
        Ok(())
    }

    /// Standard deviation of mu + eta on each axis, µT.
    pub fn sd_ut(&self, total_current_a: f64, throttle: f64) -> [f64; 3] {
        if !self.enabled {
            return [0.0; 3];
        }
        let eta = match self.eta_law {
            EtaLaw::Current => self.eta_sd_per_a_ut * total_current_a.max(0.0),
            EtaLaw::Throttle => {
                self.eta_sd_full_ut * throttle.clamp(0.0, 1.0).powf(self.eta_exponent)
            }
        };
        self.eta_axis_scale
            .map(|s| (self.sensor_sd_ut.powi(2) + (s * eta).powi(2)).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sd_adds_in_quadrature_and_grows_with_load() {
        let p = NoiseParams::default();
        assert_eq!(p.sd_ut(0.0, 0.0), [0.15; 3]);
        let full = p.sd_ut(60.0, 1.0)[0];
        assert!(
            (full - (0.15f64.powi(2) + 1.2f64.powi(2)).sqrt()).abs() < 1e-12,
            "{full}"
        );
        let t = NoiseParams {
            eta_law: EtaLaw::Throttle,
            sensor_sd_ut: 0.0,
            ..p
        };
        assert!((t.sd_ut(0.0, 0.25)[2] - 1.2 * 0.125).abs() < 1e-12);
    }

    #[test]
    fn disabled_noise_is_zero() {
        let p = NoiseParams {
            enabled: false,
            ..Default::default()
        };
        assert_eq!(p.sd_ut(60.0, 1.0), [0.0; 3]);
    }
}
