//! Board temperature and the magnetometer offset drift it causes.
//!
//! The board heats with the electrical power the stand draws and cools towards ambient with a
//! time constant of minutes: `dT/dt = (T_amb + k P - T) / tau`. The sensor offset moves by a
//! fixed vector per degree of rise. Off by default: it is one of the effects the mismatch
//! diagnosis must find.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use crate::lag::LagFactor;
use magstand_core::Vec3;

/// Thermal parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ThermalParams {
    /// Switch for the offset drift (the temperature itself is always simulated).
    pub enabled: bool,
    /// Ambient and starting temperature, °C.
    pub ambient_c: f64,
    /// Time constant of the board, s.
    pub tau_s: f64,
    /// Steady-state temperature rise per watt drawn, °C/W.
    pub rise_c_per_w: f64,
    /// Offset drift per degree of rise, µT/°C (x, y, z).
    pub offset_ut_per_c: [f64; 3],
}

impl Default for ThermalParams {
    fn default() -> Self {
        Self {
            enabled: false,
            ambient_c: 20.0,
            tau_s: 120.0,
            rise_c_per_w: 0.02,
            offset_ut_per_c: [0.08, -0.05, 0.12],
        }
    }
}

impl crate::stand_module::ModuleParams for ThermalParams {
    fn table(&self) -> &'static str {
        "thermal"
    }
    /// Keys without the table's name: the checker adds it.
    fn check(&self, c: &Checker) -> Result<(), SimError> {
        c.range("ambient_c", self.ambient_c, -60.0, 100.0)?;
        c.positive("tau_s", self.tau_s)?;
        c.range("rise_c_per_w", self.rise_c_per_w, 0.0, 10.0)?;
        c.within3(
            "offset_ut_per_c",
            self.offset_ut_per_c,
            crate::MAX_GAIN_UT_PER_A,
        )
    }
    fn build(&self) -> Box<dyn crate::stand_module::StandModule> {
        Box::new(ThermalModule::new(self))
    }
    fn adds_field(&self) -> bool {
        self.enabled
    }
}

impl ThermalParams {
    /// Offset at temperature `temp_c`, µT (zero when disabled).
    pub fn offset_ut(&self, temp_c: f64) -> Vec3 {
        if self.enabled {
            Vec3::from(self.offset_ut_per_c) * (temp_c - self.ambient_c)
        } else {
            Vec3::zeros()
        }
    }
}

/// Board temperature state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalState {
    /// Temperature, °C.
    pub temp_c: f64,
}

impl ThermalState {
    /// Starts at ambient.
    pub fn new(p: &ThermalParams) -> Self {
        Self {
            temp_c: p.ambient_c,
        }
    }

    /// Advances by `dt_s` while `power_w` is drawn (exact first-order step).
    pub fn step(&mut self, p: &ThermalParams, power_w: f64, dt_s: f64) {
        self.step_by(p, power_w, crate::lag::lag_factor(dt_s, p.tau_s));
    }

    /// [`step`](Self::step) with its factor `1 - exp(-dt_s / tau_s)` given.
    fn step_by(&mut self, p: &ThermalParams, power_w: f64, factor: f64) {
        let target = p.ambient_c + p.rise_c_per_w * power_w;
        self.temp_c += (target - self.temp_c) * factor;
    }
}

/// The trace column of the board temperature, °C.
pub const TEMP_C: &str = "temp_c";

/// Board heating as a stand module: heats with the electrical power, adds the sensor's offset
/// drift (inside the sensor, so not through its soft iron).
#[derive(Debug, Clone)]
pub struct ThermalModule {
    params: ThermalParams,
    state: ThermalState,
    /// The heating's lag factor, kept for the step length (a simulation steps by one length
    /// a thousand times a second).
    factor: LagFactor,
}

impl ThermalModule {
    /// At ambient temperature.
    pub fn new(p: &ThermalParams) -> Self {
        Self {
            params: p.clone(),
            state: ThermalState::new(p),
            factor: LagFactor::new(p.tau_s),
        }
    }
}

impl crate::stand_module::StandModule for ThermalModule {
    fn column(&self) -> &'static str {
        TEMP_C
    }
    fn field_ut(&mut self, _: crate::stand_module::Electrical) -> Vec3 {
        self.params.offset_ut(self.state.temp_c)
    }
    fn step(&mut self, e: crate::stand_module::Electrical, dt_s: f64) {
        let factor = self.factor.of(dt_s);
        self.state
            .step_by(&self.params, e.voltage_v * e.total_a, factor);
    }
    fn state(&self) -> f64 {
        self.state.temp_c
    }
    fn boxed_clone(&self) -> Box<dyn crate::stand_module::StandModule> {
        Box::new(self.clone())
    }
    fn through_soft_iron(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heats_as_a_first_order_lag() {
        let p = ThermalParams {
            enabled: true,
            ..Default::default()
        };
        let mut s = ThermalState::new(&p);
        for _ in 0..1200 {
            s.step(&p, 500.0, 0.1); // one time constant at 500 W: 10 degC final rise
        }
        let expected = 20.0 + 10.0 * (1.0 - (-1.0f64).exp());
        assert!(
            (s.temp_c - expected).abs() < 1e-9,
            "{} vs {expected}",
            s.temp_c
        );
        let off = p.offset_ut(s.temp_c);
        assert!((off.z - 0.12 * (expected - 20.0)).abs() < 1e-9);
    }

    #[test]
    fn disabled_gives_no_offset() {
        assert_eq!(ThermalParams::default().offset_ut(80.0), Vec3::zeros());
    }
}
