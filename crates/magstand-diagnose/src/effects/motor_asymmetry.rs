use magstand_sim::Scenario;
use magstand_sim::replay::Trace;
use nalgebra::{Matrix3, SymmetricEigen};

use super::{Context, Effect, EffectFit, Param};
use crate::augmented_model::MotorCurrentLaw;
use crate::fit::{Design, LawColumn, MAX_SPEED_POWERS};
use crate::optimize::Search;

/// Motors affect the sensor unequally.
pub struct MotorAsymmetry;

/// Smallest spread between motor commands that counts as differential, and the share of rows
/// that must have it, for per-motor gains to be identifiable at all.
const MIN_SPREAD: f64 = 0.01;
const MIN_SHARE: f64 = 0.01;

/// Least correlation, over the identification rows, between the calibrated law's field along
/// its main direction and the nominal motor current for the law to stand for the current: a
/// law that does not follow the current at all (a sensor the motors do not reach) says nothing
/// of its shape, and the nominal motor's current is followed instead.
const MIN_LAW_CORRELATION: f64 = 0.5;

/// Points at which a calibrated law is checked to rise with speed over the speeds driven.
const MONOTONE_CHECK_POINTS: usize = 64;

/// Largest fall between neighbouring check points a calibrated law may have, as a share of
/// its rise over the speeds driven: a polynomial's wiggle where the current is flat.
const MONOTONE_SLACK: f64 = 0.01;

/// The motor current as a fitted baseline's current law has it. The law's field is
/// `F(r) = sum_j coef_j x_j(r)` over its columns; a motor's field is its current times one
/// direction, so the law's shape is its field along the main direction `u` of `F` (the
/// leading eigenvector of `sum F F^T` over the identification rows), scaled to amperes by
/// least squares against the nominal motor current (`load * full_load_a`). None where the
/// design has no law column, the field does not follow the current (see
/// [`MIN_LAW_CORRELATION`]), or the law's current does not rise with speed (see
/// [`rises_over_driven_speeds`]).
pub(crate) fn calibrated_current_law(
    design: &Design,
    coef: &[[f64; 3]],
    nominal_a: &[f64],
    holdout: &[bool],
) -> Option<MotorCurrentLaw> {
    let law: Vec<usize> = (0..design.len())
        .filter(|&j| LawColumn::parse(&design.names[j]).is_some())
        .collect();
    if law.is_empty() || coef.len() != design.len() {
        return None;
    }
    let rows: Vec<usize> = (0..nominal_a.len()).filter(|&r| !holdout[r]).collect();
    let field = |r: usize| -> [f64; 3] {
        std::array::from_fn(|a| law.iter().map(|&j| coef[j][a] * design.columns[j][r]).sum())
    };
    let mut second = Matrix3::<f64>::zeros();
    for &r in &rows {
        let f = field(r);
        for a in 0..3 {
            for b in 0..3 {
                second[(a, b)] += f[a] * f[b];
            }
        }
    }
    let eigen = SymmetricEigen::new(second);
    let lead = eigen.eigenvalues.imax();
    let u = eigen.eigenvectors.column(lead);
    let along = |r: usize| -> f64 {
        let f = field(r);
        (0..3).map(|a| u[a] * f[a]).sum()
    };
    // Least squares of the law's current-like field on the nominal current, and their
    // correlation (uncentred: both vanish with the motors off).
    let (mut hi, mut ii, mut hh) = (0.0, 0.0, 0.0);
    for &r in &rows {
        let (h, i) = (along(r), nominal_a[r]);
        hi += h * i;
        ii += i * i;
        hh += h * h;
    }
    let scale = hi / ii;
    let correlation = hi / (ii * hh).sqrt();
    if !(scale.is_finite() && scale != 0.0 && correlation.abs() >= MIN_LAW_CORRELATION) {
        return None;
    }
    let a_per_unit: Vec<f64> = law
        .iter()
        .map(|&j| (0..3).map(|a| u[a] * coef[j][a]).sum::<f64>() / scale)
        .collect();
    let found = MotorCurrentLaw {
        columns: law.iter().map(|&j| design.names[j].clone()).collect(),
        a_per_unit,
    };
    (found.a_per_unit.iter().all(|a| a.is_finite())
        && rises_over_driven_speeds(&found, design, &rows))
    .then_some(found)
}

