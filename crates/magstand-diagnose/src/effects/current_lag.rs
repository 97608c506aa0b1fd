use magstand_sim::Scenario;

use super::{Context, Effect};
use crate::optimize::Search;

/// Motor current follows a command step through a first-order lag (spin-up) other than the
/// nominal one.
pub struct CurrentLag;

impl Effect for CurrentLag {
    fn name(&self) -> &'static str {
        "current_lag"
    }
    fn explanation(&self) -> &'static str {
        "The rotors take time to spin up and down, so motor current, and the field it makes, \
         follows each command step through a first-order lag."
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
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        s.motors.spinup_tau_s = theta[0];
    }
}
