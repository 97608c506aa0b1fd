use magstand_sim::Scenario;
use magstand_sim::battery::{SupplyParams, lipo_cell_ocv_v};
use magstand_sim::replay::{Trace, replay};

use super::{Context, Effect, EffectFit, Param};
use crate::fit::{ARMED_IN_DEAD_ZONE, STRAIGHT_DISCHARGE};
use crate::optimize::{Search, minimize};

/// The supply is a battery whose voltage falls with the charge drawn and under load.
///
/// The catalog's form replays the nominal motor on a LiPo pack. Where no voltage is logged,
/// richer forms ([`Effect::richer`]) also free the discharge's shape and the current's
/// sensitivity to the voltage (`discharge_columns`), to first and then to second order in
/// the voltage's change, or drop the pack's constants altogether (`drawn_charge_columns`);
/// each is kept only where it lowers the held-out error significantly beyond the catalog's.
/// A free form whose resistance runs to the lower end of its range stands for the same form
/// without a sag under load ([`Effect::edge_limit`]).
pub struct BatterySag {
    form: Form,
}

/// The forms of [`BatterySag`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum Form {
    /// The catalog's: the nominal motor on a LiPo pack of searched resistance and capacity.
    Lipo,
    /// The discharge's shape and the current's sensitivity to it free, to `order` in the
    /// voltage's change, at a searched capacity and, where `sag`, resistance. Without: a sag
    /// under load that follows the commands at once is a function of them, which the
    /// calibrated current law holds, so the resistance may not be identifiable.
    FreeDischarge {
        /// Order in the voltage's change.
        order: u8,
        /// Whether the resistance is searched.
        sag: bool,
    },
    /// The field's change at a command proportional to the charge drawn, with no constant of
    /// the pack: where the run neither empties it nor crosses the bends of its curve, its
    /// resistance and capacity are not identifiable without `bat_v`.
    DrawnCharge,
}

impl BatterySag {
    /// The catalog's form: the nominal motor on a LiPo pack.
    pub const NOMINAL: BatterySag = BatterySag { form: Form::Lipo };
}

/// The richer forms, with their names in a model file.
static RICHER_FORMS: [(BatterySag, &str); 5] = [
    (
        BatterySag {
            form: Form::FreeDischarge {
                order: 1,
                sag: true,
            },
        },
        "free_discharge",
    ),
    (
        BatterySag {
            form: Form::FreeDischarge {
                order: 2,
                sag: true,
            },
        },
        "free_discharge_second_order",
    ),
    (
        BatterySag {
            form: Form::FreeDischarge {
                order: 1,
                sag: false,
            },
        },
        "free_discharge_no_sag",
    ),
    (
        BatterySag {
            form: Form::FreeDischarge {
                order: 2,
                sag: false,
            },
        },
        "free_discharge_no_sag_second_order",
    ),
    (
        BatterySag {
            form: Form::DrawnCharge,
        },
        "drawn_charge",
    ),
];

/// The richer forms ([`RICHER_FORMS`]), for a model file that names one.
pub(crate) fn richer_forms() -> impl Iterator<Item = &'static dyn Effect> {
    RICHER_FORMS.iter().map(|(form, _)| form as &dyn Effect)
}

/// The richer form `form` of [`RICHER_FORMS`].
fn richer_form(form: Form) -> &'static dyn Effect {
    RICHER_FORMS
        .iter()
        .find(|(b, _)| b.form == form)
        .map(|(b, _)| b as &dyn Effect)
        .expect("every richer form is listed")
}

nonlinear_params! {
    /// The battery standing in for the supply: searched where no voltage is logged, fitted
    /// to `bat_v` where it is.
    Battery {
        /// Internal resistance, ohm.
        internal_resistance_ohm,
        /// Capacity, Ah.
        capacity_ah,
    }
}

const RESISTANCE_SEARCH: Search = Search {
    name: "internal_resistance_ohm",
    unit: "ohm",
    lo: 0.003,
    hi: 0.3,
    log: true,
    points: 9,
};

