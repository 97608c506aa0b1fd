use magstand_sim::Scenario;

use super::{Context, Effect, EffectFit, Param, searched_params};
use crate::optimize::Search;

/// The magnetometer stream is logged late against the command stream.
pub struct TimeOffset;

nonlinear_params! {
    /// The magnetometer stream's lateness.
    Delay {
        /// Delay of the magnetometer's stamps behind the commands', s.
        mag_delay_s,
    }
}

impl Effect for TimeOffset {
    fn name(&self) -> &'static str {
        "time_offset"
    }
    fn explanation(&self) -> &'static str {
        "The magnetometer samples are time-stamped late against the motor commands (logging \
         latency), so every change in the field appears a fixed time after its cause."
    }
    fn applies(&self, ctx: &Context) -> bool {
        // A flight's baseline calibrates the delay (`flight.mag_delay_s`).
        !ctx.flight
    }
    fn mimics_calibration(&self) -> bool {
        // Every change in the field a fixed time late: a spin-up calibrated at the delay
        // takes most of that misfit.
        true
    }
    fn has_a_basin_per_interval(&self) -> bool {
        // A delay's chi-square has a kink at each sample interval (where a command change
        // passes a row): at 200 Hz a late magnetometer kept at 0.285 s, a local minimum 0.012
        // s from the 0.296 s the whole range finds, once the spin-up was calibrated beside it.
        true
    }
    fn parameters(&self) -> &'static [&'static str] {
        Delay::NAMES
    }
    fn search(&self, ctx: &Context) -> Vec<Search> {
        // From one sample interval (shorter delays cannot be told from where in the interval
        // a logged command changed, which the baseline calibrates) to half a second, in steps
        // finer than one sample.
        let dt = ctx.rec.typical_interval_s();
        Vec::from([Search {
            name: "mag_delay_s",
            unit: "s",
            lo: dt.min(0.25),
            hi: 0.5,
            log: false,
            points: ((0.5 / dt).ceil() as usize + 1).clamp(11, 51),
        }])
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if let Some(p) = Delay::from_slice(theta) {
            s.logging.mag_delay_s = p.mag_delay_s;
        }
    }
    fn switch_on(&self, ctx: &Context, scenario: &mut Scenario, fitted: &EffectFit) -> Vec<Param> {
        self.apply(ctx, scenario, fitted.theta);
        // A log does not say whether a logged command acted from its own row on or had
        // already acted when it was logged (the lead the baseline calibrates on delayed
        // data takes either end): the two readings of one recording differ in the delay by
        // one sample interval. The reported uncertainty holds that ambiguity, a uniform
        // spread of one interval either way, beside the fit's own.
        let dt = ctx.rec.typical_interval_s();
        let mut params = searched_params(&self.search(ctx), fitted);
        for p in &mut params {
            p.sd = p.sd.map(|sd| (sd * sd + dt * dt / 3.0).sqrt());
        }
        params
    }
}
