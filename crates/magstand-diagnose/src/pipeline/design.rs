//! Stage 1, the regression design: the recording's commands replayed through the nominal
//! physics with the terms' nonlinear parameters, the regressor columns of the baseline and of
//! every term, and the weighted fit of such a design with a noise law from its own residuals.
use std::sync::{Arc, Mutex};

use magstand_core::Vec3;
use magstand_sim::Scenario;
use magstand_sim::replay::{Logged, SupplyLags, Trace, replay_behind_lags, voltage_follows_load};

use crate::DiagnoseError;
use crate::effects::{Context, Effect, SeriesLag};
use crate::fit::{Design, Fitted, VarianceModel, Weights, fit};

/// An effect in the model with its nonlinear parameters.
#[derive(Clone)]
pub(crate) struct Term<'e> {
    pub(crate) effect: &'e dyn Effect,
    pub(crate) theta: Vec<f64>,
    pub(crate) theta_sd: Vec<Option<f64>>,
}

#[cfg(test)]
impl Term<'static> {
    /// The catalog's effect `name` at the middle of each of its search ranges (the geometric
    /// middle of a logarithmic one).
    pub(crate) fn mid_range(ctx: &Context, name: &str) -> Self {
        let effect = crate::effects::find(name, None).unwrap_or_else(|| panic!("no {name}"));
        let theta: Vec<f64> = effect
            .search(ctx)
            .iter()
            .map(|s| {
                if s.log {
                    (s.lo * s.hi).sqrt()
                } else {
                    0.5 * (s.lo + s.hi)
                }
            })
            .collect();
        Term {
            effect,
            theta_sd: vec![None; theta.len()],
            theta,
        }
    }
}

/// The design of a model and which columns belong to which term.
pub(crate) struct Built {
    pub(crate) design: Design,
    /// What the nominal physics fixes (per-motor wiring differences, switched-on extras).
    pub(crate) fixed: Vec<Vec3>,
    /// Motor current over its largest value: the load the noise variance grows with.
    pub(crate) load: Vec<f64>,
    /// The largest motor current, A (`load` 1).
    pub(crate) full_load_a: f64,
    /// The columns of each term, in the order of the terms.
    pub(crate) term_columns: Vec<std::ops::Range<usize>>,
}

impl Built {
    /// Motor current at every row, A.
    pub(crate) fn load_a(&self) -> Vec<f64> {
        self.load.iter().map(|q| q * self.full_load_a).collect()
    }
}

/// The latest few values made, each with what it was made from, most recent first: the
/// searches ask for the same ones many times (a replay, a lag's maps). How many are kept is
/// what the caller says for the value just made.
struct LatestKept<K, V>(Mutex<Vec<(K, Arc<V>)>>);

impl<K, V> Default for LatestKept<K, V> {
    fn default() -> Self {
        LatestKept(Mutex::new(Vec::new()))
    }
}

impl<K, V> LatestKept<K, V> {
    /// The kept value whose key `matches`, or the one `make` makes (kept under `key()`, with
    /// the `keep(&value)` latest); the value used goes first.
    fn get_or_make(
        &self,
        matches: impl Fn(&K) -> bool,
        key: impl FnOnce() -> K,
        make: impl FnOnce() -> V,
        keep: impl FnOnce(&V) -> usize,
    ) -> Arc<V> {
        // A poisoned lock only means another search panicked; the list itself stays valid.
        let lock = || self.0.lock().unwrap_or_else(|e| e.into_inner());
        {
            let mut kept = lock();
            if let Some(i) = kept.iter().position(|(k, _)| matches(k)) {
                let hit = kept.remove(i);
                let value = Arc::clone(&hit.1);
                kept.insert(0, hit);
                return value;
            }
        }
        // Made outside the lock: the candidates' searches run in parallel.
        let value = Arc::new(make());
        let mut kept = lock();
        kept.insert(0, (key(), Arc::clone(&value)));
        kept.truncate(keep(&value).max(1));
        value
    }
}

/// Replays of the recording already made, by the physics and the timing they were made with
/// (the magnetometer's delay left out where the motors are coupled and the replay is shifted
/// instead): the searches evaluate the same physics many times (an effect whose parameters
/// the replay does not see, a delay searched over one coupled replay, the accepted terms'
/// physics in every round). A few of the latest are kept, within
/// [`REPLAY_CACHE_BYTES`].
#[derive(Default)]
pub(crate) struct ReplayCache(LatestKept<ReplayKey, Trace>);