const CAPACITY_SEARCH: Search = Search {
    name: "capacity_ah",
    unit: "Ah",
    lo: 0.3,
    hi: 30.0,
    log: true,
    points: 9,
};

/// The battery standing in for the supply: cells in series and the charge it starts with.
/// With `bat_v` logged, the pack the highest logged voltage implies (cells at a nominal 3.9 V
/// each, the charge at which that many cells rest at that voltage): a 4S pack logged at
/// 16.8 V is not the nominal 12 V supply's 3S. Otherwise the nominal battery's cells, or the
/// number whose 3.9 V per cell is nearest the bench voltage, full.
fn pack(ctx: &Context) -> (u32, f64) {
    pack_and_whether_known(ctx).0
}

/// [`pack`], and whether its cells are known: from the logged voltage, or from the supply's
/// cells or voltage where the scenario states them. Otherwise they are the nominal supply's,
/// a starting point rather than a claim about the stand: the data see the voltage's relative
/// fall only, which the same resistance per cell gives on any number of cells.
fn pack_and_whether_known(ctx: &Context) -> ((u32, f64), bool) {
    let cells_at = |v: f64| ((v / 3.9).round() as u32).clamp(1, 14);
    let logged_max = ctx
        .rec
        .bat_v
        .as_deref()
        .and_then(|v| v.iter().copied().filter(|x| x.is_finite()).reduce(f64::max))
        .filter(|v| *v > 0.0);
    match (logged_max, &ctx.nominal.supply) {
        (Some(v), _) => {
            let cells = cells_at(v);
            ((cells, charge_resting_at(v / cells as f64)), true)
        }
        (None, SupplyParams::Battery { cells, .. }) => {
            ((*cells, 1.0), ctx.nominal.states("supply.cells"))
        }
        (None, SupplyParams::Bench { voltage_v, .. }) => (
            (cells_at(*voltage_v), 1.0),
            ctx.nominal.states("supply.voltage_v"),
        ),
    }
}

