use magstand_sim::Scenario;
use magstand_sim::replay::Trace;

use super::{Context, Effect, EffectFit, Param, first_order_lag};
use crate::optimize::{Search, minimize};
use magstand_ident::least_squares::NormalEquations;

/// The board heats with the power drawn and the sensor offset moves with temperature.
pub struct ThermalDrift;

nonlinear_params! {
    /// The board's heating, where no temperature is logged.
    Heating {
        /// The board's time constant, s.
        tau_s,
    }
}

fn tau_search() -> Search {
    Search {
        name: "tau_s",
        unit: "s",
        lo: 10.0,
        hi: 3000.0,
        log: true,
        points: 13,
    }
}

/// Electrical power drawn at every row, W: the supply's voltage times the stand's current
/// ([`super::law_current`]).
fn power_w(ctx: &Context, trace: &Trace) -> Vec<f64> {
    trace
        .voltage_v
        .iter()
        .zip(super::law_current(ctx, trace).iter())
        .map(|(v, i)| v * i)
        .collect()
}

/// Whether the power a heating follows is in watts nobody stated: the nominal motor's amperes
/// ([`super::amperes_are_nominal`]), or a supply voltage neither logged nor stated.
fn watts_are_nominal(ctx: &Context) -> bool {
    let voltage_known = ctx.follow_recorded_voltage
        || ["supply.voltage_v", "supply.cells"]
            .iter()
            .any(|key| ctx.nominal.states(key));
    super::amperes_are_nominal(ctx) || !voltage_known
}

/// What heats the board where `temp_c` is logged, each column free in its weight: the
/// supply's voltage times each column of the stand's calibrated current law summed over the
/// motors (a board warmed by a conductor's losses, or by a regulator's, follows the current
/// by a law of its own, which the logged temperature tells), else the power alone. A column
/// that is zero on every row is left out.
fn heating_inputs(ctx: &Context, trace: &Trace) -> Vec<Vec<f64>> {
    let Some(law) = super::followed_current_law(ctx) else {
        return vec![power_w(ctx, trace)];
    };
    law.columns
        .iter()
        .map(|column| {
            let unit = crate::augmented_model::MotorCurrentLaw {
                columns: vec![column.clone()],
                a_per_unit: vec![1.0],
            };
            super::stand_current(trace, &unit)
                .iter()
                .zip(&trace.voltage_v)
                .map(|(x, v)| x * v)
                .collect::<Vec<f64>>()
        })
        .filter(|x| x.iter().any(|v| *v != 0.0))
        .collect()
}

/// The logged temperature's rise from its first row less its least-squares fit on `inputs`
/// each lagged by `tau_s`, or None where the lagged inputs cannot be told apart.
fn heating_residual(
    t_s: &[f64],
    rise_c: &[f64],
    inputs: &[Vec<f64>],
    tau_s: f64,
) -> Option<Vec<f64>> {
    let lagged: Vec<Vec<f64>> = inputs
        .iter()
        .map(|x| first_order_lag(t_s, x, tau_s))
        .collect();
    let mut equations = NormalEquations::new(lagged.len(), 1);
    let mut row = vec![0.0; lagged.len()];
    for (r, y) in rise_c.iter().enumerate() {
        for (x, column) in row.iter_mut().zip(&lagged) {
            *x = column[r];
        }
        equations.add(&row, &[*y], 1.0);
    }
    let coef = equations.solve().ok()?;
    Some(
        rise_c
            .iter()
            .enumerate()
            .map(|(r, y)| {
                y - lagged
                    .iter()
                    .enumerate()
                    .map(|(j, c)| coef[(j, 0)] * c[r])
                    .sum::<f64>()
            })
            .collect(),
    )
}

/// The time constant, with its uncertainty, through which `inputs` heat the board to the
/// logged rise `rise_c` (least squares in their weights, search in the time constant).
fn heating_time_constant(
    t_s: &[f64],
    rise_c: &[f64],
    inputs: &[Vec<f64>],
) -> Option<(f64, Option<f64>)> {
    let sse = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    // Chi-square with a 0.1 °C temperature error, for the search.
    const ASSUMED_VAR: f64 = 0.01;
    let residual_at = |tau: f64| heating_residual(t_s, rise_c, inputs, tau);
    let o = minimize(&[tau_search()], |th| {
        residual_at(th[0]).map(|r| sse(&r) / ASSUMED_VAR)
    })?;
    let tau = o.theta[0];
    let residual = residual_at(tau)?;
    // The uncertainty at the residual's own variance, widened by its serial correlation
    // (what the inputs miss of the heating runs for minutes).
    let var = sse(&residual) / residual.len().saturating_sub(inputs.len() + 1).max(1) as f64;
    let z: Vec<f64> = residual.iter().map(|r| r / var.sqrt().max(1e-12)).collect();
    let widen = (var / ASSUMED_VAR).sqrt() * crate::stats::serial_sd_factor(&z);
    Some((tau, o.sd[0].map(|sd| sd * widen)))
}