/// What a replay depends on.
struct ReplayKey {
    scenario: Scenario,
    lead_bits: u64,
    recorded_voltage: bool,
    recorded_current: bool,
    supply_lags: SupplyLags,
}

/// Most replays a cache keeps.
const REPLAYS_KEPT: usize = 6;

/// Memory the kept replays may take, bytes: a long log keeps fewer of them (at least the
/// latest), so a diagnosis's memory stays a small multiple of its recording's.
const REPLAY_CACHE_BYTES: usize = 256 << 20;

/// About how many bytes a replay of `t` holds.
fn trace_bytes(t: &Trace) -> usize {
    let columns = 3 * t.speed.len() + 3 + t.modules.len() + 3;
    t.len() * columns * std::mem::size_of::<f64>()
}

impl ReplayCache {
    /// The replay of `scenario` at `lead`, made by `make` unless one is kept; the latest used
    /// are kept.
    fn get_or_make(
        &self,
        scenario: &Scenario,
        lead: f64,
        logged: Logged,
        supply_lags: SupplyLags,
        make: impl FnOnce() -> Trace,
    ) -> Arc<Trace> {
        let (lead_bits, recorded_voltage, recorded_current) = (
            lead.to_bits(),
            logged.bat_v.is_some(),
            logged.bat_a.is_some(),
        );
        self.0.get_or_make(
            // Every field named (no `..`): a field added to the key is compared here too.
            |ReplayKey {
                 scenario: s,
                 lead_bits: l,
                 recorded_voltage: v,
                 recorded_current: c,
                 supply_lags: g,
             }| {
                (*l, *v, *c) == (lead_bits, recorded_voltage, recorded_current)
                    && g.0.map(f64::to_bits) == supply_lags.0.map(f64::to_bits)
                    && s == scenario
            },
            || ReplayKey {
                scenario: scenario.clone(),
                lead_bits,
                recorded_voltage,
                recorded_current,
                supply_lags,
            },
            make,
            |trace| (REPLAY_CACHE_BYTES / trace_bytes(trace).max(1)).clamp(1, REPLAYS_KEPT),
        )
    }
}

/// The design of `terms` with the context's command lead.
pub(crate) fn build(ctx: &Context, terms: &[(&dyn Effect, &[f64])]) -> Built {
    build_with_lead(ctx, terms, ctx.command_lead)
}