/// The state of charge at which a LiPo cell rests at `cell_v` (0 below the empty cell's
/// voltage, 1 above the full one's), by bisection of the simulator's curve.
fn charge_resting_at(cell_v: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if lipo_cell_ocv_v(mid) < cell_v {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Puts the battery `b` of `(cells, initial_charge)` ([`pack`]) in for the supply.
fn set_battery(ctx: &Context, (cells, initial_charge): (u32, f64), s: &mut Scenario, b: Battery) {
    s.supply = SupplyParams::Battery {
        cells,
        capacity_ah: b.capacity_ah,
        internal_resistance_ohm: b.internal_resistance_ohm,
        initial_charge,
        avionics_current_a: ctx.nominal.supply.avionics_current_a(),
    };
}

impl BatterySag {
    /// The battery of searched parameters `theta`: without a sag under load, no resistance.
    fn battery(&self, theta: &[f64]) -> Option<Battery> {
        match (self.form, theta) {
            (Form::FreeDischarge { sag: false, .. }, &[capacity_ah]) => Some(Battery {
                internal_resistance_ohm: 0.0,
                capacity_ah,
            }),
            (Form::FreeDischarge { sag: false, .. }, _) => None,
            _ => Battery::from_slice(theta),
        }
    }

    /// With `bat_v` recorded, the battery that reproduces it best through the replayed
    /// currents (chi-square with a 10 mV voltage error): the simulator's motors' currents, so
    /// that the augmented scenario gives the logged voltage. On a stand whose motors draw
    /// another current its constants are in the simulator's units, not the pack's
    /// ([`logged_pack`] gives those where `bat_a` is logged).
    fn fit_to_recorded_voltage(&self, ctx: &Context, s: &Scenario) -> Option<Battery> {
        let v = ctx.rec.bat_v.as_deref()?;
        let logged_pack = pack(ctx);
        let o = minimize(&[RESISTANCE_SEARCH, CAPACITY_SEARCH], |theta| {
            let mut b = s.clone();
            set_battery(ctx, logged_pack, &mut b, Battery::from_slice(theta)?);
            let tr = replay(&b, &ctx.rec.t_s, &ctx.rec.thr, None, ctx.command_lead);
            Some(
                tr.voltage_v
                    .iter()
                    .zip(v)
                    .map(|(a, b)| ((a - b) / 0.01).powi(2))
                    .sum(),
            )
        })?;
        Battery::from_slice(&o.theta)
    }
}

impl Effect for BatterySag {
    fn name(&self) -> &'static str {
        "battery_sag"
    }
    fn variant(&self) -> Option<&'static str> {
        RICHER_FORMS
            .iter()
            .find(|(b, _)| b.form == self.form)
            .map(|(_, name)| *name)
    }
    fn richer(&self, ctx: &Context) -> Vec<&'static dyn Effect> {
        // With `bat_v` the voltage is the log's; a flight follows its logged current,
        // whatever the voltage did to it.
        if ctx.rec.bat_v.is_some() || ctx.follow_recorded_current {
            return Vec::new();
        }
        match self.form {
            Form::Lipo => vec![
                richer_form(Form::FreeDischarge {
                    order: 1,
                    sag: true,
                }),
                richer_form(Form::DrawnCharge),
            ],
            Form::FreeDischarge { order: 1, sag } => {
                vec![richer_form(Form::FreeDischarge { order: 2, sag })]
            }
            Form::FreeDischarge { .. } | Form::DrawnCharge => Vec::new(),
        }
    }
    fn edge_limit(&self, parameter: &str, lower: bool) -> Option<&'static dyn Effect> {
        // The free forms' resistance at its lowest: no sag under load beyond what the
        // calibrated current law holds (the capacity stays, where the run empties the pack or
        // crosses a bend of its curve; where it does neither, `drawn_charge` stands for it).
        // The catalog's capacity at its largest: the run's charge moves the pack's voltage
        // less than any capacity in range makes it, so the capacity only scales a fall the
        // data cannot place on the LiPo curve; `drawn_charge` has the fall's size free and
        // no constant of the pack.
        match self.form {
            Form::FreeDischarge { order, sag: true }
                if lower && parameter == RESISTANCE_SEARCH.name =>
            {
                Some(richer_form(Form::FreeDischarge { order, sag: false }))
            }
            Form::Lipo if !lower && parameter == CAPACITY_SEARCH.name => {
                Some(richer_form(Form::DrawnCharge))
            }
            _ => None,
        }
    }
    fn explanation(&self) -> &'static str {
        "The battery voltage falls with the charge drawn and sags under load, so at a fixed \
         command the motor currents, and the field they make, drift down over a run."
    }
    fn parameters(&self) -> &'static [&'static str] {
        match self.form {
            Form::DrawnCharge => &[],
            Form::FreeDischarge { sag: false, .. } => &Battery::NAMES[1..],
            _ => Battery::NAMES,
        }
    }
    fn search(&self, ctx: &Context) -> Vec<Search> {
        if ctx.rec.bat_v.is_some() {
            return Vec::new();
        }
        match self.form {
            Form::DrawnCharge => Vec::new(),
            Form::FreeDischarge { sag: false, .. } => vec![CAPACITY_SEARCH],
            _ => vec![RESISTANCE_SEARCH, CAPACITY_SEARCH],
        }
    }
    fn apply(&self, ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if ctx.rec.bat_v.is_none()
            && let Some(b) = self.battery(theta)
        {
            set_battery(ctx, pack(ctx), s, b);
        }
    }
    fn uses_recorded_voltage(&self, ctx: &Context) -> bool {
        ctx.rec.bat_v.is_some()
    }
    fn changes_the_currents(&self, ctx: &Context) -> bool {
        // On a stand its columns are the current law's times the supply's change; a flight's
        // logged current already holds the voltage's effect and any lag.
        !ctx.follow_recorded_current
    }
    fn regressors(
        &self,
        ctx: &Context,
        trace: &Trace,
        law: &[(&str, &[f64])],
        theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        // With the voltage logged, the replay follows it through the nominal motor, whose
        // current grows about as the voltage squared at a fixed command (speed with the
        // voltage, propeller load with the speed squared). Another stand's current may follow
        // its voltage more or less steeply, and its field may be a nonlinear function of the
        // current: neither is stated. To first order in the voltage's relative change, the
        // field at a command then moves by the change times a combination of the current law's
        // own columns (a law in powers of speed holds the current times its derivative), so
        // each of them times the change enters with a free gain: the driven motors' columns
        // ([`driven_law`]), with `bat_v` and without it.
        let law = driven_law(law);
        let law = law.as_slice();
        let Some(v) = ctx.rec.bat_v.as_deref() else {
            return match (self.form, self.battery(theta)) {
                (Form::FreeDischarge { order, .. }, Some(b)) => {
                    discharge_columns(ctx, trace, law, b.capacity_ah, order)
                }
                (Form::DrawnCharge, _) => drawn_charge_columns(trace, law),
                _ => Vec::new(),
            };
        };
        // Relative to the nominal supply's no-load voltage, a constant of the model (not of
        // the recording), so that a model file predicts a new recording with the same columns.
        let reference_v = ctx.nominal.supply.no_load_voltage_v();
        if !(reference_v > 0.0) {
            return Vec::new();
        }
        let change = v.iter().map(|v| (v - reference_v) / reference_v);
        if ctx.follow_recorded_current {
            // A flight logs its current: the voltage's effect on it is in the log, and what is
            // left is how steeply the field follows it at the voltage, one column.
            let avionics = ctx.nominal.supply.avionics_current_a();
            return vec![(
                "current_x_voltage_change".into(),
                trace
                    .total_a
                    .iter()
                    .zip(change)
                    .map(|(a, d)| (a - avionics) * d)
                    .collect(),
            )];
        }
        // The baseline's own current-law columns, before any lag of the currents' field (the
        // design lags these columns with it: `changes_the_currents`).
        let change: Vec<f64> = change.collect();
        let change = &change;
        // To second order: each column times the change, and times its square.
        [("voltage_change", 1), ("voltage_change_squared", 2)]
            .into_iter()
            .flat_map(|(prefix, power)| {
                law.iter().map(move |(name, law)| {
                    (
                        format!("{prefix}_x_{name}"),
                        law.iter()
                            .zip(change)
                            .map(|(x, d)| (0..power).fold(*x, |v, _| v * d))
                            .collect(),
                    )
                })
            })
            .collect()
    }
    fn switch_on(&self, ctx: &Context, s: &mut Scenario, f: &EffectFit) -> Vec<Param> {
        if self.form == Form::DrawnCharge {
            // No constant of the pack is fitted (nor its cells, which only the supply's
            // voltage would tell): the supply stays as stated.
            return Vec::new();
        }
        let (pack, cells_known) = pack_and_whether_known(ctx);
        let cells = Param::new("cells", pack.0 as f64, None, "cells in series");
        let fitted = if ctx.rec.bat_v.is_none() {
            self.battery(f.theta)
        } else {
            self.fit_to_recorded_voltage(ctx, s)
        };
        // The searches' sds are not reported: they are conditional on the LiPo curve and on
        // the simulator's motors, which nobody stated (see the bases below).
        let Some(b) = fitted else {
            return Vec::new();
        };
        set_battery(ctx, pack, s, b);
        // No sd: the curvature's would be conditional on a discharge curve nobody stated.
        let capacity = Param::new("capacity_ah", b.capacity_ah, None, "Ah").resting_on(LIPO_BASIS);
        if matches!(self.form, Form::FreeDischarge { sag: false, .. }) {
            // The resistance was not fitted: whatever sag follows the commands at once is in
            // the calibrated current law.
            return std::iter::once(capacity)
                .chain(cells_known.then_some(cells))
                .collect();
        }
        // With the voltage and the current logged, the pack's load and fall are the log's own.
        if let Some([resistance, fall]) = logged_pack(ctx, pack.0) {
            return vec![resistance, fall, capacity, cells];
        }
        // Otherwise the sag is seen through the simulator's motors' current: another stand's
        // motors draw another, and the resistance scales with it.
        let per_cell = if cells_known { 1.0 } else { pack.0 as f64 };
        let resistance = Param::new(
            if cells_known {
                "internal_resistance_ohm"
            } else {
                // Only the voltage's relative fall is seen: the resistance over the cells'
                // voltage, not the pack's resistance, whose cells nobody stated.
                "internal_resistance_per_cell_ohm"
            },
            b.internal_resistance_ohm / per_cell,
            None,
            "ohm",
        )
        .resting_on(MOTOR_CURRENT_BASIS);
        std::iter::once(resistance)
            .chain([capacity])
            .chain(cells_known.then_some(cells))
            .collect()
    }
}

