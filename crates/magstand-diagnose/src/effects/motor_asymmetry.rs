use magstand_sim::Scenario;
use magstand_sim::replay::Trace;

use super::{Context, Effect, EffectFit, Param};
use crate::optimize::Search;

/// Motors affect the sensor unequally.
pub struct MotorAsymmetry;

/// Smallest spread between motor commands that counts as differential, and the share of rows
/// that must have it, for per-motor gains to be identifiable at all.
const MIN_SPREAD: f64 = 0.01;
const MIN_SHARE: f64 = 0.01;

/// Per-motor gains from the N-1 fitted deviation coefficients: `g_m = c_m - sum(c)/N`, the
/// last `-sum(c)/N`, so that the gains sum to zero (their common part is the baseline's).
fn gains(coef: &[[f64; 3]], motors: usize) -> Vec<[f64; 3]> {
    let mut sum = [0.0; 3];
    for c in coef {
        for a in 0..3 {
            sum[a] += c[a];
        }
    }
    (0..motors)
        .map(|m| {
            std::array::from_fn(|a| coef.get(m).map_or(0.0, |c| c[a]) - sum[a] / motors as f64)
        })
        .collect()
}

impl Effect for MotorAsymmetry {
    fn name(&self) -> &'static str {
        "motor_asymmetry"
    }
    fn explanation(&self) -> &'static str {
        "The motors' leads run at different distances from the sensor, so each motor's current \
         moves the field by its own amount and the field depends on every motor's command, not \
         only on their sum."
    }
    fn applies(&self, ctx: &Context) -> bool {
        let thr = &ctx.rec.thr;
        if thr.len() < 2 || thr.len() != ctx.nominal.motors.count {
            return false;
        }
        let rows = ctx.rec.len();
        let spread = (0..rows)
            .filter(|&r| {
                let (lo, hi) = thr
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), c| {
                        (lo.min(c[r]), hi.max(c[r]))
                    });
                hi - lo > MIN_SPREAD
            })
            .count();
        spread as f64 > MIN_SHARE * rows as f64
    }
    fn search(&self, _ctx: &Context) -> Vec<Search> {
        Vec::new()
    }
    fn regressors(
        &self,
        _ctx: &Context,
        trace: &Trace,
        _law: &[(&str, &[f64])],
        _theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        let n = trace.current_a.len();
        (0..n - 1)
            .map(|m| {
                let col = (0..trace.len())
                    .map(|r| {
                        let mean = trace.current_a.iter().map(|c| c[r]).sum::<f64>() / n as f64;
                        trace.current_a[m][r] - mean
                    })
                    .collect();
                (format!("motor{}_current_deviation_a", m + 1), col)
            })
            .collect()
    }
    fn switch_on(&self, ctx: &Context, s: &mut Scenario, f: &EffectFit) -> Vec<Param> {
        let n = ctx.nominal.motors.count;
        let g = gains(f.coef, n);
        if s.wiring.extra_motor_ut_per_a.len() == g.len() {
            for (e, g) in s.wiring.extra_motor_ut_per_a.iter_mut().zip(&g) {
                for a in 0..3 {
                    e[a] += g[a];
                }
            }
        } else {
            s.wiring.extra_motor_ut_per_a = g.clone();
        }
        // Uncertainty of each gain ignoring the coefficients' covariance (approximate).
        let sum_var: [f64; 3] =
            std::array::from_fn(|a| f.coef_sd.iter().map(|s| s[a] * s[a]).sum());
        g.iter()
            .enumerate()
            .flat_map(|(m, g)| {
                let sd = std::array::from_fn(|a| match f.coef_sd.get(m) {
                    Some(s) => s[a],
                    None => sum_var[a].sqrt() / n as f64,
                });
                Param::axes(&format!("motor{}_gain_ut_per_a", m + 1), *g, sd, "µT/A")
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_sum_to_zero_and_reproduce_the_deviation_model() {
        let c = [[1.0, 0.0, 2.0], [0.0, 3.0, 0.0], [-1.0, 1.0, 1.0]];
        let g = gains(&c, 4);
        let currents = [5.0, 7.0, 2.0, 9.0];
        let mean = currents.iter().sum::<f64>() / 4.0;
        for a in 0..3 {
            let s: f64 = g.iter().map(|g| g[a]).sum();
            assert!(s.abs() < 1e-12, "axis {a}: gains sum to {s}");
            let by_gains: f64 = g.iter().zip(&currents).map(|(g, i)| g[a] * i).sum();
            let by_dev: f64 = (0..3).map(|m| c[m][a] * (currents[m] - mean)).sum();
            assert!(
                (by_gains - by_dev).abs() < 1e-12,
                "axis {a}: {by_gains} vs {by_dev}"
            );
        }
    }
}