/// Whether a driven motor's current by `law` rises with its speed over the speeds the rows
/// drive the motors at (each row's mean speed of its driven motors): a motor draws more
/// current the faster it turns, so a law that does not is the noise of a field the motors
/// barely reach, or a field that is not their currents', and no shape for a current.
fn rises_over_driven_speeds(law: &MotorCurrentLaw, design: &Design, rows: &[usize]) -> bool {
    let column = |name: &str| {
        design
            .names
            .iter()
            .position(|n| n == name)
            .map(|j| &design.columns[j])
    };
    let (Some(driven), Some(speed)) = (column("driven"), column("speed^1")) else {
        return false;
    };
    let (lo, hi) = rows
        .iter()
        .filter(|&&r| driven[r] > 0.0)
        .map(|&r| speed[r] / driven[r])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s), hi.max(s))
        });
    if !(lo.is_finite() && hi > lo) {
        return false;
    }
    // One driven motor's current at speed `s` (its part of each column).
    let per = PerUnit::of(law);
    let at = |s: f64| per.driven + per.powers_at(s);
    let values: Vec<f64> = (0..MONOTONE_CHECK_POINTS)
        .map(|i| at(lo + (hi - lo) * i as f64 / (MONOTONE_CHECK_POINTS - 1) as f64))
        .collect();
    let rise = values[values.len() - 1] - values[0];
    rise > 0.0
        && values
            .windows(2)
            .all(|w| w[1] >= w[0] - MONOTONE_SLACK * rise)
}

/// A law's amperes per unit of the driven flag, of an armed motor within its dead zone, and
/// of each power of speed.
struct PerUnit {
    driven: f64,
    armed: f64,
    powers: [f64; MAX_SPEED_POWERS],
}

impl PerUnit {
    fn of(law: &MotorCurrentLaw) -> PerUnit {
        let mut per = PerUnit {
            driven: 0.0,
            armed: 0.0,
            powers: [0.0; MAX_SPEED_POWERS],
        };
        for (name, a) in law.columns.iter().zip(&law.a_per_unit) {
            match LawColumn::parse(name) {
                Some(LawColumn::Driven) => per.driven += a,
                Some(LawColumn::ArmedInDeadZone) => per.armed += a,
                Some(LawColumn::SpeedPower(k)) => per.powers[k as usize - 1] += a,
                None => {}
            }
        }
        per
    }

    /// The powers' part at speed `s` (Horner's rule).
    fn powers_at(&self, s: f64) -> f64 {
        self.powers.iter().rev().fold(0.0, |acc, a| (acc + a) * s)
    }
}

/// Motor `m`'s current at every row of `trace`: by `law` where given, else the nominal
/// motor's. One pass over the rows (each design of a model with this term makes it).
fn motor_current(trace: &Trace, law: Option<&MotorCurrentLaw>, m: usize) -> Vec<f64> {
    let Some(law) = law else {
        return trace.current_a[m].clone();
    };
    let per = PerUnit::of(law);
    let (speed, driven, armed) = (&trace.speed[m], &trace.driven[m], &trace.armed[m]);
    (0..trace.len())
        .map(|r| {
            let d = driven[r];
            d * (per.driven + per.powers_at(speed[r])) + (armed[r] - d) * per.armed
        })
        .collect()
}