/// The design of `terms` with command changes taking effect at `lead` of each interval.
pub(crate) fn build_with_lead(ctx: &Context, terms: &[(&dyn Effect, &[f64])], lead: f64) -> Built {
    let mut s = ctx.nominal.clone();
    let mut recorded_v = ctx.follow_recorded_voltage;
    for (e, theta) in terms {
        e.apply(ctx, &mut s, theta);
        recorded_v |= e.uses_recorded_voltage(ctx);
    }
    let logged = Logged::of(ctx.rec, recorded_v, ctx.follow_recorded_current);
    let field_lags: Vec<Option<f64>> = terms.iter().map(|(e, t)| e.field_lag_s(ctx, t)).collect();
    // A current lag the scenario states (`motors.current_lag_s`: the motors' current follows
    // the current of their speed through it, as a `current_lag` finding slower than any
    // spin-up has it) is the design's lag of the currents' field where no term brings one of
    // its own (a finding replaces it): the replay steps the commands in full and the columns
    // are lagged below, as for the finding. (A flight's field follows its measured current.)
    let stated_lag_s = (!ctx.follow_recorded_current && field_lags.iter().all(Option::is_none))
        .then(|| std::mem::take(&mut s.motors.current_lag_s))
        .filter(|&tau_s| tau_s > 0.0);
    let any_lag_s = field_lags.iter().flatten().next().copied().or(stated_lag_s);
    // Behind a lag of the currents' field, the spin-up is a second lag in series with it,
    // applied to the columns below with the field's: the replay steps each command in full at
    // its moment. A replay that spun the motors up itself would leave a change made within a
    // few spin-up times of the row that shows it half done at that row, and the field's lag
    // would take the half as a step of its own and the rest as another, an interval later:
    // the chi-square would dip where the moment lies a spin-up time before the row, a false
    // optimum the timing search can settle in.
    // Behind a stated lag an unstated spin-up is not the nominal one: as behind a finding of
    // such a lag (`CurrentLag::apply`), the lag takes up whatever spin-up the rotors have,
    // so the baseline is the model the refit at the statement has.
    let spinup_behind_s = match any_lag_s {
        Some(_) => {
            let replayed_s = std::mem::take(&mut s.motors.spinup_tau_s);
            if stated_lag_s.is_some() && !ctx.nominal.states("motors.spinup_tau_s") {
                crate::effects::FASTEST_SPINUP_S
            } else {
                replayed_s
            }
        }
        None => 0.0,
    };
    // The replay reads a late magnetometer's rows at their delayed times by its own steps (a
    // command change is a step at its moment, not a ramp between two rows: at a low rate a
    // ramp misses half the step at the row the delay puts within its interval).
    // The replay takes the lead within 0..1: a curvature step past an end is the end's replay.
    let lead = lead.clamp(0.0, 1.0);
    // Behind such a lag the current itself lags: a battery's sag follows the lagged current.
    // (Only a voltage that moves with the load sees it: elsewhere the replay is the same for
    // every lag, and kept for all of them.)
    let supply_lags = match any_lag_s {
        Some(tau_s) if voltage_follows_load(&s, logged) => SupplyLags([tau_s, spinup_behind_s]),
        _ => SupplyLags::NONE,
    };
    let trace: &Trace = &ctx.replays.get_or_make(&s, lead, logged, supply_lags, || {
        replay_behind_lags(&s, &ctx.rec.t_s, &ctx.rec.thr, logged, lead, supply_lags)
    });
    let mut design = Design::baseline(
        trace,
        ctx.follow_recorded_current,
        ctx.speed_powers,
        ctx.armed_current,
    );
    let mut fixed = trace.extra_ut.clone();
    // The lag runs over the magnetometer's reads: a late one reads between the commands' rows.
    let read_lead =
        lead_between_reads(ctx.rec.typical_interval_s(), s.logging.read_delay_s(), lead);
    let kernel = |tau_s: f64| {
        FieldLag::new(
            &ctx.series_lags,
            &trace.t_s,
            spinup_behind_s,
            tau_s,
            read_lead,
        )
    };
    let kernels: Vec<Option<FieldLag>> = field_lags.iter().map(|t| t.map(kernel)).collect();
    let stated_kernel = stated_lag_s.map(kernel);
    // Every lag of the currents' field: the terms' and a stated one.
    let field_kernels = || kernels.iter().flatten().chain(&stated_kernel);
    // The law before the lag, for the terms that change the currents: their columns are
    // lagged after they are formed, as the currents they change are.
    let lags_the_field = field_kernels().next().is_some();
    let unlagged_law: Vec<(String, Vec<f64>)> =
        if lags_the_field && terms.iter().any(|(e, _)| e.changes_the_currents(ctx)) {
            design
                .current_law_columns()
                .map(|(name, c)| (name.to_string(), c.to_vec()))
                .collect()
        } else {
            Vec::new()
        };
    for lag in field_kernels() {
        lag_current_field(&mut design, &mut fixed, lag);
    }
    // A stated lag is the baseline's as a finding's is its term's, with the same second order
    // of a field nonlinear in the current: a lag stated at a finding's value (the augmented
    // scenario's) is the model the finding had.
    let avionics_a = s.supply.avionics_current_a();
    if let Some(lag) = &stated_kernel {
        design.push(
            LAGGED_CURRENT_SQUARED,
            square_behind_lag(trace, avionics_a, lag),
        );
    }
    // Every term's columns, from the baseline's current law as built; a term that lags the
    // currents' field also takes the second order of a field nonlinear in the current.
    let law: Vec<(&str, &[f64])> = design.current_law_columns().collect();
    let law_before_lag: Vec<(&str, &[f64])> = unlagged_law
        .iter()
        .map(|(name, c)| (name.as_str(), c.as_slice()))
        .collect();
    let added: Vec<Vec<(String, Vec<f64>)>> = terms
        .iter()
        .zip(&kernels)
        .map(|((e, theta), field_lag)| {
            let mut columns = if lags_the_field && e.changes_the_currents(ctx) {
                let mut columns = e.regressors(ctx, trace, &law_before_lag, theta);
                let mut lagged: Vec<&mut [f64]> =
                    columns.iter_mut().map(|(_, c)| c.as_mut_slice()).collect();
                for lag in field_kernels() {
                    lag.apply(&mut lagged);
                }
                columns
            } else {
                e.regressors(ctx, trace, &law, theta)
            };
            if let Some(lag) = field_lag {
                columns.push((
                    LAGGED_CURRENT_SQUARED.into(),
                    square_behind_lag(trace, avionics_a, lag),
                ));
            }
            columns
        })
        .collect();
    let mut term_columns = Vec::new();
    for columns in added {
        let start = design.len();
        for (name, col) in columns {
            design.push(name, col);
        }
        term_columns.push(start..design.len());
    }
    let max_a = trace
        .total_a
        .iter()
        .map(|a| a - avionics_a)
        .fold(0.0, f64::max)
        .max(1e-9);
    Built {
        design,
        fixed,
        load: trace
            .total_a
            .iter()
            .map(|a| (a - avionics_a) / max_a)
            .collect(),
        full_load_a: max_a,
        term_columns,
    }
}

