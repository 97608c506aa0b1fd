use magstand_sim::Scenario;

use super::{Context, Effect};
use crate::optimize::Search;

/// The slowest spin-up time constant a motor and propeller have, s. Electric multirotor
/// motors reach speed in tens of milliseconds; even large (30-inch) propellers stay near
/// 0.2 s. A current lag calibrated slower than this is not the rotor's inertia but something
/// else: a filtered current, a slow ESC ramp, a supply that cannot follow.
pub const MAX_SPINUP_S: f64 = 0.3;

/// Motor current follows a command step through a first-order lag (spin-up) other than the
/// nominal one.
pub struct CurrentLag;

nonlinear_params! {
    /// The motors' spin-up.
    SpinUp {
        /// First-order time constant of the current after a command step, s.
        spinup_tau_s,
    }
}

impl Effect for CurrentLag {
    fn name(&self) -> &'static str {
        "current_lag"
    }
    fn explanation(&self) -> &'static str {
        "The rotors take time to spin up and down, so motor current, and the field it makes, \
         follows each command step through a first-order lag."
    }
    fn parameters(&self) -> &'static [&'static str] {
        SpinUp::NAMES
    }
    fn search(&self, _ctx: &Context) -> Vec<Search> {
        vec![Search {
            name: "spinup_tau_s",
            unit: "s",
            lo: 0.005,
            hi: 3.0,
            log: true,
            points: 15,
        }]
    }
    fn stand_constant(&self, s: &Scenario) -> Option<(&'static str, f64)> {
        Some(("motors.spinup_tau_s", s.motors.spinup_tau_s))
    }
    fn beyond_calibration(&self, theta: &[f64]) -> Option<String> {
        let tau_s = SpinUp::from_slice(theta)?.spinup_tau_s;
        (tau_s > MAX_SPINUP_S).then(|| {
            format!(
                "The calibrated lag, {:.3} s, is slower than any motor spin-up ({MAX_SPINUP_S} s at \
                 most, for the largest propellers): something other than the rotors' inertia \
                 delays the current (a filtered current, a slow ESC ramp, the supply).",
                tau_s
            )
        })
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if let Some(p) = SpinUp::from_slice(theta) {
            s.motors.spinup_tau_s = p.spinup_tau_s;
        }
    }
}
