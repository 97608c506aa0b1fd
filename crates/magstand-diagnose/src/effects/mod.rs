//! The catalog of candidate physics. Each effect is one file with one type implementing
//! [`Effect`]: its name and physics, the nonlinear parameters it searches, how it changes the
//! replayed physics, the regressors it adds, and how it switches the matching simulator module
//! on with the fitted values.
use magstand_core::Recording;
use magstand_sim::Scenario;
use magstand_sim::replay::Trace;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

use crate::optimize::Search;
use magstand_core::held_out::Split;

/// Declares an effect's nonlinear parameters as a struct with one named field per searched
/// parameter, in the order its search holds them, so the effect reads `p.play_a` rather than
/// `theta[0]`. The same struct names their uncertainties (`Play::<Option<f64>>`).
macro_rules! nonlinear_params {
    ($(#[$doc:meta])* $name:ident { $($(#[$fdoc:meta])* $field:ident),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub(crate) struct $name<T = f64> {
            $($(#[$fdoc])* pub(crate) $field: T,)+
        }

        impl $name {
            /// The parameters' names, in the order the search holds them.
            pub(crate) const NAMES: &'static [&'static str] = &[$(stringify!($field)),+];
        }

        impl<T: Copy> $name<T> {
            /// Named values from the optimiser's slice (values or their uncertainties), in
            /// search order; `None` unless the slice holds one value per parameter.
            pub(crate) fn from_slice(values: &[T]) -> Option<Self> {
                let mut it = values.iter().copied();
                let p = Self { $($field: it.next()?,)+ };
                it.next().is_none().then_some(p)
            }
        }
    };
}

mod battery_sag;
mod current_lag;
mod dead_zone;
mod hysteresis;
mod motor_asymmetry;
mod thermal_drift;
mod time_offset;

pub use battery_sag::BatterySag;
pub(crate) use current_lag::FASTEST_SPINUP_S;
pub use current_lag::{CurrentLag, MAX_SPINUP_S};
#[cfg(test)]
pub(crate) use dead_zone::DEAD_ZONE_SEARCH;
pub use dead_zone::DeadZone;
pub use hysteresis::Hysteresis;
pub use motor_asymmetry::MotorAsymmetry;
pub(crate) use motor_asymmetry::{calibrated_current_law, stand_current};
pub use thermal_drift::ThermalDrift;
pub use time_offset::TimeOffset;

/// What an effect sees of the problem.
pub struct Context<'a> {
    /// The recording diagnosed.
    pub rec: &'a Recording,
    /// The nominal physics (the scenario as given, or the default nominal stand).
    pub nominal: &'a Scenario,
    /// Identification and held-out rows.
    pub split: &'a Split,
    /// The nominal replay of the recording's commands.
    pub nominal_trace: &'a Trace,
    /// The recording's name, for messages.
    pub rec_origin: String,
    /// Where within the interval before a row its command change is taken to happen (0: at
    /// the previous sample, 1: at the row), calibrated with the baseline: logs differ in
    /// whether commands are stamped when issued or when sampled.
    pub command_lead: f64,
    /// Whether the recording is a flight, whose Earth field, offset and magnetometer delay
    /// the baseline already took out.
    pub flight: bool,
    /// Whether the replay follows the recording's logged supply voltage (`bat_v`) from the
    /// start, as the physics model does; the diagnosis instead names the battery's sag as an
    /// effect when the data demand it.
    pub follow_recorded_voltage: bool,
    /// Whether the replay's supply current is the recording's logged one (`bat_a`): on a
    /// flight, where the vehicle's motors and battery are not the nominal stand's, the
    /// measured current is the best account of the current the field follows, so the
    /// current-driven modules (hysteresis, heating) and the current lag follow it.
    pub follow_recorded_current: bool,
    /// Powers of speed in the baseline's current law (see `current_law_powers`).
    pub speed_powers: usize,
    /// Whether the baseline counts the motors commanded within their dead zone as a column
    /// of its own (see `Design::baseline`); a model file written before that column has none.
    pub armed_current: bool,
    /// The motors in groups the recording can tell apart (see [`motor_groups`]): per-motor
    /// physics is fitted per group.
    pub motor_groups: Vec<Vec<usize>>,
    /// Each motor's current as the baseline's calibrated law has it, which a per-motor term
    /// follows once it is named (see [`MotorCurrentLaw`](crate::augmented_model::MotorCurrentLaw));
    /// None: the nominal motor's current, on which such a term is named.
    pub motor_current_law: Option<crate::augmented_model::MotorCurrentLaw>,
    /// The stand's current as the baseline's calibrated law has it, which the hysteresis's
    /// play follows (set once the stand constants are calibrated, where the data tell the
    /// law's shape from the nominal motor's); None: the replayed current. A play acts on the
    /// current's value, so a current of another shape moves it at other commands.
    pub current_law: Option<crate::augmented_model::MotorCurrentLaw>,
    /// Replays already made of this recording, reused by the searches.
    pub(crate) replays: crate::pipeline::design::ReplayCache,
    /// Factors of the field's lags already made for this recording, reused by the searches.
    pub(crate) series_lags: crate::pipeline::design::SeriesLagCache,
}