impl ThermalDrift {
    /// With `temp_c` recorded: the board's time constant that reproduces it from what heats
    /// the board ([`heating_inputs`]; least squares in their weights, search in the time
    /// constant), its uncertainty, and the rise per watt of the power at that time constant.
    fn fit_heating(&self, ctx: &Context, trace: &Trace) -> Option<(f64, Option<f64>, f64)> {
        let temp = ctx.rec.temp_c.as_deref()?;
        let t0 = temp[0];
        let rise_c: Vec<f64> = temp.iter().map(|t| t - t0).collect();
        let mut inputs = heating_inputs(ctx, trace);
        if heating_residual(&trace.t_s, &rise_c, &inputs, tau_search().hi).is_none() {
            inputs = vec![power_w(ctx, trace)];
        }
        let (tau, tau_sd) = heating_time_constant(&trace.t_s, &rise_c, &inputs)?;
        // The rise per watt of the power lagged by that time constant, for the simulator's
        // one-input board.
        let x = first_order_lag(&trace.t_s, &power_w(ctx, trace), tau);
        let (sxx, sxy) = x
            .iter()
            .zip(&rise_c)
            .fold((0.0, 0.0), |(a, b), (x, y)| (a + x * x, b + x * y));
        let rise = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        Some((tau, tau_sd, rise))
    }
}