/// Where within each interval between two of the magnetometer's reads a command change takes
/// effect, as a fraction of the interval before the later read: `lead` of the commands' own
/// interval (`interval_s`, the rows' typical one) where the magnetometer reads at its rows'
/// times; where it reads `delay_s` earlier, `lead` less the delay's fraction of an interval,
/// wrapped into 0..1 (a change the commands' rows place a quarter interval before a row lies
/// a quarter interval before a read of a magnetometer late by whole intervals, and three
/// quarters before one late by half an interval more). The replay reads a late magnetometer's
/// rows at their delayed times with each command stepped at its moment; a lag of the field run
/// over those reads must put each step where the replay did. A negative delay (the commands
/// logged late) moves the reads the other way.
pub(crate) fn lead_between_reads(interval_s: f64, delay_s: f64, lead: f64) -> f64 {
    if !(delay_s != 0.0 && interval_s > 0.0) {
        return lead;
    }
    (lead - (delay_s / interval_s).fract()).rem_euclid(1.0)
}

/// Lags the field of the motor currents by `lag` ([`FieldLag`]): the baseline's current-law
/// columns (all but the motors-off `reference` and a measured `current_a`) and the per-motor
/// field the scenario fixes.
fn lag_current_field(design: &mut Design, fixed: &mut [Vec3], lag: &FieldLag) {
    let mut xyz: [Vec<f64>; 3] = std::array::from_fn(|a| fixed.iter().map(|v| v[a]).collect());
    let mut columns: Vec<&mut [f64]> = design.current_law_columns_mut().collect();
    columns.extend(xyz.iter_mut().map(|c| c.as_mut_slice()));
    lag.apply(&mut columns);
    for (r, v) in fixed.iter_mut().enumerate() {
        *v = Vec3::new(xyz[0][r], xyz[1][r], xyz[2][r]);
    }
}

/// A lag of the currents' field, for the columns of a replay (each command stepped in full at
/// its moment): `tau_s` behind a spin-up of `spinup_s` (none where 0), the two first-order
/// lags in series, each change acting from `lead` of its interval.
enum FieldLag<'t> {
    /// Behind a spin-up: its factors, made once for every column a design lags.
    BehindSpinup(Arc<SeriesLag>),
    /// No spin-up: the field's lag alone.
    Alone {
        t_s: &'t [f64],
        tau_s: f64,
        lead: f64,
    },
}

impl<'t> FieldLag<'t> {
    /// The lag over `t_s`, its factors from `cache` where they were made before.
    fn new(cache: &SeriesLagCache, t_s: &'t [f64], spinup_s: f64, tau_s: f64, lead: f64) -> Self {
        if spinup_s > 0.0 {
            FieldLag::BehindSpinup(cache.get_or_make(t_s, spinup_s, tau_s, lead))
        } else {
            FieldLag::Alone { t_s, tau_s, lead }
        }
    }

    /// Lags `columns` in place, each from its first value.
    fn apply(&self, columns: &mut [&mut [f64]]) {
        match self {
            FieldLag::BehindSpinup(series) => series.apply(columns),
            FieldLag::Alone { t_s, tau_s, lead } => {
                crate::effects::lag_in_place(t_s, columns, *tau_s, *lead)
            }
        }
    }
}

/// The factors of the field's lags already made ([`SeriesLag`]), by the times, time
/// constants and lead they were made for: every candidate beside a lagging field, and every
/// step of a search of anything but the lag, lags its columns the same way. A few of the
/// latest are kept, within [`SERIES_LAG_CACHE_BYTES`].
#[derive(Default)]
pub(crate) struct SeriesLagCache(LatestKept<SeriesLagKey, SeriesLag>);

/// What a [`SeriesLag`] depends on.
struct SeriesLagKey {
    t_s: Vec<f64>,
    bits: [u64; 3],
}

/// Most factor sets a [`SeriesLagCache`] keeps.
const SERIES_LAGS_KEPT: usize = 4;

/// Memory the kept factor sets may take, bytes (a long log keeps fewer, at least the latest).
const SERIES_LAG_CACHE_BYTES: usize = 64 << 20;

