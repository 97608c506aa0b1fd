//! Ferromagnetic hysteresis near the sensor, modelled as a play (backlash) operator on the
//! supply current: the magnetization of nearby steel follows the current only after the current
//! has moved by more than the play width, so the disturbance going up differs from the one
//! coming down. Off by default.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use magstand_core::Vec3;

/// Hysteresis parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HysteresisParams {
    /// Switch.
    pub enabled: bool,
    /// Half-width of the play, A of supply current.
    pub play_a: f64,
    /// Field per ampere of play-operator output, µT/A (x, y, z).
    pub gain_ut_per_a: [f64; 3],
}

impl Default for HysteresisParams {
    fn default() -> Self {
        Self {
            enabled: false,
            play_a: 6.0,
            gain_ut_per_a: [0.03, 0.04, -0.06],
        }
    }
}

impl crate::stand_module::ModuleParams for HysteresisParams {
    fn table(&self) -> &'static str {
        "hysteresis"
    }
    /// Keys without the table's name: the checker adds it.
    fn check(&self, c: &Checker) -> Result<(), SimError> {
        c.range("play_a", self.play_a, 0.0, 1000.0)?;
        c.within3(
            "gain_ut_per_a",
            self.gain_ut_per_a,
            crate::MAX_GAIN_UT_PER_A,
        )
    }
    fn build(&self) -> Box<dyn crate::stand_module::StandModule> {
        Box::new(HysteresisModule::new(self))
    }
    fn adds_field(&self) -> bool {
        self.enabled
    }
}

/// The play operator: output stays put until the input leaves `[y - w, y + w]`.
pub fn play(previous: f64, input: f64, width: f64) -> f64 {
    previous.clamp(input - width, input + width)
}

/// Play-operator state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HysteresisState {
    /// Operator output, A.
    pub output_a: f64,
}

impl HysteresisState {
    /// Feeds the current and returns the field, µT (zero when disabled).
    pub fn step(&mut self, p: &HysteresisParams, current_a: f64) -> Vec3 {
        self.output_a = play(self.output_a, current_a, p.play_a);
        if p.enabled {
            Vec3::from(p.gain_ut_per_a) * self.output_a
        } else {
            Vec3::zeros()
        }
    }
}

/// The trace column of the play operator's output, A.
pub const PLAY_A: &str = "play_a";

/// Hysteresis of nearby steel as a stand module: a play operator fed the supply current at
/// each sample, its field seen through the sensor's soft iron.
#[derive(Debug, Clone)]
pub struct HysteresisModule {
    params: HysteresisParams,
    state: HysteresisState,
}

impl HysteresisModule {
    /// With the operator at zero.
    pub fn new(p: &HysteresisParams) -> Self {
        Self {
            params: p.clone(),
            state: HysteresisState::default(),
        }
    }
}

impl crate::stand_module::StandModule for HysteresisModule {
    fn column(&self) -> &'static str {
        PLAY_A
    }
    fn field_ut(&mut self, e: crate::stand_module::Electrical) -> Vec3 {
        self.state.step(&self.params, e.total_a)
    }
    fn step(&mut self, _: crate::stand_module::Electrical, _: f64) {}
    fn state(&self) -> f64 {
        self.state.output_a
    }
    fn boxed_clone(&self) -> Box<dyn crate::stand_module::StandModule> {
        Box::new(self.clone())
    }
    fn through_soft_iron(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn play_operator_lags_by_its_width_in_both_directions() {
        let mut y = 0.0;
        let mut up = Vec::new();
        for i in 0..=20 {
            y = play(y, i as f64, 3.0);
            up.push(y);
        }
        assert_eq!(up[2], 0.0, "inside the play nothing moves");
        assert_eq!(up[20], 17.0, "going up the output trails by the width");
        for i in (10..=20).rev() {
            y = play(y, i as f64, 3.0);
        }
        assert_eq!(y, 13.0, "coming down it leads by the width");
    }

    #[test]
    fn up_and_down_branches_differ_by_twice_the_width() {
        let p = HysteresisParams {
            enabled: true,
            play_a: 2.0,
            gain_ut_per_a: [1.0, 0.0, 0.0],
        };
        let mut s = HysteresisState::default();
        for i in 0..=40 {
            s.step(&p, i as f64);
        }
        let at_20_down = {
            let mut b = Vec3::zeros();
            for i in (20..=40).rev() {
                b = s.step(&p, i as f64);
            }
            b
        };
        let mut fresh = HysteresisState::default();
        let mut at_20_up = Vec3::zeros();
        for i in 0..=20 {
            at_20_up = fresh.step(&p, i as f64);
        }
        assert!(
            (at_20_down.x - at_20_up.x - 4.0).abs() < 1e-12,
            "{at_20_down} {at_20_up}"
        );
    }
}
