use magstand_sim::Scenario;
use magstand_sim::replay::Trace;

use super::{Context, Effect, EffectFit, Param};
use crate::optimize::Search;

/// Magnetized steel near the sensor: the field differs going up and coming down.
pub struct Hysteresis;

nonlinear_params! {
    /// The play operator's half-width.
    Play {
        /// Half-width, A of supply current.
        play_a,
    }
}

impl Effect for Hysteresis {
    fn name(&self) -> &'static str {
        "hysteresis"
    }
    fn explanation(&self) -> &'static str {
        "Steel near the sensor is magnetized by the current's field and keeps part of it, so \
         the disturbance going up in throttle differs from the one coming down."
    }
    fn parameters(&self) -> &'static [&'static str] {
        Play::NAMES
    }
    fn search(&self, ctx: &Context) -> Vec<Search> {
        let max_a = largest_current_a(ctx).max(1.0);
        vec![Search {
            name: "play_a",
            unit: "A",
            // A play of a few amperes on a stand drawing 70 A is still a loop a sensor sees.
            lo: 0.01 * max_a,
            hi: 0.5 * max_a,
            log: true,
            points: 17,
        }]
    }
    fn follows_the_current_law(&self, _ctx: &Context) -> bool {
        true
    }
    fn apply(&self, _ctx: &Context, s: &mut Scenario, _theta: &[f64]) {
        // The play operator's output is the regressor, computed from the replayed current in
        // `regressors`; the field comes from its coefficient. The play is left out of the
        // replayed scenario, so every play searched shares one replay of the motors.
        s.hysteresis.enabled = false;
    }
    fn regressors(
        &self,
        ctx: &Context,
        trace: &Trace,
        _law: &[(&str, &[f64])],
        theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        let Some(p) = Play::from_slice(theta) else {
            return Vec::new();
        };
        // The stand's hysteresis module's play operator, on the same current, row by row
        // from rest (`magstand_sim::hysteresis`).
        let mut out = 0.0;
        let mut play: Vec<f64> = super::law_current(ctx, trace)
            .iter()
            .map(|&a| {
                out = magstand_sim::hysteresis::play(out, a, p.play_a);
                out
            })
            .collect();
        // A nominal current is a smooth function of the rotor speeds, which the baseline
        // columns already follow; a measured one is not, so only the play's departure from it
        // is the hysteresis.
        if ctx.follow_recorded_current {
            for (p, a) in play.iter_mut().zip(&trace.total_a) {
                *p -= a;
            }
        }
        vec![("play_a".into(), play)]
    }
    fn switch_on(&self, ctx: &Context, s: &mut Scenario, f: &EffectFit) -> Vec<Param> {
        let (Some(play), Some(sd)) = (Play::from_slice(f.theta), Play::from_slice(f.theta_sd))
        else {
            return Vec::new();
        };
        s.hysteresis.enabled = true;
        s.hysteresis.play_a = play.play_a;
        s.hysteresis.gain_ut_per_a = f.coef[0];
        let mut p = vec![Param::new("play_a", play.play_a, sd.play_a, "A")];
        p.extend(Param::axes(
            "gain_ut_per_a",
            f.coef[0],
            f.coef_sd[0],
            "µT/A",
        ));
        if !super::amperes_are_nominal(ctx) {
            return p;
        }
        // The field gives the current's shape, not its amperes: those are the nominal motor's,
        // a default, and no sd in them holds the stand's. The play as a share of the largest
        // current the recording draws does not rest on that scale, only on the law's shape
        // (on the independent generator's three stands, whose play is 3 A of about 66 A, the
        // amperes came out 2.6 to 5.8 +- 0.03 to 0.1, the share within a fifth of the truth).
        let full_a = largest_current_a(ctx);
        let basis = format!(
            "the current as the field calibrates it: its amperes are the nominal motor's, whose \
             scale nobody stated (log bat_a, or state the motor's kv, winding resistance and \
             torque coefficient, for the stand's own), and its shape the calibrated current \
             law's, so no sd (the curvature's, in those amperes, is {}); play_fraction, the play \
             over the largest current the recording draws ({full_a:.2} A in those amperes), \
             rests on the shape only",
            sd.play_a.map_or("none".into(), |sd| format!("{sd:.3}"))
        );
        let mut p: Vec<Param> = p
            .into_iter()
            .map(|q| q.without_sd_resting_on(&basis))
            .collect();
        if full_a > 0.0 {
            let share = Param::new(
                "play_fraction",
                play.play_a / full_a,
                None,
                "of the largest current",
            );
            p.insert(1, share.resting_on(&basis));
        }
        p
    }
}

/// The largest current the recording draws, as the play sees it ([`super::law_current`] of the
/// nominal replay), A: what the play's search range and its share are taken of.
fn largest_current_a(ctx: &Context) -> f64 {
    super::law_current(ctx, ctx.nominal_trace)
        .iter()
        .cloned()
        .fold(0.0, f64::max)
}