impl<'a> Context<'a> {
    /// The same problem with the baseline's current law of `powers` powers of speed, with
    /// caches of its own (a design's columns depend on the law; its replays do not, but the
    /// caches keep only the latest few).
    pub(crate) fn with_speed_powers(&self, powers: usize) -> Context<'a> {
        Context {
            rec: self.rec,
            nominal: self.nominal,
            split: self.split,
            nominal_trace: self.nominal_trace,
            rec_origin: self.rec_origin.clone(),
            command_lead: self.command_lead,
            flight: self.flight,
            follow_recorded_voltage: self.follow_recorded_voltage,
            follow_recorded_current: self.follow_recorded_current,
            speed_powers: powers,
            armed_current: self.armed_current,
            motor_groups: self.motor_groups.clone(),
            motor_current_law: self.motor_current_law.clone(),
            current_law: self.current_law.clone(),
            replays: Default::default(),
            series_lags: Default::default(),
        }
    }
}

/// The motors of `thr` (one command column per motor) in groups that no row tells apart: the
/// motors of a group are commanded alike on every row, so a per-motor gain can be fitted only
/// for the group (a hexacopter whose attitude commands pair opposite motors). Groups are in
/// the order of their first motor; a single column for all motors is one motor's group.
pub fn motor_groups(thr: &[Vec<f64>]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (m, col) in thr.iter().enumerate() {
        let alike = |g: &&mut Vec<usize>| {
            thr[g[0]]
                .iter()
                .zip(col)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        };
        match groups.iter_mut().find(alike) {
            Some(g) => g.push(m),
            None => groups.push(vec![m]),
        }
    }
    groups
}

/// A fitted parameter with its unit and standard uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Name, with its unit suffix.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard uncertainty (None where the fit gives no curvature, e.g. at a range limit).
    pub sd: Option<f64>,
    /// Unit.
    pub unit: String,
    /// What the value rests on that nobody stated, where it is a model's constant rather
    /// than the stand's (the battery's capacity is the LiPo curve's scale); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub basis: Option<String>,
}

impl Param {
    /// A parameter.
    pub fn new(name: impl Into<String>, value: f64, sd: Option<f64>, unit: &str) -> Param {
        Param {
            name: name.into(),
            value,
            sd: sd.filter(|s| s.is_finite()),
            unit: unit.into(),
            basis: None,
        }
    }

    /// `name = value ± sd unit`, as the text summary and the report show it.
    pub fn shown(&self) -> String {
        format!(
            "{} = {} {}",
            self.name,
            crate::diagnosis::value_with_sd(self.value, self.sd),
            self.unit
        )
    }

    /// This parameter, resting on `basis`: a constant of the model nobody stated.
    pub fn resting_on(self, basis: &str) -> Param {
        Param {
            basis: Some(basis.into()),
            ..self
        }
    }

    /// This parameter with no sd, resting on `basis`: what the value rests on is something no
    /// curvature of the fit can give an uncertainty for.
    pub fn without_sd_resting_on(self, basis: &str) -> Param {
        Param { sd: None, ..self }.resting_on(basis)
    }

    /// Each distinct basis of `params` once, in the order it first appears, with the names of
    /// the parameters resting on it: a term's gains share one basis (a per-motor term's two
    /// dozen of them), which said once per parameter buried the summary.
    ///
    /// ```
    /// use magstand_diagnose::Param;
    /// let p = |n: &str| Param::new(n, 1.0, None, "A").resting_on("the law");
    /// let params = [p("a"), Param::new("b", 2.0, Some(0.1), "A"), p("c")];
    /// let grouped = Param::grouped_bases(&params);
    /// assert_eq!(grouped, vec![(vec!["a", "c"], "the law")]);
    /// ```
    pub fn grouped_bases<'a>(
        params: impl IntoIterator<Item = &'a Param>,
    ) -> Vec<(Vec<&'a str>, &'a str)> {
        let mut out: Vec<(Vec<&str>, &str)> = Vec::new();
        for p in params {
            let Some(basis) = p.basis.as_deref() else {
                continue;
            };
            match out.iter_mut().find(|(_, b)| *b == basis) {
                Some((names, _)) => names.push(&p.name),
                None => out.push((vec![&p.name], basis)),
            }
        }
        out
    }

    /// [`Param::grouped_bases`] in words, one line each: `a, b rest on BASIS` (`rests` for
    /// one name), as the text summary and the report say it.
    pub fn bases_in_words<'a>(params: impl IntoIterator<Item = &'a Param>) -> Vec<String> {
        Param::grouped_bases(params)
            .into_iter()
            .map(|(names, basis)| {
                let verb = if names.len() > 1 { "rest" } else { "rests" };
                format!("{} {verb} on {basis}", names.join(", "))
            })
            .collect()
    }

    /// Three parameters `name_x`, `name_y`, `name_z` from per-axis values.
    pub fn axes(name: &str, value: [f64; 3], sd: [f64; 3], unit: &str) -> Vec<Param> {
        ["x", "y", "z"]
            .iter()
            .enumerate()
            .map(|(a, ax)| Param::new(format!("{name}_{ax}"), value[a], Some(sd[a]), unit))
            .collect()
    }
}

/// An effect's fitted values in the final joint model.
pub struct EffectFit<'a> {
    /// Nonlinear parameters.
    pub theta: &'a [f64],
    /// Their standard uncertainties.
    pub theta_sd: &'a [Option<f64>],
    /// Coefficients of the effect's regressors, per column, per axis.
    pub coef: &'a [[f64; 3]],
    /// Their standard uncertainties.
    pub coef_sd: &'a [[f64; 3]],
}

/// A candidate piece of physics the nominal simulation may have left out.
pub trait Effect: Sync + Send {
    /// Catalog name (`battery_sag`, ...).
    fn name(&self) -> &'static str;