impl SeriesLagCache {
    /// The factors of `first_s` then `then_s` over `t_s` at `lead`, made unless kept (the
    /// times compared where kept, copied only for factors made).
    fn get_or_make(&self, t_s: &[f64], first_s: f64, then_s: f64, lead: f64) -> Arc<SeriesLag> {
        let bits = [first_s.to_bits(), then_s.to_bits(), lead.to_bits()];
        self.0.get_or_make(
            |k| k.bits == bits && k.t_s == t_s,
            || SeriesLagKey {
                t_s: t_s.to_vec(),
                bits,
            },
            || SeriesLag::new(t_s, first_s, then_s, lead),
            |factors| {
                let bytes = (std::mem::size_of_val(t_s) + factors.bytes()).max(1);
                (SERIES_LAG_CACHE_BYTES / bytes).clamp(1, SERIES_LAGS_KEPT)
            },
        )
    }
}

/// Where the currents' field lags, a field that is not linear in the current (steel near the
/// sensor, magnetised by the total current) follows the lagged current through its curve,
/// while the lagged current-law columns give the lag of that curve. For a curve of curvature
/// `k` the two differ by `k / 2` times this column: the square of the lagged motor current
/// less the lag of its square, A² (zero while the current holds, largest behind each step).
/// The current is the replay's (less the avionics' `avionics_a`), whose shape is the nominal
/// law's: a second-order term needs no more. The lag is the field's, `lag`.
fn square_behind_lag(trace: &Trace, avionics_a: f64, lag: &FieldLag) -> Vec<f64> {
    let mut current: Vec<f64> = trace.total_a.iter().map(|a| a - avionics_a).collect();
    let mut square: Vec<f64> = current.iter().map(|a| a * a).collect();
    lag.apply(&mut [&mut current, &mut square]);
    current
        .iter()
        .zip(&square)
        .map(|(a, sq)| a * a - sq)
        .collect()
}

/// The column of the second order of a field nonlinear in a lagged current
/// ([`square_behind_lag`]).
const LAGGED_CURRENT_SQUARED: &str = "lagged_current_squared_a2";

/// The terms as (effect, parameters) pairs, as [`build`] takes them.
pub(crate) fn as_refs<'a>(terms: &'a [Term<'a>]) -> Vec<(&'a dyn Effect, &'a [f64])> {
    terms
        .iter()
        .map(|t| (t.effect, t.theta.as_slice()))
        .collect()
}

/// Weighted chi-square of the identification rows for `terms` under `weights`, or None where
/// the design cannot be fitted: what every nonlinear search minimizes.
pub(crate) fn chi2_of(
    ctx: &Context,
    terms: &[(&dyn Effect, &[f64])],
    lead: f64,
    weights: &Weights,
) -> Option<f64> {
    fitted_with(ctx, terms, lead, weights).map(|f| f.chi2_fit)
}

/// The weighted fit of `terms` on the identification rows, or None where it cannot be fitted.
pub(crate) fn fitted_with(
    ctx: &Context,
    terms: &[(&dyn Effect, &[f64])],
    lead: f64,
    weights: &Weights,
) -> Option<Fitted> {
    let b = build_with_lead(ctx, terms, lead);
    fit(
        &b.design,
        &ctx.rec.mag_ut,
        Some(&b.fixed),
        weights,
        &ctx.split.holdout,
    )
    .ok()
}

/// A model of some terms, fitted with weights from its own residuals.
pub(crate) struct ModelFit {
    pub(crate) built: Built,
    pub(crate) fitted: Fitted,
    pub(crate) weights: Weights,
    /// The residual variance law on the held-out rows.
    pub(crate) noise: VarianceModel,
}