/// What a reported capacity rests on.
const LIPO_BASIS: &str = "the simulator's LiPo discharge curve (3.27 V empty to 4.2 V full per cell, a \
     plateau between), drawn by the simulator's motors: the pack's chemistry is not stated, and on \
     another curve, or with motors that draw another current, the same data give another capacity. \
     It is the augmented scenario's, which reproduces the recording in the simulator; where \
     open_circuit_fall_per_cell_v_per_ah is reported, that is the pack's own";

/// What a resistance seen without the logged current rests on.
const MOTOR_CURRENT_BASIS: &str = "the simulator's motors' current (bat_v and bat_a are not both \
     logged): a stand whose motors draw another current at the same commands has another \
     resistance for the same sag";

/// With `bat_v` and `bat_a` logged, the pack through its own log, whatever its chemistry and
/// whatever the motors draw: the logged voltage as a straight line in the charge drawn (the
/// logged current's integral) and the current, by least squares ([`pack_line`]). Its internal
/// resistance, ohm, and the open-circuit voltage's mean fall per cell per ampere-hour drawn
/// over the run, V/Ah. A pack's curve is not a straight line (it bends, and it flattens once
/// empty), so the sds add to the fit's the spread between the two halves of the run, each
/// fitted on its own, as the replication of a name does. None where the log does not
/// determine them (no charge drawn, or a current that does not vary).
fn logged_pack(ctx: &Context, cells: u32) -> Option<[Param; 2]> {
    let (v, i) = (ctx.rec.bat_v.as_deref()?, ctx.rec.bat_a.as_deref()?);
    let drawn: Vec<f64> = charge_drawn_ah(&ctx.rec.t_s, i).collect();
    let rows: Vec<usize> = (0..v.len())
        .filter(|&k| v[k].is_finite() && i[k].is_finite() && drawn[k].is_finite())
        .collect();
    let line = |rows: &[usize]| pack_line(rows.iter().map(|&k| (drawn[k], i[k], v[k])));
    let whole = line(&rows)?;
    let (first, second) = rows.split_at(rows.len() / 2);
    let (first, second) = (line(first)?, line(second)?);
    let sd = |j: usize| {
        let spread = 0.5 * (first.0[j] - second.0[j]);
        whole.1[j].hypot(spread)
    };
    let cells = cells as f64;
    let (resistance, fall) = (whole.0[1], whole.0[0] / cells);
    Some([
        Param::new("internal_resistance_ohm", resistance, Some(sd(1)), "ohm"),
        Param::new(
            "open_circuit_fall_per_cell_v_per_ah",
            fall,
            Some(sd(0) / cells),
            "V/Ah",
        ),
    ])
}