    /// One sentence of physics.
    fn explanation(&self) -> &'static str;

    /// Whether this recording can show the effect at all.
    fn applies(&self, _ctx: &Context) -> bool {
        true
    }

    /// Which form of its catalog effect this is, for a model file: None for the catalog's
    /// own, the name of a richer form ([`Effect::richer`]) otherwise.
    fn variant(&self) -> Option<&'static str> {
        None
    }

    /// The richer forms of this effect on this recording, with more freedom where the stand's
    /// physics is not stated. Each is tried only where this form's gain is significant, and
    /// kept only where its own held-out gain beyond this form's is; it may have richer forms
    /// of its own, tried the same way beyond it.
    fn richer(&self, _ctx: &Context) -> Vec<&'static dyn Effect> {
        Vec::new()
    }

    /// The form of this effect that its searched parameter `parameter` at the lower end of
    /// its range (`lower`) or the upper stands for, without that parameter: where a fit runs
    /// to that edge, the data ask for the limit, not for a value. None where there is no such
    /// form (the fit is then refused at the edge).
    fn edge_limit(&self, _parameter: &str, _lower: bool) -> Option<&'static dyn Effect> {
        None
    }

    /// Where this effect's searched parameter `parameter` at the lower end of its range is a
    /// limit the data determine (the value is that or less, and less changes nothing they
    /// see), not a value they leave undetermined: what it means. A finding refitted there is
    /// kept, its value reported as that limit. None, the default: such a fit is refused at
    /// the edge.
    fn lower_edge_is_a_limit(&self, _parameter: &str) -> Option<&'static str> {
        None
    }

    /// The names of the nonlinear parameters it can search, in order (its
    /// `nonlinear_params!` struct's names; none when it is linear in its regressors).
    fn parameters(&self) -> &'static [&'static str] {
        &[]
    }

    /// The nonlinear parameters searched on this recording: [`parameters`](Effect::parameters),
    /// or none where a logged column stands in for them.
    fn search(&self, ctx: &Context) -> Vec<Search>;

    /// Whether this effect's calibrated constant trades off against the shape of the
    /// calibrated current law (a dead zone: a law rising slowly from zero looks like a later
    /// start), so that its reported sd holds the spread over the law's shapes.
    fn trades_off_with_the_law_shape(&self) -> bool {
        false
    }

    /// The stand constant this effect re-fits, as its scenario key and its value in `s`, for
    /// an effect that is a different value of a nominal constant (a dead zone, a spin-up time)
    /// rather than physics the nominal stand lacks. Where the scenario states the constant, such
    /// an effect is named only where the data reject the stated value: its fit must lie beyond
    /// 3 standard uncertainties of it. The key's last part is the effect's one parameter, or,
    /// for a constant the parameter stands in for (a stated lag of the currents, which the
    /// spin-up's parameter replaces), another quantity of the same unit.
    fn stand_constant(&self, _ctx: &Context) -> Option<(&'static str, f64)> {
        None
    }

    /// For an effect with a [`stand_constant`](Effect::stand_constant) the scenario leaves
    /// out: why a fitted value `theta` is not a calibration of that constant but physics of
    /// its own, to be named (a lag far slower than any motor spin-up). `None`, the default,
    /// means any value within the search range is the stand's calibration.
    fn beyond_calibration(&self, _theta: &[f64]) -> Option<String> {
        None
    }

    /// Whether this effect's misfit can pass for a stand constant calibrated wrong (a late
    /// magnetometer looks like a slow spin-up). Such an effect is tried beside the calibration
    /// rounds that open an unstated diagnosis, and where it gains more than every calibration
    /// the whole catalog is tried before any calibration is accepted.
    fn mimics_calibration(&self) -> bool {
        false
    }

    /// Whether the chi-square over this effect's parameters has a basin per interval of the
    /// data rather than one over its range (a dead zone: one between each two logged command
    /// levels; a delay: one per sample interval), so that a later term can move its optimum
    /// to another basin. A refinement searches such an effect over its whole range again after
    /// each new term, any other only near where it was.
    fn has_a_basin_per_interval(&self) -> bool {
        false
    }

    /// Why parameters `theta`, inside their search range, are still none the data can
    /// determine (a delay within one sample interval of zero, which the command lead the
    /// baseline calibrates takes), so that a fit there is refused as one at an edge is; None
    /// where they are determined, as for most effects everywhere inside the range.
    fn undetermined_at(&self, _ctx: &Context, _theta: &[f64]) -> Option<String> {
        None
    }

    /// Changes the replayed physics for nonlinear parameters `theta`.
    fn apply(&self, _ctx: &Context, _scenario: &mut Scenario, _theta: &[f64]) {}

    /// Whether the motors should see the recorded supply voltage instead of the supply model's.
    fn uses_recorded_voltage(&self, _ctx: &Context) -> bool {
        false
    }

    /// The rows where a stand constant at `fitted` that really differs from the `stated` one
    /// must change the prediction, with why, or None where any row may show it (the default).
    /// A change seen only at the other rows is one the calibrated shape of the current law
    /// explains as well, and does not reject the statement.
    fn rows_telling_from_stated(
        &self,
        _ctx: &Context,
        _stated: f64,
        _fitted: f64,
    ) -> Option<(Vec<bool>, String)> {
        None
    }

    /// Why the recording cannot tell the stand constant at `fitted` from the `stated` one by
    /// more than the calibrated shape of the current law (see [`Effect::stand_constant`]),
    /// or None where it can (the default).
    fn inseparable_from_stated(
        &self,
        _ctx: &Context,
        _stated: f64,
        _fitted: f64,
    ) -> Option<String> {
        None
    }

    /// A first-order lag, s, that the field of the motor currents follows behind them: the
    /// baseline's current-law columns (and the per-motor field the scenario fixes) are lagged
    /// by it. None (the default) for an effect whose physics the replay carries.
    fn field_lag_s(&self, _ctx: &Context, _theta: &[f64]) -> Option<f64> {
        None
    }

    /// Whether this effect's columns change the motor currents themselves (the current law's
    /// columns times a supply's voltage change): where a term lags the currents' field, they
    /// are built from the law before that lag and lagged with it, as the currents are (a
    /// current that follows its command and its voltage through a lag follows their product,
    /// not the voltage times the lagged current). False (the default) for columns that a lag
    /// of the currents does not delay (a temperature, a measured current).
    fn changes_the_currents(&self, _ctx: &Context) -> bool {
        false
    }

    /// Whether this effect's columns follow the stand's current as the calibrated law has it
    /// (`law_current`), so that a model file with its term records that law. False (the
    /// default) for columns that other currents or logged columns make.
    fn follows_the_current_law(&self, _ctx: &Context) -> bool {
        false
    }

    /// Regressor columns the effect adds (each gets one coefficient per axis), with names.
    /// `law` is the baseline's current law as this model has it, each column by name (built
    /// from `trace`, and lagged where a term lags the currents' field, except for an effect
    /// that [changes the currents](Effect::changes_the_currents), whose columns are lagged
    /// after).
    fn regressors(
        &self,
        _ctx: &Context,
        _trace: &Trace,
        _law: &[(&str, &[f64])],
        _theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        Vec::new()
    }

    /// Switches the simulator's module on in `scenario` with the fitted values, and returns
    /// them for people: nonlinear parameters with their uncertainty, coefficients in physical
    /// units. Any fit the effect needs for this (a battery or a heating model to a logged
    /// column) happens here once. By default: `apply` the nonlinear parameters and report them
    /// as searched, which is all an effect made only of scenario settings needs.
    fn switch_on(&self, ctx: &Context, scenario: &mut Scenario, fitted: &EffectFit) -> Vec<Param> {
        self.apply(ctx, scenario, fitted.theta);
        searched_params(&self.search(ctx), fitted)
    }
}