/// Fits the model of `terms` with weights from its own residuals (one reweighting pass).
pub(crate) fn fit_model(
    ctx: &Context,
    terms: &[Term],
    weights: Option<&Weights>,
) -> Result<ModelFit, DiagnoseError> {
    let y = &ctx.rec.mag_ut;
    let built = build(ctx, &as_refs(terms));
    use magstand_ident::least_squares::SolveError;
    let singular = |e: SolveError| DiagnoseError::Singular {
        origin: ctx.rec_origin.clone(),
        message: match e {
            SolveError::NoData => "no rows to fit".into(),
            SolveError::Singular { column, .. } => format!(
                "regressor `{}` is not determined: the recording needs motors off and at least \
                 four distinct throttle levels",
                built.design.names.get(column).map_or("?", String::as_str)
            ),
        },
    };
    let unit = Weights(vec![[1.0; 3]; y.len()]);
    // The weights the model's parameters were searched with.
    let searched = weights.unwrap_or(&unit);
    let first = fit(&built.design, y, None, searched, &ctx.split.holdout).map_err(singular)?;
    // The load as this model's physics has it (a delay or a lag moves it too).
    let q = &built.load;
    let var = VarianceModel::fit(&first.residuals(y), q, &ctx.split.holdout);
    let w = var.weights(q, &timing_spread(ctx, terms, &first.coef));
    // Weights from the model's own residuals can leave a term's columns too little weight to
    // be told apart (a battery's voltage columns once a dead zone is calibrated below every
    // command: a hexacopter at 200 Hz): the model then keeps the weights it was searched with.
    let (fitted, w) = match fit(&built.design, y, Some(&built.fixed), &w, &ctx.split.holdout) {
        Ok(fitted) => (fitted, w),
        Err(SolveError::Singular { .. }) => {
            let fitted = fit(
                &built.design,
                y,
                Some(&built.fixed),
                searched,
                &ctx.split.holdout,
            )
            .map_err(singular)?;
            (fitted, searched.clone())
        }
        Err(e) => return Err(singular(e)),
    };
    // What a model file promises for a new recording is the error on rows the fit did not
    // see, so its noise law comes from the held-out rows (the weights above must not).
    let skip_identification: Vec<bool> = ctx.split.holdout.iter().map(|h| !h).collect();
    let noise = VarianceModel::fit(&fitted.residuals(y), q, &skip_identification);
    Ok(ModelFit {
        built,
        fitted,
        weights: w,
        noise,
    })
}