impl Effect for ThermalDrift {
    fn name(&self) -> &'static str {
        "thermal_drift"
    }
    fn explanation(&self) -> &'static str {
        "The board warms with the power drawn and cools over minutes, and the magnetometer's \
         offset moves with its temperature."
    }
    fn parameters(&self) -> &'static [&'static str] {
        Heating::NAMES
    }
    fn follows_the_current_law(&self, ctx: &Context) -> bool {
        ctx.rec.temp_c.is_none()
    }
    fn search(&self, ctx: &Context) -> Vec<Search> {
        if ctx.rec.temp_c.is_some() {
            Vec::new()
        } else {
            vec![tau_search()]
        }
    }
    fn regressors(
        &self,
        ctx: &Context,
        trace: &Trace,
        _law: &[(&str, &[f64])],
        theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        match ctx.rec.temp_c.as_deref() {
            Some(t) => vec![("temp_rise_c".into(), t.iter().map(|v| v - t[0]).collect())],
            // Temperature rise per (°C/W): the lagged power, W.
            None => Heating::from_slice(theta)
                .map(|h| {
                    (
                        "lagged_power_w".into(),
                        first_order_lag(&trace.t_s, &power_w(ctx, trace), h.tau_s),
                    )
                })
                .into_iter()
                .collect(),
        }
    }
    fn switch_on(&self, ctx: &Context, s: &mut Scenario, f: &EffectFit) -> Vec<Param> {
        s.thermal.enabled = true;
        match self.fit_heating(ctx, ctx.nominal_trace) {
            Some((tau, tau_sd, rise)) if rise > 0.0 => {
                s.thermal.tau_s = tau;
                s.thermal.rise_c_per_w = rise.min(10.0);
                s.thermal.ambient_c = ctx
                    .rec
                    .temp_c
                    .as_deref()
                    .map_or(s.thermal.ambient_c, |t| t[0]);
                s.thermal.offset_ut_per_c = f.coef[0];
                let mut p = Param::axes("offset_ut_per_c", f.coef[0], f.coef_sd[0], "µT/°C");
                p.push(Param::new("tau_s", tau, tau_sd, "s"));
                p.push(Param::new("rise_c_per_w", rise, None, "°C/W"));
                p
            }
            _ => {
                // Only the product of rise and offset is seen: keep the nominal rise.
                let (Some(heating), Some(sd)) = (
                    Heating::from_slice(f.theta),
                    Heating::from_slice(f.theta_sd),
                ) else {
                    return Vec::new();
                };
                s.thermal.tau_s = heating.tau_s;
                let rise = s.thermal.rise_c_per_w.max(1e-6);
                s.thermal.offset_ut_per_c = f.coef[0].map(|c| c / rise);
                let mut p = vec![Param::new("tau_s", heating.tau_s, sd.tau_s, "s")];
                let per_w = Param::axes("offset_ut_per_w", f.coef[0], f.coef_sd[0], "µT/W");
                if !watts_are_nominal(ctx) {
                    p.extend(per_w);
                    return p;
                }
                // The watts are the nominal motor's amperes times a voltage nobody stated: the
                // field the heating settles at under the recording's largest power does not
                // rest on that scale, only on the law's shape (on the independent generator's
                // default stand, stair, seed 1, without `temp_c`: the offsets per watt 1.4
                // times the generator's, +- 1.5 %; the settled field within a tenth of it on
                // three stands' random steps and stairs, where its curvature's sd held it on 21
                // of 36 axis values, so it has none either).
                let largest_w = power_w(ctx, ctx.nominal_trace)
                    .into_iter()
                    .fold(0.0, f64::max);
                let basis = format!(
                    "the power as the replay gives it: the nominal motor's amperes, or a supply \
                     voltage, that nobody stated or logged (log temp_c, or bat_v and bat_a, or \
                     state the motor's kv, winding resistance and torque coefficient and the \
                     supply, for the stand's own), and its shape the calibrated current law's, \
                     so no sd; offset_at_largest_power_ut_* is the field the heating settles at \
                     under the largest power the recording draws ({largest_w:.1} W in those \
                     watts), which rests on the shape only"
                );
                let at_largest = Param::axes(
                    "offset_at_largest_power_ut",
                    f.coef[0].map(|c| c * largest_w),
                    [0.0; 3],
                    "µT",
                );
                p.extend(
                    per_w
                        .into_iter()
                        .chain(at_largest)
                        .map(|q| q.without_sd_resting_on(&basis)),
                );
                p
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::augmented_model::MotorCurrentLaw;
    use crate::effects::TestStand;

    /// A recording up a stair of five levels and down again, 40 s a level, sampled every
    /// 0.1 s, whose `temp_c` is 25 °C plus `heating` (of its stand's replay) lagged by 60 s.
    fn heated_stair(heating: impl Fn(&TestStand) -> Vec<f64>) -> TestStand {
        let t_s: Vec<f64> = (0..4000).map(|k| k as f64 * 0.1).collect();
        let thr: Vec<f64> = t_s
            .iter()
            .map(|t| {
                let level = (t / 40.0).floor();
                (if level < 5.0 { level } else { 9.0 - level }) / 4.0
            })
            .collect();
        let stand = TestStand::new(magstand_core::Recording {
            mag_ut: vec![magstand_core::Vec3::new(20.0, -4.0, 40.0); t_s.len()],
            thr: vec![thr],
            overall_only: true,
            t_s,
            ..Default::default()
        });
        let heat = first_order_lag(&stand.trace.t_s, &heating(&stand), 60.0);
        let mut rec = stand.rec.clone();
        rec.temp_c = Some(heat.iter().map(|h| 25.0 + h).collect());
        TestStand::new(rec)
    }

    /// The stand's calibrated law of these tests: linear in the speed, not the nominal
    /// motor's shape.
    fn linear_law() -> MotorCurrentLaw {
        MotorCurrentLaw {
            columns: vec!["driven".into(), "speed^1".into()],
            a_per_unit: vec![0.5, 20.0],
        }
    }

    /// A board heated through 60 s by the stand's power as its calibrated law has it: with
    /// `temp_c` logged, the time constant and the rise per watt come back. On the nominal
    /// motor's current alone (no law), of another shape, the same temperature gives another
    /// time constant.
    #[test]
    fn a_logged_heating_is_fitted_on_the_stands_current_as_its_law_has_it() {
        let rise_c_per_w = 0.02;
        let stand = heated_stair(|stand| {
            let mut ctx = stand.context();
            ctx.current_law = Some(linear_law());
            let p = power_w(&ctx, &stand.trace);
            p.iter().map(|p| rise_c_per_w * p).collect()
        });
        let mut ctx = stand.context();
        ctx.current_law = Some(linear_law());
        let (tau, _, rise) = ThermalDrift.fit_heating(&ctx, &stand.trace).unwrap();
        assert!(
            (tau - 60.0).abs() < 0.6 && (rise - rise_c_per_w).abs() < 0.01 * rise_c_per_w,
            "fitted tau {tau} s, rise {rise} °C/W; generated 60 s, {rise_c_per_w} °C/W"
        );
        ctx.current_law = None;
        let (nominal_tau, ..) = ThermalDrift.fit_heating(&ctx, &stand.trace).unwrap();
        assert!(
            (nominal_tau - 60.0).abs() > 3.0,
            "on the nominal current: tau {nominal_tau} s, generated 60 s"
        );
    }

    /// A board that follows the current by a law of its own (here far more of the idle
    /// current than the field's law has, as a regulator's losses would): each of the law's
    /// columns heats it with a weight the logged temperature tells, so the time constant
    /// still comes back, where the law's power alone gives another.
    #[test]
    fn a_logged_heating_of_its_own_law_has_its_time_constant() {
        let stand = heated_stair(|stand| {
            let t = &stand.trace;
            (0..t.len())
                .map(|r| t.voltage_v[r] * (0.03 * t.driven[0][r] + 0.002 * t.speed[0][r]))
                .collect()
        });
        let mut ctx = stand.context();
        ctx.current_law = Some(linear_law());
        let (tau, ..) = ThermalDrift.fit_heating(&ctx, &stand.trace).unwrap();
        assert!(
            (tau - 60.0).abs() < 0.6,
            "fitted tau {tau} s, generated 60 s"
        );
        let rise_c: Vec<f64> = ctx
            .rec
            .temp_c
            .as_ref()
            .unwrap()
            .iter()
            .map(|t| t - 25.0)
            .collect();
        let (power_tau, _) =
            heating_time_constant(&stand.trace.t_s, &rise_c, &[power_w(&ctx, &stand.trace)])
                .unwrap();
        assert!(
            (power_tau - 60.0).abs() > 3.0,
            "on the law's power alone: tau {power_tau} s, generated 60 s"
        );
    }
}