/// The stand's current at every row of `trace`, the one a term of the current's history (a
/// play, a board's heating) follows: as the baseline's law calibrated it where there is one
/// ([`Context::current_law`]), else the replayed one (the logged current on a flight that
/// follows it). The nominal motor's current is another stand's shape: beside a stand whose
/// current is a 1.7th power of its command, a play on it moves at other commands, and a
/// heating on it weighs the levels otherwise, so a heating lag fits a play's loop and a
/// board's time constant comes out long.
pub(crate) fn law_current<'t>(ctx: &Context, trace: &'t Trace) -> Cow<'t, [f64]> {
    match followed_current_law(ctx) {
        Some(law) => Cow::Owned(stand_current(trace, law)),
        None => Cow::Borrowed(&trace.total_a),
    }
}

/// Whether a current in amperes that the diagnosis works with is the nominal motor's, a
/// default: the field calibrates the current's shape, not its scale, so where no current is
/// logged (and followed) and the scenario does not state the motor constants that set the
/// scale (the velocity constant, the winding resistance and the propeller's torque
/// coefficient), a parameter per ampere, or in amperes, rests on the nominal motor's.
pub(crate) fn amperes_are_nominal(ctx: &Context) -> bool {
    !ctx.follow_recorded_current
        && ![
            "motors.kv_rpm_per_v",
            "motors.winding_resistance_ohm",
            "motors.torque_coeff_nms2",
        ]
        .iter()
        .all(|key| ctx.nominal.states(key))
}

/// The calibrated current law that terms of the current's history follow
/// ([`law_current`]): none where it could not be told, or on a flight that follows its
/// logged current.
pub(crate) fn followed_current_law<'c>(
    ctx: &'c Context,
) -> Option<&'c crate::augmented_model::MotorCurrentLaw> {
    ctx.current_law
        .as_ref()
        .filter(|_| !ctx.follow_recorded_current)
}

/// The nonlinear parameters of `fitted` reported as `searches` name them, with their
/// uncertainty.
pub(crate) fn searched_params(searches: &[Search], fitted: &EffectFit) -> Vec<Param> {
    searches
        .iter()
        .zip(fitted.theta.iter().zip(fitted.theta_sd))
        .map(|(s, (v, sd))| Param::new(s.name, *v, *sd, s.unit))
        .collect()
}

/// Every effect of the catalog, in a fixed order.
pub fn catalog() -> Vec<Box<dyn Effect>> {
    vec![
        Box::new(BatterySag::NOMINAL),
        Box::new(ThermalDrift),
        Box::new(CurrentLag::NOMINAL),
        Box::new(TimeOffset),
        Box::new(Hysteresis),
        Box::new(MotorAsymmetry),
        Box::new(DeadZone),
    ]
}

/// The catalog's effect `name` in its form `variant` ([`Effect::variant`]), as a model file
/// names it.
pub(crate) fn find(name: &str, variant: Option<&str>) -> Option<&'static dyn Effect> {
    static CATALOG: std::sync::OnceLock<Vec<Box<dyn Effect>>> = std::sync::OnceLock::new();
    let catalog = CATALOG.get_or_init(catalog);
    match variant {
        None => catalog
            .iter()
            .find(|e| e.name() == name)
            .map(|e| e.as_ref()),
        Some(v) => battery_sag::richer_forms()
            .chain(current_lag::richer_forms())
            .find(|e| e.name() == name && e.variant() == Some(v)),
    }
}