/// The least-squares line `v = v0 - fall * drawn - resistance * current` through `rows` of
/// `(drawn_ah, current_a, voltage_v)`: `([fall, resistance], [their sds])`, the sds from the
/// residuals widened for their lag-one correlation. None where the line is not determined
/// (fewer than four rows, a charge or current that does not vary) or not finite.
fn pack_line(rows: impl Iterator<Item = (f64, f64, f64)> + Clone) -> Option<([f64; 2], [f64; 2])> {
    let x = |(q, i, _): (f64, f64, f64)| nalgebra::Vector3::new(1.0, q, i);
    let mut normal = nalgebra::Matrix3::<f64>::zeros();
    let mut moment = nalgebra::Vector3::<f64>::zeros();
    let mut n = 0usize;
    for row in rows.clone() {
        normal += x(row) * x(row).transpose();
        moment += x(row) * row.2;
        n += 1;
    }
    let chol = normal.cholesky()?;
    let coef = chol.solve(&moment);
    let residuals: Vec<f64> = rows.map(|row| row.2 - x(row).dot(&coef)).collect();
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let rho = (residuals.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / rss).clamp(0.0, 0.99);
    let dof = n.checked_sub(3).filter(|&d| d > 0)? as f64;
    let variance = rss / dof * (1.0 + rho) / (1.0 - rho);
    // The diagonal of the inverse normal matrix, one unit column solved at a time.
    let sd = |j: usize| {
        let e = nalgebra::Vector3::from_fn(|r, _| if r == j { 1.0 } else { 0.0 });
        (chol.solve(&e)[j] * variance).sqrt()
    };
    let (value, sd) = ([-coef[1], -coef[2]], [sd(1), sd(2)]);
    value
        .iter()
        .chain(&sd)
        .all(|x| x.is_finite())
        .then_some((value, sd))
}

