//! A gimbal under the stand that turns the whole vehicle: the attitude changes of a flight
//! without flying. The Earth field seen in the body frame then moves with the attitude while
//! the motor disturbance, fixed to the body, does not: exactly the separation a flight-log
//! identification has to make. Off (no turning, no tilt) by default.
//!
//! The gimbal yaws at a constant rate and tilts on a cone: roll `tilt sin(2 pi t / P)`,
//! pitch `tilt cos(2 pi t / P)`. It is applied on top of the rapier body's own small motion.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use magstand_core::Quat;

/// `[motion]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotionParams {
    /// Yaw rate of the gimbal, degrees per second (positive turns the nose east).
    pub yaw_rate_dps: f64,
    /// Tilt of the cone, degrees.
    pub tilt_deg: f64,
    /// Period of one turn of the tilt cone, s.
    pub tilt_period_s: f64,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            yaw_rate_dps: 0.0,
            tilt_deg: 0.0,
            tilt_period_s: 20.0,
        }
    }
}

impl MotionParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        c.range("motion.yaw_rate_dps", self.yaw_rate_dps, -360.0, 360.0)?;
        c.range("motion.tilt_deg", self.tilt_deg, 0.0, 60.0)?;
        c.range("motion.tilt_period_s", self.tilt_period_s, 1e-2, 1e6)
    }

    /// True when the gimbal moves at all.
    pub fn is_on(&self) -> bool {
        self.yaw_rate_dps != 0.0 || self.tilt_deg != 0.0
    }

    /// The gimbal's rotation at time `t_s`, applied in the world (north-east-down) frame.
    pub fn rotation(&self, t_s: f64) -> Quat {
        let phase = std::f64::consts::TAU * t_s / self.tilt_period_s;
        let tilt = self.tilt_deg.to_radians();
        let yaw = (self.yaw_rate_dps * t_s).to_radians();
        Quat::from_euler_angles(tilt * phase.sin(), tilt * phase.cos(), yaw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use magstand_core::Vec3;

    #[test]
    fn off_by_default_and_turns_when_on() {
        let off = MotionParams::default();
        assert!(!off.is_on());
        assert!(off.rotation(12.3).angle() < 1e-15);
        let turn = MotionParams {
            yaw_rate_dps: 10.0,
            ..MotionParams::default()
        };
        // After 9 s at 10 deg/s the nose points east.
        let nose = turn.rotation(9.0) * Vec3::x();
        assert!((nose - Vec3::y()).norm() < 1e-12, "{nose:?}");
        let cone = MotionParams {
            tilt_deg: 20.0,
            tilt_period_s: 8.0,
            ..MotionParams::default()
        };
        for t in [0.0, 1.0, 2.5, 6.0] {
            let up = cone.rotation(t) * Vec3::z();
            let tilt = up.angle(&Vec3::z()).to_degrees();
            assert!((tilt - 20.0).abs() < 0.5, "t {t}: tilt {tilt}");
        }
    }
}