/// Names of the catalog's effects.
pub fn names() -> Vec<&'static str> {
    catalog().iter().map(|e| e.name()).collect()
}

/// First-order lag of `x` sampled at `t_s` with time constant `tau_s`, starting from zero
/// (exact for a signal held between samples).
pub(crate) fn first_order_lag(t_s: &[f64], x: &[f64], tau_s: f64) -> Vec<f64> {
    let mut y = x.to_vec();
    lag_columns(t_s, &mut [&mut y], tau_s, false, 0.0);
    y
}

/// Lags every column of `columns` in place from each column's first value (a run that starts
/// with current flowing starts settled), each column's change between two samples taking
/// effect `lead` (0..1) of the interval before the later one: where the replay puts a logged
/// command's change ([`Context::command_lead`]). Exact for a column that steps there, as the
/// replay's do behind a fast spin-up; holding the earlier value over the whole interval would
/// start every step of a lag up to a sample late, a misfit that grows with the step and
/// stands out on a quiet sensor.
pub(crate) fn lag_in_place(t_s: &[f64], columns: &mut [&mut [f64]], tau_s: f64, lead: f64) {
    lag_columns(t_s, columns, tau_s, true, lead.clamp(0.0, 1.0));
}

/// Rows per task where [`SeriesLag::new`] computes its factors in parallel.
const LAG_ROWS_PER_TASK: usize = 4096;

/// Columns [`SeriesLag::apply`] lags together in one task: each column's recursion is a chain
/// of dependent steps, and a few columns stepped side by side keep a core busy between them.
const LAG_COLUMNS_PER_TASK: usize = 4;

/// [`lag_in_place`] through two first-order lags in series, `first_s` then `then_s` (a
/// motor's spin-up, then a lag of the currents' field), each column settled at its first
/// value, as a map of each interval of a recording made once for all the columns a design
/// lags the same way (the current law's, the fixed field's, the square of the current): its
/// four exponentials per row cost as much as lagging the columns.
///
/// Each interval is solved exactly for its two stretches (the earlier sample held for
/// `1 - lead` of it, then the later one): the first lag's output is not a step at either end,
/// so lagging a column twice, row by row, would take the part of a change that the first lag
/// had passed by a row for a step at that row's moment and the rest for another step an
/// interval later. (With no first lag this is [`lag_in_place`] in other rounding; that one
/// stays for a single lag, so the outputs of every other lag keep their bits.)
pub(crate) struct SeriesLag {
    /// Per interval, its two stretches composed into one linear map ([`IntervalMap`]).
    intervals: Vec<IntervalMap>,
}

/// One interval of two first-order lags in series, its two stretches (the earlier sample
/// `p` held, then the later one `q`) composed: the states `x1`, `x2` at its end are
/// `a11 x1 + b1p p + b1q q` and `a22 x2 + a21 x1 + b2p p + b2q q`. Each column's recursion
/// is then one multiply-add deep per row on each state, where stepping the two stretches
/// one after the other chains eight operations.
#[derive(Clone, Copy)]
struct IntervalMap {
    a11: f64,
    b1p: f64,
    b1q: f64,
    a21: f64,
    a22: f64,
    b2p: f64,
    b2q: f64,
}

impl IntervalMap {
    /// The stretch with factors `held` ([`series_factors`]) on the earlier sample, then the
    /// one with `then` on the later.
    fn composed(held: (f64, f64, f64), then: (f64, f64, f64)) -> Self {
        let ((e1, e2, c), (g1, g2, gc)) = (held, then);
        IntervalMap {
            a11: g1 * e1,
            b1p: g1 * (1.0 - e1),
            b1q: 1.0 - g1,
            a21: g2 * c + gc * e1,
            a22: g2 * e2,
            b2p: g2 * (1.0 - e2 - c) + gc * (1.0 - e1),
            b2q: 1.0 - g2 - gc,
        }
    }
}

impl SeriesLag {
    /// The map of `first_s` then `then_s` over each interval of `t_s`, each column's change
    /// acting from `lead` (0..1) of its interval.
    pub(crate) fn new(t_s: &[f64], first_s: f64, then_s: f64, lead: f64) -> Self {
        use rayon::prelude::*;
        let lead = lead.clamp(0.0, 1.0);
        let intervals = t_s
            .par_windows(2)
            .with_min_len(LAG_ROWS_PER_TASK)
            .map(|w| {
                let dt = w[1] - w[0];
                IntervalMap::composed(
                    series_factors((1.0 - lead) * dt, first_s, then_s),
                    series_factors(lead * dt, first_s, then_s),
                )
            })
            .collect();
        SeriesLag { intervals }
    }

    /// About how many bytes the maps take.
    pub(crate) fn bytes(&self) -> usize {
        std::mem::size_of_val(self.intervals.as_slice())
    }

    /// Lags every column in place from its first value, a few columns per task in parallel
    /// (each column's bits are those of one column lagged alone).
    pub(crate) fn apply(&self, columns: &mut [&mut [f64]]) {
        use rayon::prelude::*;
        let n = columns
            .iter()
            .map(|c| c.len())
            .fold(self.intervals.len() + 1, usize::min);
        columns
            .par_chunks_mut(LAG_COLUMNS_PER_TASK)
            .for_each(|group| self.apply_to(group, n));
    }