/// The current law's columns of the driven motors: all but [`ARMED_IN_DEAD_ZONE`]. A motor
/// armed within its dead zone is not driven; what it draws (the ESC holding it at idle) does
/// not follow the pack's voltage through the motor as a driven one's current does. That
/// column's count also hangs on the dead zone, which is itself often calibrated within a wide
/// sd: times the supply's change it gave the fit free gains on the few rows between the stand's
/// dead zone and the calibrated one, and no physics behind them.
fn driven_law<'a>(law: &[(&'a str, &'a [f64])]) -> Vec<(&'a str, &'a [f64])> {
    law.iter()
        .filter(|(name, _)| *name != ARMED_IN_DEAD_ZONE)
        .copied()
        .collect()
}

/// Without `bat_v`, the voltage's course over the run is the candidate's own, and two things
/// that shape it are not stated: the pack's discharge curve (the replay's is a LiPo cell's)
/// and how steeply the stand's current follows its voltage (the nominal motor's about as the
/// voltage squared). To first order in the open-circuit voltage's relative change, the field
/// at a command then moves by the change times a combination of the current law's columns.
/// The change is taken in two shapes, from the replay's charge drawn at the candidate's
/// capacity: the LiPo curve's, and a straight line between its empty and full cell voltages
/// (a pack whose curve has no plateau). Each law column times each shape enters with a free
/// gain, so a discharge curve between the two, and any first-order sensitivity of the
/// current to the voltage, are within the term's reach.
fn discharge_columns(
    ctx: &Context,
    trace: &Trace,
    law: &[(&str, &[f64])],
    capacity_ah: f64,
    order: u8,
) -> Vec<(String, Vec<f64>)> {
    let (_, start_charge) = pack(ctx);
    if !(capacity_ah > 0.0) {
        return Vec::new();
    }
    let (empty, full) = (lipo_cell_ocv_v(0.0), lipo_cell_ocv_v(1.0));
    let straight = |soc: f64| empty + (full - empty) * soc.clamp(0.0, 1.0);
    let (start_v, straight_start_v) = (lipo_cell_ocv_v(start_charge), straight(start_charge));
    let mut shapes = [
        Vec::with_capacity(trace.t_s.len()),
        Vec::with_capacity(trace.t_s.len()),
    ];
    for drawn_ah in charge_drawn_ah(&trace.t_s, &trace.total_a) {
        let soc = start_charge - drawn_ah / capacity_ah;
        shapes[0].push((lipo_cell_ocv_v(soc) - start_v) / start_v);
        shapes[1].push((straight(soc) - straight_start_v) / start_v);
    }
    // To second order, each shape's square too (a pack's voltage falls by a fifth or more
    // over a run that empties it, and a current linear in the voltage, replayed through the
    // nominal motor's quadratic one, leaves the square of that change).
    let powers = if order >= 2 { 2 } else { 1 };
    let shapes: Vec<(String, Vec<f64>)> = (1..=powers)
        .flat_map(|power| {
            let suffix = if power == 1 { "" } else { "_squared" };
            [LIPO_DISCHARGE, STRAIGHT_DISCHARGE]
                .into_iter()
                .zip(&shapes)
                .map(move |(prefix, shape)| {
                    let powered = shape.iter().map(|d| if power == 1 { *d } else { d * d });
                    (format!("{prefix}{suffix}"), powered.collect())
                })
        })
        .collect();
    shapes
        .iter()
        .flat_map(|(prefix, shape)| times_law(prefix, shape, law))
        .collect()
}

