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

/// Per-motor gains from the fitted deviation coefficients of all groups but the last
/// (`coef[k]` for `groups[k]`): each motor takes its group's coefficient (the last group 0),
/// less their mean over the motors, so that the gains sum to zero (their common part is the
/// baseline's). Singleton groups give `g_m = c_m - sum(c)/N`, the last `-sum(c)/N`.
fn gains(coef: &[[f64; 3]], groups: &[Vec<usize>], motors: usize) -> Vec<[f64; 3]> {
    let per_motor = per_motor(coef, groups, motors);
    let mut sum = [0.0; 3];
    for c in &per_motor {
        for a in 0..3 {
            sum[a] += c[a];
        }
    }
    per_motor
        .iter()
        .map(|c| std::array::from_fn(|a| c[a] - sum[a] / motors as f64))
        .collect()
}

/// Each motor's value of a per-group list (the last group's, and any motor in no group, 0).
fn per_motor(coef: &[[f64; 3]], groups: &[Vec<usize>], motors: usize) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; motors];
    for (c, group) in coef.iter().zip(groups) {
        for &m in group.iter().filter(|&&m| m < motors) {
            out[m] = *c;
        }
    }
    out
}

/// The design column's name of a group of motors (`motor3_...`, `motors1+5_...`): a single
/// motor's keeps the name model files have always had.
fn column_name(group: &[usize]) -> String {
    match group {
        [m] => format!("motor{}_current_deviation_a", m + 1),
        _ => format!(
            "motors{}_current_deviation_a",
            group
                .iter()
                .map(|m| (m + 1).to_string())
                .collect::<Vec<_>>()
                .join("+")
        ),
    }
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
        if thr.len() < 2 || thr.len() != ctx.nominal.motors.count || ctx.motor_groups.len() < 2 {
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
        ctx: &Context,
        trace: &Trace,
        _law: &[(&str, &[f64])],
        _theta: &[f64],
    ) -> Vec<(String, Vec<f64>)> {
        // One column per group of motors the recording tells apart, the last left out: the
        // deviations of all motors from their mean sum to zero.
        let n = trace.current_a.len();
        let groups = &ctx.motor_groups;
        groups[..groups.len().saturating_sub(1)]
            .iter()
            .map(|group| {
                let col = (0..trace.len())
                    .map(|r| {
                        let mean = trace.current_a.iter().map(|c| c[r]).sum::<f64>() / n as f64;
                        group
                            .iter()
                            .filter(|&&m| m < n)
                            .map(|&m| trace.current_a[m][r] - mean)
                            .sum()
                    })
                    .collect();
                (column_name(group), col)
            })
            .collect()
    }
    fn switch_on(&self, ctx: &Context, s: &mut Scenario, f: &EffectFit) -> Vec<Param> {
        let n = ctx.nominal.motors.count;
        let groups = &ctx.motor_groups;
        let g = gains(f.coef, groups, n);
        if s.wiring.extra_motor_ut_per_a.len() == g.len() {
            for (e, g) in s.wiring.extra_motor_ut_per_a.iter_mut().zip(&g) {
                for a in 0..3 {
                    e[a] += g[a];
                }
            }
        } else {
            s.wiring.extra_motor_ut_per_a = g.clone();
        }
        // Uncertainty of each gain ignoring the coefficients' covariance (approximate): a
        // fitted group's own coefficient's, and for the last group, whose gain is minus the
        // others' sum over the motors, that sum's.
        let last_var: [f64; 3] = std::array::from_fn(|a| {
            f.coef_sd
                .iter()
                .zip(groups)
                .map(|(s, group)| (group.len() as f64 * s[a]).powi(2))
                .sum()
        });
        let fitted_sd = per_motor(f.coef_sd, groups, n);
        let in_last = |m: usize| groups.last().is_some_and(|g| g.contains(&m));
        g.iter()
            .enumerate()
            .flat_map(|(m, g)| {
                let sd = std::array::from_fn(|a| {
                    if in_last(m) {
                        last_var[a].sqrt() / n as f64
                    } else {
                        fitted_sd[m][a]
                    }
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
        let g = gains(&c, &[vec![0], vec![1], vec![2], vec![3]], 4);
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

    #[test]
    fn motors_commanded_alike_share_their_groups_gain() {
        // Six motors, 1 and 5 commanded alike, 2 and 6 too: four groups, three coefficients.
        let groups = vec![vec![0, 4], vec![1, 5], vec![2], vec![3]];
        let c = [[1.0, -2.0, 0.5], [0.3, 0.0, -1.0], [-0.7, 1.0, 2.0]];
        let g = gains(&c, &groups, 6);
        assert_eq!(g[0], g[4], "{g:?}");
        assert_eq!(g[1], g[5], "{g:?}");
        let currents = [5.0, 7.0, 2.0, 9.0, 5.0, 7.0];
        let mean = currents.iter().sum::<f64>() / 6.0;
        for a in 0..3 {
            let s: f64 = g.iter().map(|g| g[a]).sum();
            assert!(s.abs() < 1e-12, "axis {a}: gains sum to {s}");
            let by_gains: f64 = g.iter().zip(&currents).map(|(g, i)| g[a] * i).sum();
            let by_columns: f64 = groups[..3]
                .iter()
                .zip(&c)
                .map(|(group, c)| c[a] * group.iter().map(|&m| currents[m] - mean).sum::<f64>())
                .sum();
            assert!(
                (by_gains - by_columns).abs() < 1e-12,
                "axis {a}: {by_gains} vs {by_columns}"
            );
        }
    }

    #[test]
    fn motors_are_grouped_where_no_row_tells_them_apart() {
        let a = vec![0.0, 0.5, 0.6];
        let b = vec![0.0, 0.5, 0.4];
        let thr = vec![a.clone(), b.clone(), a.clone(), vec![0.0, 0.5, 0.5], b];
        assert_eq!(
            crate::effects::motor_groups(&thr),
            vec![vec![0, 2], vec![1, 4], vec![3]]
        );
        assert_eq!(column_name(&[0, 2]), "motors1+3_current_deviation_a");
        assert_eq!(column_name(&[3]), "motor4_current_deviation_a");
    }
}
