use magstand_sim::Scenario;

use super::{Context, Effect};
use crate::optimize::Search;

/// The ESCs start the motors at a command other than the nominal one.
pub struct DeadZone;

nonlinear_params! {
    /// Where the ESCs start driving the motors.
    Start {
        /// Command below which no motor turns, 0..1.
        dead_zone,
    }
}

impl Effect for DeadZone {
    fn name(&self) -> &'static str {
        "dead_zone"
    }
    fn explanation(&self) -> &'static str {
        "The ESCs start driving the motors at a different command than the simulation assumes, \
         so current, and the field, begins at another throttle."
    }
    fn parameters(&self) -> &'static [&'static str] {
        Start::NAMES
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
    fn stand_constant(&self, ctx: &Context) -> Option<(&'static str, f64)> {
        Some(("motors.dead_zone", ctx.nominal.motors.dead_zone))
    }
    fn inseparable_from_stated(&self, ctx: &Context, stated: f64, fitted: f64) -> Option<String> {
        // A dead zone is which commands drive the motors. Two of them differ in the rows
        // whose command lies between them (driven under one, not the other); where none
        // does, they differ only in how a command maps to speed above both, which the
        // current law's calibrated shape takes up as well: the data cannot reject the
        // statement for the dead zone itself.
        let (lo, hi) = (stated.min(fitted), stated.max(fitted));
        let between = |motor: &Vec<f64>| motor.iter().any(|&c| c > lo && c <= hi);
        (!ctx.rec.thr.iter().any(between)).then(|| {
            "no logged command lies between the two, so they differ only in how a command maps \
             to speed above both, which the calibrated current law takes up as well"
                .to_string()
        })
    }
    fn rows_telling_from_stated(
        &self,
        ctx: &Context,
        stated: f64,
        fitted: f64,
    ) -> Option<(Vec<bool>, String)> {
        // Under a dead zone above the stated one, the motors commanded between the two draw
        // the armed motors' idle current, a coefficient of its own (`armed_in_dead_zone`)
        // that those rows alone then determine: the fit there improves by a free offset
        // whatever the stand, wherever the law near its start misfits (a supply or a current
        // law unlike the nominal one). Those rows cannot testify; what only a higher dead zone
        // does is map the commands above it to other speeds, where every coefficient is
        // shared. (A dead zone below the stated one turns rotors the statement holds still:
        // any row may show it. Without the armed motors' column, as in flight, the rows
        // between have no coefficient of their own and testify like any other.)
        (fitted > stated && ctx.armed_current).then(|| {
            let above = (0..ctx.rec.len())
                .map(|r| ctx.rec.thr.iter().any(|motor| motor[r] > fitted))
                .collect();
            (
                above,
                format!(
                    "its prediction changed significantly only at rows where no motor is \
                     commanded above the fitted dead zone ({fitted:.3}); there the motors \
                     commanded between it and the stated one draw the armed motors' idle \
                     current, whose own coefficient those rows then fit freely. A dead zone \
                     above the stated one also maps the commands above it to other speeds, and \
                     the prediction there did not change significantly"
                ),
            )
        })
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if let Some(p) = Start::from_slice(theta) {
            s.motors.dead_zone = p.dead_zone;
        }
    }
}