/// The charge a current `current_a` (the replay's or the logged one, at times `t_s`) drew by
/// each row, Ah, by the trapezoid rule over the rows (a replay's substeps are not kept).
fn charge_drawn_ah<'a>(t_s: &'a [f64], current_a: &'a [f64]) -> impl Iterator<Item = f64> + 'a {
    let mut drawn_ah = 0.0;
    (0..t_s.len()).map(move |k| {
        if k > 0 {
            let dt_s = t_s[k] - t_s[k - 1];
            drawn_ah += 0.5 * (current_a[k] + current_a[k - 1]) * dt_s / 3600.0;
        }
        drawn_ah
    })
}

/// Each of the current law's columns times `shape`, named `{prefix}_x_{column}`.
fn times_law<'a>(
    prefix: &'a str,
    shape: &'a [f64],
    law: &'a [(&str, &[f64])],
) -> impl Iterator<Item = (String, Vec<f64>)> + 'a {
    law.iter().map(move |(name, law)| {
        (
            format!("{prefix}_x_{name}"),
            law.iter().zip(shape).map(|(x, d)| x * d).collect(),
        )
    })
}

/// Without `bat_v`, where the run neither empties the pack nor crosses the bends of its
/// curve, its open-circuit voltage falls about in proportion to the charge drawn, and its
/// capacity only scales that fall, as the gains of [`discharge_columns`] do: it is not
/// identifiable, nor is a resistance whose sag follows the commands at once (the calibrated
/// current law holds that). To first order the field at a command then moves by the charge
/// drawn (the replay's, on the stated supply) times a combination of the law's columns: each
/// law column times the charge enters with a free gain, and no constant of the pack is
/// searched.
fn drawn_charge_columns(trace: &Trace, law: &[(&str, &[f64])]) -> Vec<(String, Vec<f64>)> {
    let drawn: Vec<f64> = charge_drawn_ah(&trace.t_s, &trace.total_a).collect();
    times_law(DRAWN_CHARGE, &drawn, law).collect()
}

/// Prefix of a battery's columns on the charge drawn ([`drawn_charge_columns`]).
const DRAWN_CHARGE: &str = "drawn_ah";

/// Prefix of a battery's columns on the LiPo curve's discharge ([`discharge_columns`]).
const LIPO_DISCHARGE: &str = "lipo_discharge";

#[cfg(test)]
mod tests {
    use super::*;

    /// A free form's resistance at its lowest stands for the same form without a sag, of the
    /// same order; nothing else has a limit form, and the form without a sag searches the
    /// capacity alone.
    #[test]
    fn a_resistance_at_its_lowest_stands_for_the_form_without_a_sag() {
        for order in [1, 2] {
            let with = BatterySag {
                form: Form::FreeDischarge { order, sag: true },
            };
            let limit = with
                .edge_limit("internal_resistance_ohm", true)
                .and_then(|e| e.variant());
            let expected = if order == 1 {
                "free_discharge_no_sag"
            } else {
                "free_discharge_no_sag_second_order"
            };
            assert_eq!(limit, Some(expected), "order {order}");
            assert!(with.edge_limit("internal_resistance_ohm", false).is_none());
            assert!(with.edge_limit("capacity_ah", true).is_none());
            let without = richer_form(Form::FreeDischarge { order, sag: false });
            assert_eq!(without.parameters(), ["capacity_ah"], "order {order}");
            assert!(without.edge_limit("capacity_ah", true).is_none());
        }
        assert!(
            BatterySag::NOMINAL
                .edge_limit("internal_resistance_ohm", true)
                .is_none()
        );
        let no_sag = BatterySag {
            form: Form::FreeDischarge {
                order: 1,
                sag: false,
            },
        };
        let b = no_sag.battery(&[2.5]).expect("one capacity");
        assert_eq!((b.internal_resistance_ohm, b.capacity_ah), (0.0, 2.5));
        assert!(no_sag.battery(&[0.03, 2.5]).is_none());
    }

