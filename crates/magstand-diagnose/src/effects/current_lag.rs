use magstand_sim::Scenario;

use magstand_sim::replay::Trace;

use super::{Context, Effect, EffectFit, Param, first_order_lag, searched_params};
use crate::optimize::Search;

/// The slowest spin-up time constant a motor and propeller have, s. Electric multirotor
/// motors reach speed in tens of milliseconds; even large (30-inch) propellers stay near
/// 0.2 s. A current lag calibrated slower than this is not the rotor's inertia but something
/// else: a filtered current, a slow ESC ramp, a supply that cannot follow.
pub const MAX_SPINUP_S: f64 = 0.3;

/// The fastest spin-up searched, s: a small motor with a light propeller.
pub(crate) const FASTEST_SPINUP_S: f64 = 0.001;

/// Motor current follows a command step through a first-order lag (spin-up) other than the
/// nominal one.
///
/// The catalog's form keeps a stated spin-up behind a lag slower than any spin-up. Where the
/// scenario states one, a richer form ([`Effect::richer`]) has the slow lag replace it too,
/// kept only where that lowers the held-out error significantly: a slow lag is tested against
/// the stated spin-up, and the data decide whether that spin-up is there behind it.
pub struct CurrentLag {
    form: LagForm,
}

/// The forms of [`CurrentLag`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum LagForm {
    /// The catalog's: a lag slower than any spin-up keeps a stated spin-up behind it.
    StatedSpinupBehind,
    /// A lag slower than any spin-up is all the lag there is: a stated spin-up goes too.
    WithoutStatedSpinup,
}

impl CurrentLag {
    /// The catalog's form.
    pub const NOMINAL: CurrentLag = CurrentLag {
        form: LagForm::StatedSpinupBehind,
    };
}

/// The richer form, and its name in a model file.
static WITHOUT_STATED_SPINUP: (CurrentLag, &str) = (
    CurrentLag {
        form: LagForm::WithoutStatedSpinup,
    },
    "without_stated_spinup",
);

/// The richer forms of [`CurrentLag`], for a model file that names one.
pub(crate) fn richer_forms() -> impl Iterator<Item = &'static dyn Effect> {
    std::iter::once(&WITHOUT_STATED_SPINUP.0 as &dyn Effect)
}

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
         the rotors spin up and down (a lag slower than any spin-up lags the currents' field \
         itself), or, on a flight with its current logged, behind the measured current (eddy \
         currents in nearby metal, a filtered current sensor)."
    }
    fn parameters(&self) -> &'static [&'static str] {
        SpinUp::NAMES
    }
    fn variant(&self) -> Option<&'static str> {
        (self.form == LagForm::WithoutStatedSpinup).then_some(WITHOUT_STATED_SPINUP.1)
    }
    fn richer(&self, ctx: &Context) -> Vec<&'static dyn Effect> {
        // Only beside a stated spin-up slower than the fastest: elsewhere the two forms are
        // the same physics. (Against a stated spin-up of 0.06 s, the generator's 0.5 s lag
        // with no spin-up kept the 0.06 s in series, and its misfit was named a -0.06 s
        // `time_offset` and `unexplained`.)
        let offered = self.form == LagForm::StatedSpinupBehind
            && !ctx.follow_recorded_current
            && ctx.nominal.states("motors.spinup_tau_s")
            && ctx.nominal.motors.spinup_tau_s > FASTEST_SPINUP_S;
        if offered {
            richer_forms().collect()
        } else {
            Vec::new()
        }
    }
    fn search(&self, _ctx: &Context) -> Vec<Search> {
        vec![Search {
            name: "spinup_tau_s",
            unit: "s",
            lo: FASTEST_SPINUP_S,
            hi: 3.0,
            log: true,
            points: 15,
        }]
    }
    fn stand_constant(&self, ctx: &Context) -> Option<(&'static str, f64)> {
        // Behind a measured current the spin-up is already in the measurement: a lag of the
        // field behind it is physics of its own, not the stand's constant.
        if ctx.follow_recorded_current {
            return None;
        }
        // A lag of the currents the scenario states (`motors.current_lag_s`, as an augmented
        // scenario of a slow `current_lag` writes it) is the lag this effect re-fits: its fit
        // replaces the statement (see `apply`), so a recording without that lag rejects it.
        // Tested against the spin-up instead, a stated 0.5 s lag the data did not have could
        // only be added to, and its misfit went to a delay and `unexplained`.
        let motors = &ctx.nominal.motors;
        Some(
            if ctx.nominal.states("motors.current_lag_s") && motors.current_lag_s > 0.0 {
                ("motors.current_lag_s", motors.current_lag_s)
            } else {
                ("motors.spinup_tau_s", motors.spinup_tau_s)
            },
        )
    }
    fn lower_edge_is_a_limit(&self, parameter: &str) -> Option<&'static str> {
        // A spin-up at the fastest searched is a rotor that follows each command within what
        // the data resolve: a millisecond less changes no row. Against a stated spin-up the
        // data reject, that is the finding (the stated one too slow), not an undetermined lag.
        (parameter == SpinUp::NAMES[0]).then_some(
            "the rotors follow each command faster than the data resolve: the spin-up is this \
             or less",
        )
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
        // A lag slower than any spin-up is not the rotors': the replay keeps a stated spin-up
        // and the field follows the currents through the lag (`field_lag_s`).
        let Some(p) = SpinUp::from_slice(theta) else {
            return;
        };
        if p.spinup_tau_s <= MAX_SPINUP_S {
            s.motors.spinup_tau_s = p.spinup_tau_s;
            // The one lag the fit has is all the current lags: a stated lag of the currents
            // is replaced, not kept beside it (0 already where none is stated).
            s.motors.current_lag_s = 0.0;
        } else if self.form == LagForm::WithoutStatedSpinup
            || !ctx.nominal.states("motors.spinup_tau_s")
        {
            // Behind a lag this slow an unstated spin-up is not kept at the nominal value: the
            // lag, calibrated from the data, takes up whatever spin-up the rotors have (the two
            // in series are the slower one, a few tens of milliseconds later), where a nominal
            // one kept beside it would add a lag the data may not have.
            s.motors.spinup_tau_s = FASTEST_SPINUP_S;
        }
    }
    fn field_lag_s(&self, ctx: &Context, theta: &[f64]) -> Option<f64> {
        // What lags beyond a spin-up (a filtered current, a slow ESC ramp, a supply that
        // cannot follow) lags the current itself, and the field linear in it: the current
        // of a lagged speed is another curve (the current law is not linear in the speed).
        let tau_s = SpinUp::from_slice(theta)?.spinup_tau_s;
        (!ctx.follow_recorded_current && tau_s > MAX_SPINUP_S).then_some(tau_s)
    }
    fn switch_on(&self, ctx: &Context, scenario: &mut Scenario, fitted: &EffectFit) -> Vec<Param> {
        // As the fits had it: a spin-up as a spin-up; a lag slower than any spin-up as the
        // motors' current lagging the current of their speed (`motors.current_lag_s`, which
        // the simulator and the replay run), beside the spin-up the fits kept.
        self.apply(ctx, scenario, fitted.theta);
        if let Some(tau_s) = self.field_lag_s(ctx, fitted.theta) {
            scenario.motors.current_lag_s = tau_s;
        }
        searched_params(&self.search(ctx), fitted)
    }
    fn regressors(
        &self,
        ctx: &Context,
        trace: &Trace,
        _law: &[(&str, &[f64])],
        theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
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