/// The spread of a model's prediction between the two extreme moments at which each logged
/// command change could have happened (start or end of its interval): it sets the timing part
/// of every row's variance.
///
/// Where the model holds a late magnetometer (`time_offset`), the extremes are also one
/// sample interval either side of the fitted delay: a log does not say whether a logged
/// command acted from its own row on or before it, so the delay is known to an interval
/// either way (its reported sd holds that), and a row that straddles a step under one
/// reading does not under the other. Without it, one such row could decide a calibration: on
/// the independent generator's default stand at 50 Hz with a 0.3 s late magnetometer (seed 13,
/// unstated), the delay fitted at 0.282 s, one sample early, left a single row 14 rows after
/// a step down to a command of 0.18 off by 34.85 µT; at that low a load the noise law's
/// variance is near its floor, the row weighed some 190,000 in the chi-square, and the dead
/// zone was calibrated at 0.19891 ± 0.00060 above that level (the motors coasting down
/// undriven in the replay) for the generator's 0.12. Now 0.129 ± 0.040.
pub(crate) fn timing_spread(ctx: &Context, terms: &[Term], coef: &[[f64; 3]]) -> Vec<Vec3> {
    use crate::effects::{Effect, TimeOffset};
    let dt = ctx.rec.typical_interval_s();
    let delay = terms
        .iter()
        .position(|t| t.effect.name() == TimeOffset.name());
    // The design with the delay moved by `by` (a later delay shows each change later) and
    // each change at `lead` of its interval.
    let build_at = |by: f64, lead: f64| {
        let moved: Vec<f64>;
        let mut refs = as_refs(terms);
        if let Some(d) = delay {
            moved = terms[d].theta.iter().map(|v| v + by).collect();
            refs[d].1 = &moved;
        }
        build_with_lead(ctx, &refs, lead)
    };
    let (early, late) = (build_at(-dt, 0.0), build_at(dt, 1.0));
    let (a, b) = (early.design.predict(coef), late.design.predict(coef));
    (0..a.len())
        .map(|r| (b[r] + late.fixed[r]) - (a[r] + early.fixed[r]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use magstand_core::Recording;

    /// A lag of the currents' field stated in the scenario (`motors.current_lag_s`, as the
    /// augmented scenario of a `current_lag` finding slower than any spin-up writes it) had
    /// the lagged law columns but not the finding's second order of a field nonlinear in the
    /// current (`lagged_current_squared_a2`): rediagnosed on its own augmented scenario, a
    /// recording's baseline was not the model the finding had. Now the stated lag's design is
    /// the finding's, column for column and bit for bit (the spin-up behind it the fastest
    /// searched, as the finding sets an unstated one).
    #[test]
    fn a_stated_lag_of_the_currents_field_is_the_design_the_finding_had() {
        let tau_s = 0.8;
        let found = crate::effects::TestStand::drifting_stair(2000)
            .with_nominal(|s| s.motors.spinup_tau_s = 0.001);
        let stated = crate::effects::TestStand::drifting_stair(2000).with_nominal(|s| {
            s.motors.spinup_tau_s = 0.001;
            s.motors.current_lag_s = tau_s;
        });
        let lag = crate::effects::find("current_lag", None).unwrap();
        let with_finding = build(&found.context(), &[(lag, &[tau_s])]);
        let with_statement = build(&stated.context(), &[]);
        assert_eq!(
            with_statement.design.names, with_finding.design.names,
            "the stated lag's columns against the finding's"
        );
        for (name, (a, b)) in with_statement.design.names.iter().zip(
            with_statement
                .design
                .columns
                .iter()
                .zip(&with_finding.design.columns),
        ) {
            let bits = |c: &[f64]| c.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert!(bits(a) == bits(b), "column {name} differs");
        }
        let square = with_statement
            .design
            .names
            .iter()
            .position(|n| n == LAGGED_CURRENT_SQUARED);
        assert!(
            square.is_some_and(|k| with_statement.design.columns[k]
                .iter()
                .any(|v| v.abs() > 1e-3)),
            "the second order is all but zero: {square:?}"
        );
    }

    /// A command stepped from 0 to 1 at 1.0075 s (a quarter of the 0.01 s interval before the
    /// row at 1.01 s), read by a magnetometer late by 0.3, 0.305 and 0.3125 s (whole intervals,
    /// and half and three quarters more): the field lagged over the reads, with the change
    /// placed by [`lead_between_reads`], is the first-order step response `1 - exp(-(t - t0)
    /// / tau)` at every read's time, to rounding. With the commands' own lead instead, a read
    /// late by half an interval more takes the step half an interval off.
    #[test]
    fn a_lag_over_a_late_magnetometers_reads_steps_where_the_command_did() {
        let (interval_s, tau_s, lead) = (0.01, 0.5, 0.25);
        let switch_s = 1.01 - lead * interval_s;
        let t_s: Vec<f64> = (0..400).map(|k| k as f64 * interval_s).collect();
        for delay_s in [0.3, 0.305, 0.3125] {
            let reads: Vec<f64> = t_s.iter().map(|t| t - delay_s).collect();
            let stepped = |lead: f64| {
                let mut column: Vec<f64> = reads
                    .iter()
                    .map(|&t| if t >= switch_s { 1.0 } else { 0.0 })
                    .collect();
                crate::effects::lag_in_place(&t_s, &mut [&mut column], tau_s, lead);
                column
            };
            let placed = stepped(lead_between_reads(interval_s, delay_s, lead));
            for (r, (&t, &got)) in reads.iter().zip(&placed).enumerate() {
                let want = if t > switch_s {
                    1.0 - (-(t - switch_s) / tau_s).exp()
                } else {
                    0.0
                };
                assert!(
                    (got - want).abs() < 1e-9,
                    "delay {delay_s} s, read {r} at {t} s: lagged {got}, the step response {want}"
                );
            }
            if delay_s == 0.305 {
                let unplaced = stepped(lead);
                let worst = unplaced
                    .iter()
                    .zip(&placed)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(
                    worst > 1e-3,
                    "the commands' lead placed the step as well: {worst}"
                );
            }
        }
        assert_eq!(lead_between_reads(interval_s, 0.0, lead), lead);
    }

    /// Regression, twice. With `bat_v` logged, `battery_sag` first rebuilt the baseline's current
    /// law from the replay for its columns (the voltage's change times each law column), beside
    /// the one the design had just built: where a slow current lag lags the currents' field,
    /// the design's law is lagged and the rebuilt one was not, so the battery's columns followed
    /// a current the model no longer had. They then became the design's lagged law times the
    /// change, which moved the voltage's part of each step a lag early (the independent
    /// generator's battery beside a 0.5 s lag got `unexplained` or `dead_zone`): the current
    /// that lags is the one the voltage drives. They are now the law before the lag times the
    /// change, lagged with the law. So, on a voltage that steps once (a load switched on) with
    /// the commands held: before the step the columns are the lagged law times the change (a
    /// constant change passes through the lag); at the row after it they have moved by the
    /// lag's share of one row only; seconds after it, by all of it.
    #[test]
    fn the_battery_follows_the_law_the_model_has() {
        let t_s: Vec<f64> = (0..3000).map(|k| k as f64 * 0.02).collect();
        let thr: Vec<f64> = t_s
            .iter()
            .map(|t| ((t / 3.0).floor() % 9.0 + 1.0) / 10.0)
            .collect();
        // The voltage steps down 30.5 s in, halfway through a stair.
        let step_s = 30.5;
        let bat_v: Vec<f64> = t_s
            .iter()
            .map(|&t| if t < step_s { 12.6 } else { 11.0 })
            .collect();
        let rows = t_s.len();
        let stand = crate::effects::TestStand::new(Recording {
            mag_ut: vec![Vec3::zeros(); rows],
            thr: vec![thr],
            overall_only: true,
            bat_v: Some(bat_v.clone()),
            t_s: t_s.clone(),
            ..Default::default()
        });
        let ctx = stand.context();
        let effect =
            |name: &str| crate::effects::find(name, None).unwrap_or_else(|| panic!("no {name}"));
        let (lag, battery) = (effect("current_lag"), effect("battery_sag"));
        let tau_s = 0.8;
        let lagged = build(&ctx, &[(lag, &[tau_s]), (battery, &[])]);
        let plain = build(&ctx, &[(battery, &[])]);
        let reference_v = ctx.nominal.supply.no_load_voltage_v();
        let change = |r: usize| (bat_v[r] - reference_v) / reference_v;
        // The baseline's own columns: those before the first term's.
        let baseline = Design {
            names: lagged.design.names[..lagged.term_columns[0].start].to_vec(),
            columns: lagged.design.columns[..lagged.term_columns[0].start].to_vec(),
        };
        // The driven motors' law: the stair's first step lies within the nominal dead zone,
        // whose armed motors' column the battery's change does not move.
        let all_law: Vec<(&str, &[f64])> = baseline.current_law_columns().collect();
        assert!(
            all_law
                .iter()
                .any(|(n, _)| *n == crate::fit::ARMED_IN_DEAD_ZONE),
            "the stair arms motors within their dead zone: {:?}",
            baseline.names
        );
        let law: Vec<(&str, &[f64])> = all_law
            .into_iter()
            .filter(|(n, _)| *n != crate::fit::ARMED_IN_DEAD_ZONE)
            .collect();
        let battery_columns = lagged.term_columns[1].clone();
        assert_eq!(
            battery_columns.len(),
            2 * law.len(),
            "two columns per law column (the voltage's change and its square)"
        );
        let at_step = t_s.iter().position(|&t| t >= step_s).unwrap();
        let settled = t_s.iter().position(|&t| t >= step_s + 8.0 * tau_s).unwrap();
        // The powers of the change whose columns carry the step.
        let mut moved = [false; 2];
        // The voltage's change, then its square, times each law column, in that order.
        let forms = [("voltage_change", 1), ("voltage_change_squared", 2)]
            .into_iter()
            .flat_map(|(prefix, power)| {
                law.iter()
                    .map(move |(name, law)| (prefix, power, name, law))
            });
        for ((prefix, power, name, law), k) in forms.zip(battery_columns.clone()) {
            let name = format!("{prefix}_x_{name}");
            assert_eq!(lagged.design.names[k], name);
            let column = &lagged.design.columns[k];
            let (before, after) = (change(at_step - 1).powi(power), change(at_step).powi(power));
            // What the voltage's step moves the column by, once through the lag.
            let full = law.iter().fold(0.0_f64, |m, v| m.max(v.abs())) * (after - before).abs();
            if full < 1e-9 {
                continue;
            }
            moved[power as usize - 1] = true;
            for r in 0..at_step {
                assert!(
                    (column[r] - law[r] * before).abs() <= 1e-9 * full,
                    "{name} row {r}, before the step: {} against the lagged law's {}",
                    column[r],
                    law[r] * before
                );
            }
            // Beyond what the lagged law moves by itself, the row after the step moves by the
            // lag's share of one row (2.5 %), where the change times the lagged law jumps.
            let by_step =
                column[at_step] - column[at_step - 1] - (law[at_step] - law[at_step - 1]) * before;
            let jump = law[at_step] * (after - before);
            assert!(
                by_step.abs() < 0.1 * jump.abs(),
                "{name}: the row after the voltage's step moved by {by_step}, the change times \
                 the lagged law by {jump}"
            );
            for r in settled..rows {
                assert!(
                    (column[r] - law[r] * after).abs() <= 1e-2 * full,
                    "{name} row {r}, {:.1} s after the step: {} against {}",
                    t_s[r] - step_s,
                    column[r],
                    law[r] * after
                );
            }
        }
        assert_eq!(
            moved, [true; 2],
            "law columns carrying the voltage's step, by the change's power"
        );
        // Without the lag the battery's first column differs.
        assert_ne!(
            plain.design.columns[plain.term_columns[0].start],
            lagged.design.columns[battery_columns.start],
            "the lag changed nothing"
        );
    }
}