    /// [`SeriesLag::apply`] on the first `n` rows of one group of columns.
    fn apply_to(&self, group: &mut [&mut [f64]], n: usize) {
        match group {
            [a, b, c, d] => self.apply_to_width([a, b, c, d], n),
            [a, b, c] => self.apply_to_width([a, b, c], n),
            [a, b] => self.apply_to_width([a, b], n),
            [a] => self.apply_to_width([a], n),
            _ => group.chunks_mut(1).for_each(|one| self.apply_to(one, n)),
        }
    }

    /// [`SeriesLag::apply_to`] on `W` columns stepped side by side, their states in registers.
    fn apply_to_width<const W: usize>(&self, group: [&mut &mut [f64]; W], n: usize) {
        let columns: [&mut [f64]; W] = group.map(|c| &mut c[..n]);
        // Per column: the sample before, and the two lags' states.
        let mut previous: [f64; W] =
            std::array::from_fn(|j| columns[j].first().copied().unwrap_or(0.0));
        let (mut x1, mut x2) = (previous, previous);
        for (r, m) in (1..n).zip(&self.intervals) {
            for j in 0..W {
                let (p, q) = (previous[j], columns[j][r]);
                let inputs_1 = m.b1p * p + m.b1q * q;
                let inputs_2 = m.a21 * x1[j] + m.b2p * p + m.b2q * q;
                x1[j] = m.a11 * x1[j] + inputs_1;
                x2[j] = m.a22 * x2[j] + inputs_2;
                previous[j] = q;
                columns[j][r] = x2[j];
            }
        }
    }
}

/// Over a stretch of `h_s` with the input held, two first-order lags in series (`tau1_s`
/// feeding `tau2_s`) keep these shares of their departures from the input: the first's
/// `e1`, the second's `e2`, and the second also `coupling` times the first's.
fn series_factors(h_s: f64, tau1_s: f64, tau2_s: f64) -> (f64, f64, f64) {
    if h_s <= 0.0 {
        return (1.0, 1.0, 0.0);
    }
    let (e1, e2) = ((-h_s / tau1_s).exp(), (-h_s / tau2_s).exp());
    // tau1 (e1 - e2) / (tau1 - tau2), and its limit h e / tau where the two are one.
    let coupling = if (tau1_s - tau2_s).abs() <= 1e-6 * tau2_s {
        h_s / tau2_s * e2
    } else {
        tau1_s * (e1 - e2) / (tau1_s - tau2_s)
    };
    (e1, e2, coupling)
}

/// The first-order lag of every column in place, one pair of lag factors per row for all of
/// them: each column held at its earlier sample for `1 - lead` of an interval, then at its
/// later one; from each column's first value when `settled`, else from zero.
fn lag_columns(t_s: &[f64], columns: &mut [&mut [f64]], tau_s: f64, settled: bool, lead: f64) {
    let n = columns.iter().map(|c| c.len()).fold(t_s.len(), usize::min);
    let mut previous: Vec<f64> = columns
        .iter()
        .map(|c| c.first().copied().unwrap_or(0.0))
        .collect();
    let mut state: Vec<f64> = if settled {
        previous.clone()
    } else {
        vec![0.0; columns.len()]
    };
    for (col, s) in columns.iter_mut().zip(&state) {
        if let Some(first) = col.first_mut() {
            *first = *s;
        }
    }
    for r in 1..n {
        let dt = t_s[r] - t_s[r - 1];
        let held = magstand_sim::lag::lag_factor((1.0 - lead) * dt, tau_s);
        // No step after the change where it acts at the later sample (no exponential either).
        let after = (lead > 0.0).then(|| magstand_sim::lag::lag_factor(lead * dt, tau_s));
        for ((col, s), p) in columns.iter_mut().zip(&mut state).zip(&mut previous) {
            *s += (*p - *s) * held;
            if let Some(after) = after {
                *s += (col[r] - *s) * after;
            }
            *p = col[r];
            col[r] = *s;
        }
    }
}

/// A recording on the default unstated nominal stand with what a [`Context`] borrows: its
/// split, and its nominal replay.
#[cfg(test)]
pub(crate) struct TestStand {
    rec: Recording,
    nominal: Scenario,
    split: Split,
    trace: Trace,
}

#[cfg(test)]
impl TestStand {
    /// The stand for `rec`.
    pub(crate) fn new(rec: Recording) -> Self {
        Self::on(rec, crate::unstated_nominal().unwrap().into_inner())
    }

    /// The stand for `rec` with `nominal` as its nominal scenario.
    fn on(rec: Recording, nominal: Scenario) -> Self {
        let split = crate::pipeline::held_out_split(&rec.t_s, None, 3);
        let trace = magstand_sim::replay::replay(&nominal, &rec.t_s, &rec.thr, None, 0.5);
        Self {
            rec,
            nominal,
            split,
            trace,
        }
    }

    /// The stand with its nominal scenario changed by `change` (as a scenario states it).
    pub(crate) fn with_nominal(mut self, change: impl FnOnce(&mut Scenario)) -> Self {
        change(&mut self.nominal);
        Self::on(self.rec, self.nominal)
    }

