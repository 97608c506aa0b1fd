//! A field from outside the vehicle: equipment beside the stand with an alternating field
//! (a slow sine). It has nothing to do with the motors, and the mismatch diagnosis has no
//! term for it, which is why it is here: a recording with it switched on must be diagnosed as
//! "unexplained", not forced onto a wrong name. Off (zero amplitude) by default.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use magstand_core::Vec3;

/// `[interference]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InterferenceParams {
    /// Amplitude of the alternating field at the sensor, µT (x, y, z).
    pub amplitude_ut: [f64; 3],
    /// Period, s.
    pub period_s: f64,
}

impl Default for InterferenceParams {
    fn default() -> Self {
        Self {
            amplitude_ut: [0.0; 3],
            period_s: 23.0,
        }
    }
}

impl InterferenceParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        c.within3(
            "interference.amplitude_ut",
            self.amplitude_ut,
            crate::MAX_FIELD_UT,
        )?;
        c.range("interference.period_s", self.period_s, 1e-3, 1e6)
    }

    /// The field at time `t_s`, µT.
    pub fn field_ut(&self, t_s: f64) -> Vec3 {
        Vec3::from(self.amplitude_ut) * (std::f64::consts::TAU * t_s / self.period_s).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_off_by_default_and_periodic_when_on() {
        assert_eq!(InterferenceParams::default().field_ut(3.7), Vec3::zeros());
        let p = InterferenceParams {
            amplitude_ut: [1.0, 0.0, -2.0],
            period_s: 4.0,
        };
        let quarter = p.field_ut(1.0);
        assert!(
            (quarter - Vec3::new(1.0, 0.0, -2.0)).norm() < 1e-12,
            "{quarter}"
        );
        assert!((p.field_ut(9.0) - quarter).norm() < 1e-12);
    }
}