    /// The pack's line through a logged voltage: a pack whose open-circuit voltage is straight
    /// in the charge gives its fall and resistance back; one that flattens once empty gives
    /// the run's mean fall with an sd that holds both halves' (the line's own sd alone would
    /// claim a precision the curve does not have).
    #[test]
    fn a_logged_pack_gives_its_fall_and_resistance_with_the_spread_of_its_curve() {
        let (fall, resistance) = (0.6, 0.04);
        let current = |k: usize| 5.0 + 20.0 * ((k / 50) % 4) as f64;
        let mut drawn = 0.0;
        let rows: Vec<(f64, f64, f64)> = (0..4000)
            .map(|k| {
                drawn += current(k) * 0.1 / 3600.0;
                // A deterministic noise of 2 mV.
                let noise = 0.002 * ((k as f64 * 1.7).sin());
                (
                    drawn,
                    current(k),
                    16.8 - fall * drawn - resistance * current(k) + noise,
                )
            })
            .collect();
        let (value, sd) = pack_line(rows.iter().copied()).expect("a determined line");
        assert!(
            (value[0] - fall).abs() < 1e-3 && (value[1] - resistance).abs() < 1e-4,
            "fall {} V/Ah and resistance {} ohm, expected {fall} and {resistance}",
            value[0],
            value[1]
        );
        assert!(sd[0] < 1e-3 && sd[1] < 1e-4, "{sd:?}");
        // No charge drawn, no fall to tell: not determined.
        let still: Vec<(f64, f64, f64)> = rows.iter().map(|&(_, i, v)| (0.0, i, v)).collect();
        assert!(pack_line(still.into_iter()).is_none());
        // Once empty the voltage no longer falls with the charge: the halves disagree.
        let empty_at = rows[2000].0;
        let flattened: Vec<(f64, f64, f64)> = rows
            .iter()
            .map(|&(q, i, _)| (q, i, 16.8 - fall * q.min(empty_at) - resistance * i))
            .collect();
        let (first, second) = flattened.split_at(2000);
        let (whole, halves) = (
            pack_line(flattened.iter().copied()).unwrap(),
            [first, second].map(|h| pack_line(h.iter().copied()).unwrap().0[0]),
        );
        let spread = 0.5 * (halves[0] - halves[1]);
        assert!(
            (halves[0] - fall).abs() < 1e-6 && halves[1].abs() < 1e-6,
            "halves' falls {halves:?}, expected {fall} and 0"
        );
        assert!(
            whole.0[0] > 0.0
                && whole.0[0] < fall
                && (whole.0[0] - fall).abs() < whole.1[0].hypot(spread) * 3.0,
            "the whole run's fall {:?} with the spread {spread} does not hold {fall}",
            whole
        );
    }

    /// Regression: with `bat_v` logged, the battery reported beside `battery_sag` had the
    /// nominal 12 V supply's three cells, full, whatever the log said; on a 4S pack logged at
    /// 16.8 V its resistance and capacity went to the ends of their ranges (0.003 ohm, 30 Ah).
    #[test]
    fn a_logged_voltage_gives_its_packs_cells_and_charge() {
        for (v, soc) in [
            (4.2, 1.0),
            (3.84, 0.5),
            (3.69, 0.1),
            (3.27, 0.0),
            (3.0, 0.0),
            (4.5, 1.0),
        ] {
            let c = charge_resting_at(v);
            assert!(
                (c - soc).abs() < 1e-9,
                "{v} V per cell: charge {c}, expected {soc}"
            );
        }
        let mid = charge_resting_at(3.855);
        assert!((lipo_cell_ocv_v(mid) - 3.855).abs() < 1e-9, "{mid}");
    }
}
