use magstand_sim::Scenario;
use magstand_sim::battery::{SupplyParams, lipo_cell_ocv_v};
use magstand_sim::replay::{Trace, replay};

use super::{Context, Effect, EffectFit, Param};
use crate::fit::STRAIGHT_DISCHARGE;
use crate::optimize::{Search, minimize};

/// The supply is a battery whose voltage falls with the charge drawn and under load.
///
/// The catalog's form replays the nominal motor on a LiPo pack. Where no voltage is logged,
/// richer forms ([`Effect::richer`]) also free the discharge's shape and the current's
/// sensitivity to the voltage ([`discharge_columns`]), to first and then to second order in
/// the voltage's change; each is kept only where it lowers the held-out error significantly
/// beyond the form before it.
pub struct BatterySag {
    /// 0 for the catalog's form; else the order in the voltage's change to which the
    /// discharge's shape and the current's sensitivity to it are free.
    free_order: u8,
}

impl BatterySag {
    /// The catalog's form: the nominal motor on a LiPo pack.
    pub const NOMINAL: BatterySag = BatterySag { free_order: 0 };
}

/// The richer forms, first and second order, with their names in a model file.
static FREE_DISCHARGE: [(BatterySag, &str); 2] = [
    (BatterySag { free_order: 1 }, "free_discharge"),
    (BatterySag { free_order: 2 }, "free_discharge_second_order"),
];

/// The richer forms ([`FREE_DISCHARGE`]), for a model file that names one.
pub(crate) fn free_discharge() -> impl Iterator<Item = &'static dyn Effect> {
    FREE_DISCHARGE.iter().map(|(form, _)| form as &dyn Effect)
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
            (cells, charge_resting_at(v / cells as f64))
        }
        (None, SupplyParams::Battery { cells, .. }) => (*cells, 1.0),
        (None, SupplyParams::Bench { voltage_v, .. }) => (cells_at(*voltage_v), 1.0),
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
    /// With `bat_v` recorded, the battery that reproduces it best through the replayed
    /// currents (chi-square with a 10 mV voltage error).
    fn fit_to_recorded_voltage(
        &self,
        ctx: &Context,
        s: &Scenario,
    ) -> Option<(Battery, Battery<Option<f64>>)> {
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
        Some((Battery::from_slice(&o.theta)?, Battery::from_slice(&o.sd)?))
    }
}

impl Effect for BatterySag {
    fn name(&self) -> &'static str {
        "battery_sag"
    }
    fn variant(&self) -> Option<&'static str> {
        let k = usize::from(self.free_order.checked_sub(1)?);
        FREE_DISCHARGE.get(k).map(|(_, name)| *name)
    }
    fn richer(&self, ctx: &Context) -> Option<&'static dyn Effect> {
        // With `bat_v` the voltage is the log's; a flight follows its logged current,
        // whatever the voltage did to it.
        let unlogged = ctx.rec.bat_v.is_none() && !ctx.follow_recorded_current;
        let (next, _) = FREE_DISCHARGE
            .get(usize::from(self.free_order))
            .filter(|_| unlogged)?;
        Some(next)
    }
    fn explanation(&self) -> &'static str {
        "The battery voltage falls with the charge drawn and sags under load, so at a fixed \
         command the motor currents, and the field they make, drift down over a run."
    }
    fn parameters(&self) -> &'static [&'static str] {
        Battery::NAMES
    }
    fn search(&self, ctx: &Context) -> Vec<Search> {
        if ctx.rec.bat_v.is_some() {
            Vec::new()
        } else {
            vec![RESISTANCE_SEARCH, CAPACITY_SEARCH]
        }
    }
    fn apply(&self, ctx: &Context, s: &mut Scenario, theta: &[f64]) {
        if ctx.rec.bat_v.is_none()
            && let Some(b) = Battery::from_slice(theta)
        {
            set_battery(ctx, pack(ctx), s, b);
        }
    }
    fn uses_recorded_voltage(&self, ctx: &Context) -> bool {
        ctx.rec.bat_v.is_some()
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
        // each of them times the change enters with a free gain.
        let Some(v) = ctx.rec.bat_v.as_deref() else {
            return match Battery::from_slice(theta) {
                Some(b) if self.free_order > 0 => {
                    discharge_columns(ctx, trace, law, b.capacity_ah, self.free_order)
                }
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
        // The baseline's own current-law columns, as this model has them (lagged with the
        // currents' field where a term lags it).
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
        let pack = pack(ctx);
        let cells = Param::new("cells", pack.0 as f64, None, "cells in series");
        let fitted = if ctx.rec.bat_v.is_none() {
            Battery::from_slice(f.theta).zip(Battery::from_slice(f.theta_sd))
        } else {
            self.fit_to_recorded_voltage(ctx, s)
        };
        let Some((b, sd)) = fitted else {
            return Vec::new();
        };
        set_battery(ctx, pack, s, b);
        vec![
            Param::new(
                "internal_resistance_ohm",
                b.internal_resistance_ohm,
                sd.internal_resistance_ohm,
                "ohm",
            ),
            Param::new("capacity_ah", b.capacity_ah, sd.capacity_ah, "Ah"),
            cells,
        ]
    }
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
    // Charge drawn by the trapezoid rule over the rows (the replay's substeps are not kept).
    let mut drawn_ah = 0.0;
    let mut shapes = [
        Vec::with_capacity(trace.t_s.len()),
        Vec::with_capacity(trace.t_s.len()),
    ];
    for k in 0..trace.t_s.len() {
        if k > 0 {
            let dt_s = trace.t_s[k] - trace.t_s[k - 1];
            drawn_ah += 0.5 * (trace.total_a[k] + trace.total_a[k - 1]) * dt_s / 3600.0;
        }
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
        .flat_map(|(prefix, shape)| {
            law.iter().map(move |(name, law)| {
                (
                    format!("{prefix}_x_{name}"),
                    law.iter().zip(shape).map(|(x, d)| x * d).collect(),
                )
            })
        })
        .collect()
}

/// Prefix of a battery's columns on the LiPo curve's discharge ([`discharge_columns`]).
const LIPO_DISCHARGE: &str = "lipo_discharge";

#[cfg(test)]
mod tests {
    use super::*;

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