    /// A context of a stand recording (no flight, the supply modelled) at lead 0.5.
    pub(crate) fn context(&self) -> Context<'_> {
        Context {
            rec: &self.rec,
            nominal: &self.nominal,
            split: &self.split,
            nominal_trace: &self.trace,
            rec_origin: "inline".into(),
            command_lead: 0.5,
            flight: false,
            follow_recorded_voltage: false,
            follow_recorded_current: false,
            speed_powers: crate::fit::MIN_SPEED_POWERS,
            armed_current: true,
            motor_groups: motor_groups(&self.rec.thr),
            motor_current_law: None,
            current_law: None,
            replays: Default::default(),
            series_lags: Default::default(),
        }
    }

    /// A stair of one overall command (3 s per level, nine levels over and over) sampled
    /// every 0.04 s for `rows` rows, whose field the nominal law does not hold exactly: a
    /// slow drift beside the command's, so every term's fit moves the residual.
    pub(crate) fn drifting_stair(rows: usize) -> Self {
        let t_s: Vec<f64> = (0..rows).map(|k| k as f64 * 0.04).collect();
        let thr: Vec<f64> = t_s
            .iter()
            .map(|t| ((t / 3.0).floor() % 9.0) / 8.0)
            .collect();
        let mag_ut: Vec<magstand_core::Vec3> = t_s
            .iter()
            .zip(&thr)
            .map(|(t, u)| {
                let slow = 0.3 * (t / 40.0).sin();
                magstand_core::Vec3::new(20.0 + 3.0 * u + slow, -4.0 - u * u, 40.0 + 2.0 * u - slow)
            })
            .collect();
        Self::new(Recording {
            mag_ut,
            thr: vec![thr],
            overall_only: true,
            t_s,
            ..Default::default()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lag_in_place_starts_settled_and_follows_the_exact_first_order_step() {
        let t_s: Vec<f64> = (0..50)
            .map(|r| 0.02 * r as f64 + 0.001 * (r % 3) as f64)
            .collect();
        let x: Vec<f64> = (0..50).map(|r| if r < 20 { 3.0 } else { 7.0 }).collect();
        let y: Vec<f64> = (0..50).map(|r| (r as f64 * 0.3).sin()).collect();
        let (mut a, mut b) = (x.clone(), y.clone());
        lag_in_place(&t_s, &mut [&mut a, &mut b], 0.1, 0.0);
        // From the first value, as the lag from zero of the change plus that value.
        for (lagged, raw) in [(&a, &x), (&b, &y)] {
            let change: Vec<f64> = raw.iter().map(|v| v - raw[0]).collect();
            let reference = first_order_lag(&t_s, &change, 0.1);
            for r in 0..50 {
                assert!(
                    (lagged[r] - (reference[r] + raw[0])).abs() < 1e-12,
                    "row {r}: {} against {}",
                    lagged[r],
                    reference[r] + raw[0]
                );
            }
        }
        assert_eq!(
            a[..21],
            [3.0; 21],
            "settled before the step, which acts after its row"
        );
        let left = (7.0 - a[49]) / 4.0;
        let expected = (-(t_s[49] - t_s[20]) / 0.1f64).exp();
        assert!(
            (left - expected).abs() < 1e-12,
            "{left} of the step left, {expected} expected"
        );
    }

    /// Regression: the lag of the currents' field held each sample over the whole interval
    /// after it, so every step of the lag began where the next sample was taken, not where
    /// the replay put the command's change (`command_lead` of the interval before it). On an
    /// independent stand with a 0.5 s current lag and a quiet sensor the misfit behind each
    /// step was named `hysteresis`.
    #[test]
    fn a_lagged_step_starts_where_the_command_changed() {
        let t_s: Vec<f64> = (0..60)
            .map(|r| 0.0133 * r as f64 + 0.0004 * (r % 4) as f64)
            .collect();
        let x: Vec<f64> = (0..60).map(|r| if r < 20 { 3.0 } else { 7.0 }).collect();
        for lead in [0.0, 0.3, 0.5, 1.0] {
            let mut a = x.clone();
            lag_in_place(&t_s, &mut [&mut a], 0.25, lead);
            let switch_s = t_s[20] - lead * (t_s[20] - t_s[19]);
            for r in 0..60 {
                let exact = if t_s[r] <= switch_s {
                    3.0
                } else {
                    7.0 - 4.0 * (-(t_s[r] - switch_s) / 0.25f64).exp()
                };
                assert!(
                    (a[r] - exact).abs() < 1e-12,
                    "lead {lead}, row {r}: {} against the exact {exact}",
                    a[r]
                );
            }
        }
    }

    /// Regression: behind a lag of the currents' field the replay spun the motors up itself
    /// and the field's lag then took each row's value for a step at the command's moment. A
    /// change made within a few spin-up times of the row that shows it was half done there:
    /// the field's lag took that half for one step and the rest for another an interval later.
    /// The chi-square of a 0.5 s lag at 10 Hz dipped where the moment lay a millisecond (the
    /// stated spin-up) before the row, and the timing search settled in that dip (lag 0.45 s,
    /// and `hysteresis` named for what was left). The two lags in series are now solved
    /// exactly within each interval.
    #[test]
    fn two_lags_in_series_follow_the_exact_step_response() {
        let t_s: Vec<f64> = (0..60)
            .map(|r| 0.1 * r as f64 + 0.002 * (r % 3) as f64)
            .collect();
        let x: Vec<f64> = (0..60).map(|r| if r < 20 { 3.0 } else { 7.0 }).collect();
        for (spinup_s, tau_s) in [(0.001, 0.5), (0.08, 0.5), (0.3, 0.3)] {
            for lead in [0.0, 0.01, 0.5, 1.0] {
                let mut a = x.clone();
                SeriesLag::new(&t_s, spinup_s, tau_s, lead).apply(&mut [&mut a]);
                let switch_s = t_s[20] - lead * (t_s[20] - t_s[19]);
                for r in 0..60 {
                    let since = t_s[r] - switch_s;
                    // The step response of two first-order lags in series (its limit where
                    // the two are one).
                    let left = if since <= 0.0 {
                        1.0
                    } else if (tau_s - spinup_s).abs() < 1e-6 {
                        (1.0 + since / tau_s) * (-since / tau_s).exp()
                    } else {
                        (tau_s * (-since / tau_s).exp() - spinup_s * (-since / spinup_s).exp())
                            / (tau_s - spinup_s)
                    };
                    let exact = 7.0 - 4.0 * left;
                    assert!(
                        (a[r] - exact).abs() < 1e-9,
                        "spin-up {spinup_s} s, lag {tau_s} s, lead {lead}, row {r}: {} against \
                         the exact {exact}",
                        a[r]
                    );
                }
            }
        }
    }

    /// Columns are lagged a few at a time, side by side, and the groups in parallel: every
    /// column of a set of seven (groups of four and three) comes out with the bits it has
    /// lagged alone, and a column shorter than the others bounds the rows lagged in all.
    #[test]
    fn columns_lagged_together_equal_each_lagged_alone() {
        let t_s: Vec<f64> = (0..500)
            .map(|r| 0.02 * r as f64 + 0.0004 * (r % 5) as f64)
            .collect();
        let columns: Vec<Vec<f64>> = (0..7)
            .map(|c| (0..500).map(|r| ((r / (20 + c) + c) % 4) as f64).collect())
            .collect();
        let lag = SeriesLag::new(&t_s, 0.03, 0.4, 0.3);
        let mut together = columns.clone();
        lag.apply(
            &mut together
                .iter_mut()
                .map(Vec::as_mut_slice)
                .collect::<Vec<_>>(),
        );
        for (c, column) in columns.iter().enumerate() {
            let mut alone = column.clone();
            lag.apply(&mut [&mut alone]);
            assert_eq!(
                alone, together[c],
                "column {c} differs lagged with the others"
            );
            assert_ne!(alone, *column, "column {c} was not lagged");
        }
        let (mut long, mut short) = (columns[0].clone(), columns[1][..300].to_vec());
        lag.apply(&mut [&mut long, &mut short]);
        assert_eq!(
            long[300..],
            columns[0][300..],
            "rows beyond the shortest column lagged"
        );
        assert_eq!(
            short,
            together[1][..300],
            "the shorter column's rows differ"
        );
    }

    #[test]
    fn catalog_names_are_the_documented_ones() {
        assert_eq!(
            names(),
            [
                "battery_sag",
                "thermal_drift",
                "current_lag",
                "time_offset",
                "hysteresis",
                "motor_asymmetry",
                "dead_zone"
            ]
        );
    }

    /// The names an effect declares are the ones it searches, in order; an effect that re-fits
    /// a stand constant searches that constant alone (the stated-value test reads it as the
    /// first value), under the key's own name.
    #[test]
    fn every_effect_searches_its_declared_parameters() {
        let t_s: Vec<f64> = (0..2000).map(|k| k as f64 * 0.02).collect();
        let thr: Vec<f64> = t_s
            .iter()
            .map(|t| ((t / 5.0).floor() / 8.0).min(1.0))
            .collect();
        let rec = Recording {
            mag_ut: vec![magstand_core::Vec3::zeros(); t_s.len()],
            thr: vec![thr],
            overall_only: true,
            t_s,
            ..Default::default()
        };
        let stand = TestStand::new(rec);
        let ctx = stand.context();
        for e in catalog() {
            let searched: Vec<_> = e.search(&ctx).iter().map(|s| s.name).collect();
            assert_eq!(searched, e.parameters(), "effect {}", e.name());
            if let Some((key, _)) = e.stand_constant(&ctx) {
                assert_eq!(
                    [key.rsplit('.').next().unwrap()],
                    e.parameters(),
                    "effect {}",
                    e.name()
                );
            }
        }
    }

    /// A model file names an effect by its name and form: each catalog effect is found as
    /// itself, the battery's richer form by its variant, and an unknown form not at all.
    #[test]
    fn a_model_files_effects_are_found_by_name_and_form() {
        for e in catalog() {
            let found = find(e.name(), None).map(|f| (f.name(), f.variant()));
            assert_eq!(found, Some((e.name(), None)), "effect {}", e.name());
        }
        for form in [
            "free_discharge",
            "free_discharge_second_order",
            "free_discharge_no_sag",
            "free_discharge_no_sag_second_order",
            "drawn_charge",
        ] {
            let rich = find("battery_sag", Some(form)).map(|f| (f.name(), f.variant()));
            assert_eq!(rich, Some(("battery_sag", Some(form))));
        }
        let lag =
            find("current_lag", Some("without_stated_spinup")).map(|f| (f.name(), f.variant()));
        assert_eq!(lag, Some(("current_lag", Some("without_stated_spinup"))));
        assert!(find("battery_sag", Some("without_stated_spinup")).is_none());
        assert!(find("battery_sag", Some("no_such_form")).is_none());
        assert!(find("thermal_drift", Some("free_discharge")).is_none());
        assert!(find("no_such_effect", None).is_none());
    }

    #[test]
    fn first_order_lag_reaches_63_percent_after_one_time_constant() {
        let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 0.01).collect();
        let y = first_order_lag(&t, &vec![1.0; t.len()], 2.0);
        assert!(
            (y[200] - (1.0 - (-1.0f64).exp())).abs() < 1e-12,
            "{}",
            y[200]
        );
    }
}
