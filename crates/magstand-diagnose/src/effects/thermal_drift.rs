use magstand_sim::Scenario;
use magstand_sim::replay::Trace;

use super::{Context, Effect, EffectFit, Param, first_order_lag};
use crate::optimize::{Search, minimize};

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

impl ThermalDrift {
    /// With `temp_c` recorded: the board's time constant and rise per watt that reproduce it
    /// from the replayed power (least squares in the rise, search in the time constant).
    fn fit_heating(&self, ctx: &Context, trace: &Trace) -> Option<(f64, Option<f64>, f64)> {
        let temp = ctx.rec.temp_c.as_deref()?;
        let p = power_w(ctx, trace);
        let t0 = temp[0];
        // The rise that fits best at a time constant, and the residual temperature.
        let fit_at = |tau: f64| {
            let x = first_order_lag(&trace.t_s, &p, tau);
            let (sxx, sxy) = x
                .iter()
                .zip(temp)
                .fold((0.0, 0.0), |(a, b), (x, t)| (a + x * x, b + x * (t - t0)));
            let rise = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            let residual: Vec<f64> = x.iter().zip(temp).map(|(x, t)| t - t0 - rise * x).collect();
            (rise, residual)
        };
        let sse = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
        // Chi-square with a 0.1 °C temperature error, for the search.
        const ASSUMED_VAR: f64 = 0.01;
        let o = minimize(&[tau_search()], |th| {
            Some(sse(&fit_at(th[0]).1) / ASSUMED_VAR)
        })?;
        let (rise, residual) = fit_at(o.theta[0]);
        // The uncertainty at the residual's own variance, widened by its serial correlation
        // (the replayed power is a model of the heating, and what it misses runs for minutes).
        let var = sse(&residual) / residual.len().saturating_sub(2).max(1) as f64;
        let z: Vec<f64> = residual.iter().map(|r| r / var.sqrt().max(1e-12)).collect();
        let widen = (var / ASSUMED_VAR).sqrt() * crate::stats::serial_sd_factor(&z);
        Some((o.theta[0], o.sd[0].map(|sd| sd * widen), rise))
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
                p.extend(Param::axes(
                    "offset_ut_per_w",
                    f.coef[0],
                    f.coef_sd[0],
                    "µT/W",
                ));
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

    /// A board heated through 60 s by the stand's current, whose law (linear in the
    /// speed) is not the nominal motor's: with `temp_c` logged, the heating's time constant
    /// and rise come back from the law's current. On the nominal motor's current, of another
    /// shape, the same temperature gives another time constant.
    #[test]
    fn a_logged_heating_is_fitted_on_the_stands_current_as_its_law_has_it() {
        // Up a stair of five levels and down again, 40 s a level, sampled every 0.1 s.
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
        let law = MotorCurrentLaw {
            columns: vec!["driven".into(), "speed^1".into()],
            a_per_unit: vec![0.5, 20.0],
        };
        let (tau_s, rise_c_per_w) = (60.0, 0.02);
        let mut ctx = stand.context();
        ctx.current_law = Some(law.clone());
        let heat = first_order_lag(&stand.trace.t_s, &power_w(&ctx, &stand.trace), tau_s);
        let mut rec = stand.rec.clone();
        rec.temp_c = Some(heat.iter().map(|p| 25.0 + rise_c_per_w * p).collect());
        let stand = TestStand::new(rec);
        let mut ctx = stand.context();
        ctx.current_law = Some(law);
        let (tau, _, rise) = ThermalDrift.fit_heating(&ctx, &stand.trace).unwrap();
        assert!(
            (tau - tau_s).abs() < 0.01 * tau_s && (rise - rise_c_per_w).abs() < 0.01 * rise_c_per_w,
            "fitted tau {tau} s, rise {rise} °C/W; generated {tau_s} s, {rise_c_per_w} °C/W"
        );
        ctx.current_law = None;
        let (nominal_tau, ..) = ThermalDrift.fit_heating(&ctx, &stand.trace).unwrap();
        assert!(
            (nominal_tau - tau_s).abs() > 0.05 * tau_s,
            "on the nominal current: tau {nominal_tau} s, generated {tau_s} s"
        );
    }
}
