use magstand_sim::Scenario;

use super::{Context, Effect};
use crate::optimize::Search;

/// The ESCs start the motors at a command other than the nominal one.
pub struct DeadZone;

impl Effect for DeadZone {
    fn name(&self) -> &'static str {
        "dead_zone"
    }
    fn explanation(&self) -> &'static str {
        "The ESCs start driving the motors at a different command than the simulation assumes, \
         so current, and the field, begins at another throttle."
    }
    fn search(&self, _ctx: &Context) -> Vec<Search> {
        vec![Search {
            name: "dead_zone",
            unit: "command (0..1)",
            lo: 0.0,
            hi: 0.6,
            log: false,
            points: 31,
        }]
    }
    fn stand_constant(&self, s: &Scenario) -> Option<(&'static str, f64)> {
        Some(("motors.dead_zone", s.motors.dead_zone))
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        s.motors.dead_zone = theta[0];
    }
}
