use magstand_sim::Scenario;

use super::{Context, Effect, EffectFit, Param, searched_params};
use crate::optimize::Search;

/// The magnetometer stream is logged late against the command stream, or early (the commands
/// logged late).
pub struct TimeOffset;

nonlinear_params! {
    /// The magnetometer stream's lateness.
    Delay {
        /// Delay of the magnetometer's stamps behind the commands', s: negative where the
        /// commands' stamps are the late ones.
        mag_delay_s,
    }
}

/// Longest offset searched either way, s.
const MAX_OFFSET_S: f64 = 0.5;

impl Effect for TimeOffset {
    fn name(&self) -> &'static str {
        "time_offset"
    }
    fn explanation(&self) -> &'static str {
        "The magnetometer samples are time-stamped late against the motor commands (logging \
         latency), so every change in the field appears a fixed time after its cause; where \
         mag_delay_s is negative, the commands are the stream stamped late, and every change in \
         the field appears that long before the logged command that caused it."
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
        // Half a second either way, in steps of about one sample: a logger may stamp either
        // stream late. (Within an interval of zero, an offset cannot be told from where in the
        // interval a logged command changed, which the baseline calibrates: its gain there is
        // none.) The chi-square has a kink at each sample interval: on a grid two intervals
        // apart, the default stand at 30 Hz lost two late magnetometers' verdicts (an extra
        // `unexplained`, once with the heating beside it missed).
        let dt = ctx.rec.typical_interval_s();
        Vec::from([Search {
            name: "mag_delay_s",
            unit: "s",
            lo: -MAX_OFFSET_S,
            hi: MAX_OFFSET_S,
            log: false,
            points: ((2.0 * MAX_OFFSET_S / dt).ceil() as usize + 1).clamp(21, 101),
        }])
    }
    fn undetermined_at(&self, ctx: &Context, theta: &[f64]) -> Option<String> {
        // Within an interval of the nominal delay (none, unless the scenario states one), the
        // command lead the baseline calibrates takes the difference up. A delay the scenario
        // states that the data put far from it is a finding, wherever it lies: a stated
        // 0.2 s late magnetometer refitted at 0 was refused as "within an interval of zero",
        // and the statement's misfit named `unexplained`.
        let dt = ctx.rec.typical_interval_s();
        let p = Delay::from_slice(theta)?;
        let nominal = ctx.nominal.logging.read_delay_s();
        ((p.mag_delay_s - nominal).abs() < dt).then(|| {
            let of = if nominal == 0.0 {
                "zero".to_string()
            } else {
                format!("the scenario's {nominal} s")
            };
            format!(
                "its mag_delay_s = {:.4} lies within one sample interval ({dt:.4} s) of {of}, \
                 where a delay cannot be told from where in the interval a logged command \
                 changed (which the baseline calibrates), so the data do not determine it",
                p.mag_delay_s
            )
        })
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if let Some(p) = Delay::from_slice(theta) {
            // A negative offset is the commands' delay: the simulator logs them late.
            s.logging.set_read_delay_s(p.mag_delay_s);
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
        // Beside a delay the scenario states, the statement the data rejected.
        let nominal = &ctx.nominal;
        if nominal.states("logging.mag_delay_s") || nominal.states("logging.command_delay_s") {
            let stated = nominal.logging.read_delay_s();
            params.push(Param::new("stated_mag_delay_s", stated, None, "s"));
        }
        params
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::TestStand;

    /// The delay is searched half a second either way; within one sample interval of zero
    /// (0.04 s here) it is no delay the data determine, on either side, and a negative one is
    /// switched on as the commands' delay.
    #[test]
    fn a_delay_within_an_interval_of_zero_is_undetermined_and_a_negative_one_is_the_commands() {
        let stand = TestStand::drifting_stair(500);
        let ctx = stand.context();
        let [search] = TimeOffset.search(&ctx).try_into().expect("one search");
        assert_eq!((search.lo, search.hi), (-0.5, 0.5), "{search:?}");
        for d in [-0.039, 0.0, 0.02, 0.039] {
            assert!(TimeOffset.undetermined_at(&ctx, &[d]).is_some(), "{d} s");
        }
        for d in [-0.3, -0.041, 0.041, 0.3] {
            assert!(TimeOffset.undetermined_at(&ctx, &[d]).is_none(), "{d} s");
        }
        let mut s = ctx.nominal.clone();
        TimeOffset.apply(&ctx, &mut s, &[-0.2]);
        assert_eq!(
            (s.logging.mag_delay_s, s.logging.command_delay_s),
            (0.0, 0.2)
        );
        TimeOffset.apply(&ctx, &mut s, &[0.3]);
        assert_eq!(
            (s.logging.mag_delay_s, s.logging.command_delay_s),
            (0.3, 0.0)
        );
        assert_eq!(s.logging.read_delay_s(), 0.3);
    }
}
