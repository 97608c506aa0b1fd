use magstand_sim::Scenario;

use magstand_sim::replay::Trace;

use super::{Context, Effect, first_order_lag};
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
        "The field follows the current through a first-order lag: behind each command while \
         the rotors spin up and down, or, on a flight with its current logged, behind the \
         measured current (eddy currents in nearby metal, a filtered current sensor)."
    }
    fn parameters(&self) -> &'static [&'static str] {
        SpinUp::NAMES
    }
    fn search(&self, _ctx: &Context) -> Vec<Search> {
        vec![Search {
            name: "spinup_tau_s",
            unit: "s",
            lo: 0.001,
            hi: 3.0,
            log: true,
            points: 15,
        }]
    }
    fn stand_constant(&self, ctx: &Context) -> Option<(&'static str, f64)> {
        // Behind a measured current the spin-up is already in the measurement: a lag of the
        // field behind it is physics of its own, not the stand's constant.
        (!ctx.follow_recorded_current)
            .then_some(("motors.spinup_tau_s", ctx.nominal.motors.spinup_tau_s))
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
    fn apply(&self, ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if ctx.follow_recorded_current {
            return;
        }
        if let Some(p) = SpinUp::from_slice(theta) {
            s.motors.spinup_tau_s = p.spinup_tau_s;
        }
    }
    fn regressors(&self, ctx: &Context, trace: &Trace, theta: &[f64]) -> Vec<(String, Vec<f64>)> {
        if !ctx.follow_recorded_current {
            return Vec::new();
        }
        let Some(p) = SpinUp::from_slice(theta) else {
            return Vec::new();
        };
        // The lag's departure from the measured current, from the first row's current on.
        let first = trace.total_a.first().copied().unwrap_or(0.0);
        let change: Vec<f64> = trace.total_a.iter().map(|a| a - first).collect();
        let lagged = first_order_lag(&trace.t_s, &change, p.spinup_tau_s);
        let behind = lagged.iter().zip(&change).map(|(l, c)| l - c).collect();
        vec![("lag_behind_current_a".into(), behind)]
    }
}