/// The stand's current at every row of `trace` as `law` has each motor's: their sum.
pub(crate) fn stand_current(trace: &Trace, law: &MotorCurrentLaw) -> Vec<f64> {
    let mut total = vec![0.0; trace.len()];
    for m in 0..trace.speed.len() {
        for (t, a) in total.iter_mut().zip(motor_current(trace, Some(law), m)) {
            *t += a;
        }
    }
    total
}

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
        // Each motor's current as the calibrated law has it where the context carries one:
        // the nominal motor's shape at low commands may be another stand's, and a gain fitted
        // to the wrong shape leaves a misfit that other terms (a dead zone) take up.
        let n = trace.current_a.len();
        let law = ctx.motor_current_law.as_ref();
        let currents: Vec<Vec<f64>> = (0..n).map(|m| motor_current(trace, law, m)).collect();
        let mean: Vec<f64> = (0..trace.len())
            .map(|r| currents.iter().map(|c| c[r]).sum::<f64>() / n as f64)
            .collect();
        let groups = &ctx.motor_groups;
        groups[..groups.len().saturating_sub(1)]
            .iter()
            .map(|group| {
                let col = (0..trace.len())
                    .map(|r| {
                        group
                            .iter()
                            .filter(|&&m| m < n)
                            .map(|&m| currents[m][r] - mean[r])
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
        let nominal_amperes = super::amperes_are_nominal(ctx);
        let law = ctx.motor_current_law.as_ref();
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
                let gains = Param::axes(&format!("motor{}_gain_ut_per_a", m + 1), *g, sd, "µT/A");
                // Motors commanded alike throughout are one group: the data tell only the
                // group's sum, which each of them reports an even share of.
                let shared = groups
                    .iter()
                    .find(|group| group.len() > 1 && group.contains(&m))
                    .map(|group| {
                        let names: Vec<String> =
                            group.iter().map(|k| (k + 1).to_string()).collect();
                        format!(
                            "motors {} take the same commands throughout, so the data tell only \
                             their sum, of which each reports an even share",
                            names.join(", ")
                        )
                    });
                if !nominal_amperes {
                    return match &shared {
                        Some(why) => gains.into_iter().map(|q| q.resting_on(why)).collect(),
                        None => gains,
                    };
                }
                // Per ampere of the nominal motor's scale, a default: the field the gain adds
                // at the motor's largest current does not rest on it (on the independent
                // generator's hexacopter, whose motors draw up to 11.4 A, the gains came out
                // 0.63 of the generator's, +- 1.5 %).
                let largest_a = motor_current(ctx.nominal_trace, law, m)
                    .into_iter()
                    .fold(0.0, f64::max);
                let basis = format!(
                    "the motor's current as the field calibrates it, in the nominal motor's \
                     amperes, whose scale nobody stated (log bat_a, or state the motor's kv, \
                     winding resistance and torque coefficient, for the stand's own): the gain \
                     has no sd; motor{k}_field_at_largest_ut_* is the gain times the motor's \
                     largest current ({largest_a:.2} A in those amperes), which does not rest on \
                     them",
                    k = m + 1
                );
                let at_largest = Param::axes(
                    &format!("motor{}_field_at_largest_ut", m + 1),
                    g.map(|g| g * largest_a),
                    sd.map(|sd| sd * largest_a),
                    "µT",
                );
                let basis = match &shared {
                    Some(why) => format!("{basis}; {why}"),
                    None => basis,
                };
                gains
                    .into_iter()
                    .map(|q| q.without_sd_resting_on(&basis))
                    .chain(at_largest.into_iter().map(|q| q.resting_on(&basis)))
                    .collect()
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A law whose field is one direction times a current `p0 + p1 s + p2 s^2 + p3 s^3`: its
    /// amperes per unit are those powers, scaled as the nominal current (here 1.3 times that
    /// current) has it; a sensor the current does not reach gives no law.
    #[test]
    fn the_calibrated_law_is_the_fields_shape_in_amperes() {
        let p = [0.4, 2.0, -1.5, 6.0];
        let g = [-0.35, 0.6, 0.5];
        let rows = 400;
        let speed: Vec<f64> = (0..rows).map(|r| (r % 37) as f64 / 36.0).collect();
        let driven: Vec<f64> = speed
            .iter()
            .map(|&s| f64::from(u8::from(s > 0.1)))
            .collect();
        let mut design = Design::default();
        design.push("reference", vec![1.0; rows]);
        design.push("driven", driven.clone());
        for k in 1..=3 {
            let col = speed
                .iter()
                .zip(&driven)
                .map(|(s, d)| d * s.powi(k))
                .collect();
            design.push(format!("speed^{k}"), col);
        }
        // The current of powers `p` at every row, and the coefficients of its field along `g`
        // (a motors-off reference first).
        let current_of = |p: &[f64; 4]| -> Vec<f64> {
            (0..rows)
                .map(|r| {
                    (1..design.len())
                        .map(|j| p[j - 1] * design.columns[j][r])
                        .sum()
                })
                .collect()
        };
        let coef_of = |p: &[f64; 4]| -> Vec<[f64; 3]> {
            std::iter::once([12.0, -3.0, 40.0])
                .chain(p.iter().map(|pj| g.map(|ga| ga * pj)))
                .collect()
        };
        let nominal: Vec<f64> = current_of(&p).iter().map(|i| 1.3 * i).collect();
        let coef = coef_of(&p);
        let holdout: Vec<bool> = (0..rows).map(|r| r % 5 == 0).collect();
        let law = calibrated_current_law(&design, &coef, &nominal, &holdout).expect("a law");
        assert_eq!(law.columns, ["driven", "speed^1", "speed^2", "speed^3"]);
        for (a, pj) in law.a_per_unit.iter().zip(p) {
            assert!(
                (a - 1.3 * pj).abs() < 1e-9 * pj.abs().max(1.0),
                "{:?} against 1.3 x {p:?}",
                law.a_per_unit
            );
        }
        let silent: Vec<[f64; 3]> = coef.iter().map(|_| [0.0; 3]).collect();
        assert_eq!(
            calibrated_current_law(&design, &silent, &nominal, &holdout),
            None
        );
        // A law that falls with speed over the speeds driven is no motor's current, however
        // well the nominal current follows it.
        let falls = [0.4, 2.0, -8.0, 6.0];
        assert_eq!(
            calibrated_current_law(&design, &coef_of(&falls), &current_of(&falls), &holdout),
            None
        );
    }

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
