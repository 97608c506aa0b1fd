//! The diagnosis itself: baseline, forward search over the catalog, location, augmented
//! scenario and the simulation comparison.
use magstand_core::{Recording, Vec3};
use magstand_sim::ValidScenario;
use magstand_sim::replay::replay;
use rayon::prelude::*;

use crate::diagnosis::{
    Baseline, CandidateResult, Diagnosis, EffectReport, FORMAT, Round, Series, Settings,
    SimulationAgreement, Stage, UNEXPLAINED, VERSION,
};
use crate::effects::{Context, Effect, EffectFit, Param, catalog};
use crate::fit::{Design, Fitted, VarianceModel, Weights, fit};
use crate::locate::{Rows, Signal, locate};
use crate::optimize::minimize;
use crate::split::Split;
use crate::stats::{ljung_box, one_sided_t, signed_rank};
use crate::{DiagnoseError, ValidConfig};

/// Lags of the whiteness test.
const LAGS: usize = 20;
/// Most rows kept in the plotted residual series.
const SERIES_POINTS: usize = 1500;
/// Fewest held-out blocks for the paired tests to mean anything.
const MIN_HOLDOUT_BLOCKS: usize = 5;

/// An effect in the model with its nonlinear parameters.
struct Term<'e> {
    effect: &'e dyn Effect,
    theta: Vec<f64>,
    theta_sd: Vec<Option<f64>>,
}

/// The design of a model and which columns belong to which term.
pub(crate) struct Built {
    pub(crate) design: Design,
    /// What the nominal physics fixes (per-motor wiring differences, switched-on extras).
    pub(crate) fixed: Vec<Vec3>,
    /// Motor current over its largest value: the load the noise variance grows with.
    load: Vec<f64>,
    /// The largest motor current, A (`load` 1).
    full_load_a: f64,
    term_columns: Vec<std::ops::Range<usize>>,
}

impl Built {
    /// Motor current at every row, A.
    pub(crate) fn load_a(&self) -> Vec<f64> {
        self.load.iter().map(|q| q * self.full_load_a).collect()
    }
}

fn build(ctx: &Context, terms: &[(&dyn Effect, &[f64])]) -> Built {
    build_with_lead(ctx, terms, ctx.command_lead)
}

pub(crate) fn build_with_lead(ctx: &Context, terms: &[(&dyn Effect, &[f64])], lead: f64) -> Built {
    let mut s = ctx.nominal.clone();
    let mut recorded_v = false;
    for (e, theta) in terms {
        e.apply(ctx, &mut s, theta);
        recorded_v |= e.uses_recorded_voltage(ctx);
    }
    let bat_v = if recorded_v {
        ctx.rec.bat_v.as_deref()
    } else {
        None
    };
    let trace = replay(&s, &ctx.rec.t_s, &ctx.rec.thr, bat_v, lead);
    let mut design = Design::baseline(&trace);
    let mut term_columns = Vec::new();
    for (e, theta) in terms {
        let start = design.len();
        for (name, col) in e.regressors(ctx, &trace, theta) {
            design.push(name, col);
        }
        term_columns.push(start..design.len());
    }
    let avionics = s.supply.avionics_current_a();
    let max_a = trace
        .total_a
        .iter()
        .map(|a| a - avionics)
        .fold(0.0, f64::max)
        .max(1e-9);
    Built {
        design,
        fixed: trace.extra_ut,
        load: trace
            .total_a
            .iter()
            .map(|a| (a - avionics) / max_a)
            .collect(),
        full_load_a: max_a,
        term_columns,
    }
}

fn as_refs<'a>(terms: &'a [Term<'a>]) -> Vec<(&'a dyn Effect, &'a [f64])> {
    terms
        .iter()
        .map(|t| (t.effect, t.theta.as_slice()))
        .collect()
}

/// Held-out RMSE per axis, µT.
fn holdout_rmse(resid: &[Vec3], holdout: &[bool]) -> [f64; 3] {
    let mut s = [0.0; 3];
    let mut n = 0.0f64;
    for (e, _) in resid.iter().zip(holdout).filter(|(_, h)| **h) {
        for a in 0..3 {
            s[a] += e[a] * e[a];
        }
        n += 1.0;
    }
    s.map(|v| (v / n.max(1.0)).sqrt())
}

/// Per held-out block, the mean drop of the weighted squared residual from `before` to `after`.
fn block_improvements(before: &[Vec3], after: &[Vec3], w: &Weights, split: &Split) -> Vec<f64> {
    let mut out: Vec<(usize, f64, f64)> = Vec::new();
    for r in (0..before.len()).filter(|&r| split.holdout[r]) {
        let d: f64 = (0..3)
            .map(|a| w.0[r][a] * (before[r][a].powi(2) - after[r][a].powi(2)))
            .sum();
        match out.last_mut() {
            Some((b, s, n)) if *b == split.block[r] => {
                *s += d;
                *n += 1.0;
            }
            _ => out.push((split.block[r], d, 1.0)),
        }
    }
    out.into_iter().map(|(_, s, n)| s / n).collect()
}

/// One-sided p-value of the held-out gain `S = sum(z_before^2 - z_after^2) + D` (D: the
/// squared change of the prediction in noise units), which has mean zero when the candidate
/// only fits noise; its variance uses the autocovariance of the before-residuals up to one
/// block's length, so structure that is not white does not pass for a gain.
fn noise_referenced(before: &[Vec3], after: &[Vec3], w: &Weights, split: &Split) -> Option<f64> {
    let rows: Vec<usize> = (0..before.len()).filter(|&r| split.holdout[r]).collect();
    let n = rows.len();
    if n < 10 {
        return None;
    }
    let lags = (n / split.holdout_blocks().max(1)).clamp(1, 400);
    let mut s = 0.0;
    let mut var = 0.0;
    for a in 0..3 {
        let z: Vec<f64> = rows
            .iter()
            .map(|&r| before[r][a] * w.0[r][a].sqrt())
            .collect();
        let d: Vec<f64> = rows
            .iter()
            .map(|&r| (before[r][a] - after[r][a]) * w.0[r][a].sqrt())
            .collect();
        s += z.iter().zip(&d).map(|(z, d)| 2.0 * z * d).sum::<f64>();
        for k in 0..=lags.min(n - 1) {
            let (mut gamma, mut c, mut pairs) = (0.0, 0.0, 0usize);
            for i in 0..n - k {
                if split.block[rows[i]] == split.block[rows[i + k]] {
                    gamma += z[i] * z[i + k];
                    c += d[i] * d[i + k];
                    pairs += 1;
                }
            }
            if pairs == 0 {
                continue;
            }
            // Bartlett weights keep the estimate positive.
            let weight = if k == 0 {
                1.0
            } else {
                2.0 * (1.0 - k as f64 / (lags + 1) as f64)
            };
            var += 4.0 * weight * (gamma / pairs as f64) * c;
        }
    }
    if !(var > 0.0) {
        return None;
    }
    Some(crate::stats::normal_sf(s / var.sqrt()))
}

/// Standardized residuals (divided by the noise sd).
fn standardized(resid: &[Vec3], w: &Weights) -> Vec<Vec3> {
    resid
        .iter()
        .zip(&w.0)
        .map(|(e, w)| Vec3::new(e.x * w[0].sqrt(), e.y * w[1].sqrt(), e.z * w[2].sqrt()))
        .collect()
}

/// Ljung-Box p-value per axis of the held-out standardized residuals.
fn whiteness(z: &[Vec3], split: &Split) -> [f64; 3] {
    let rows: Vec<usize> = (0..z.len()).filter(|&r| split.holdout[r]).collect();
    let seg: Vec<usize> = rows.iter().map(|&r| split.block[r]).collect();
    std::array::from_fn(|a| {
        let za: Vec<f64> = rows.iter().map(|&r| z[r][a]).collect();
        ljung_box(&za, &seg, LAGS).1
    })
}

struct Candidate {
    result: CandidateResult,
    fitted: Option<(Vec<f64>, Vec<Option<f64>>, Fitted)>,
}

impl Candidate {
    /// A candidate that was not tried or could not be fitted, and why.
    fn not_fitted(effect: &dyn Effect, note: &str) -> Candidate {
        Candidate {
            result: CandidateResult {
                name: effect.name().into(),
                holdout_rmse_ut: None,
                improvement: None,
                p_value: None,
                note: Some(note.into()),
            },
            fitted: None,
        }
    }
}

fn try_candidate(
    ctx: &Context,
    terms: &[Term],
    effect: &dyn Effect,
    weights: &Weights,
    before: &[Vec3],
) -> Candidate {
    let y = &ctx.rec.mag_ut;
    let base = as_refs(terms);
    let with = |theta: &[f64]| -> Option<Fitted> {
        let mut all = base.clone();
        all.push((effect, theta));
        let b = build(ctx, &all);
        fit(&b.design, y, Some(&b.fixed), weights, &ctx.split.holdout).ok()
    };
    let Some(opt) = minimize(&effect.search(ctx), |theta| with(theta).map(|f| f.chi2_fit)) else {
        return Candidate::not_fitted(
            effect,
            "cannot be fitted on this recording (its regressors are degenerate here)",
        );
    };
    let Some(fitted) = with(&opt.theta) else {
        return Candidate::not_fitted(effect, "cannot be fitted at its best parameters");
    };
    let after = fitted.residuals(y);
    let blocks = block_improvements(before, &after, weights, ctx.split);
    let improvement = blocks.iter().sum::<f64>() / blocks.len().max(1) as f64;
    Candidate {
        result: CandidateResult {
            name: effect.name().into(),
            holdout_rmse_ut: Some(holdout_rmse(&after, &ctx.split.holdout)),
            improvement: Some(improvement),
            p_value: {
                // Three views of the same held-out gain, Bonferroni-combined: the t-test for
                // gains spread over all blocks, the signed-rank test for gains confined to the
                // blocks with steps, and the gain against its noise given the residuals' own
                // autocovariance, for gains concentrated in a few short transients.
                let p = [
                    one_sided_t(&blocks),
                    signed_rank(&blocks),
                    noise_referenced(before, &after, weights, ctx.split),
                ];
                let k = p.iter().flatten().count() as f64;
                p.iter()
                    .flatten()
                    .cloned()
                    .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))))
                    .map(|m| (m * k).min(1.0))
            },
            note: None,
        },
        fitted: Some((opt.theta, opt.sd, fitted)),
    }
}

/// A model of some terms, fitted with weights from its own residuals.
struct ModelFit {
    built: Built,
    fitted: Fitted,
    weights: Weights,
    /// The residual variance law on the held-out rows.
    noise: VarianceModel,
}

/// Fits the model of `terms` with weights from its own residuals (one reweighting pass).
fn fit_model(
    ctx: &Context,
    terms: &[Term],
    weights: Option<&Weights>,
) -> Result<ModelFit, DiagnoseError> {
    let y = &ctx.rec.mag_ut;
    let built = build(ctx, &as_refs(terms));
    let singular = |e: magstand_ident::least_squares::SolveError| DiagnoseError::Singular {
        origin: ctx.rec_origin.clone(),
        message: match e {
            magstand_ident::least_squares::SolveError::NoData => "no rows to fit".into(),
            magstand_ident::least_squares::SolveError::Singular { column, .. } => format!(
                "regressor `{}` is not determined: the recording needs motors off and at least \
                 four distinct throttle levels",
                built.design.names.get(column).map_or("?", String::as_str)
            ),
        },
    };
    let unit = Weights(vec![[1.0; 3]; y.len()]);
    let first = fit(
        &built.design,
        y,
        None,
        weights.unwrap_or(&unit),
        &ctx.split.holdout,
    )
    .map_err(singular)?;
    // The load as this model's physics has it (a delay or a lag moves it too).
    let q = &built.load;
    let var = VarianceModel::fit(&first.residuals(y), q, &ctx.split.holdout);
    let w = var.weights(q, &timing_spread(ctx, terms, &first.coef));
    let fitted =
        fit(&built.design, y, Some(&built.fixed), &w, &ctx.split.holdout).map_err(singular)?;
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

/// Passes of the coordinate search in [`refine`].
const REFINE_PASSES: usize = 2;

/// Refits the nonlinear parameters of all accepted terms and the command lead together, by
/// coordinate search: each term's parameters (over its whole search range) with the others
/// held, then the lead, [`REFINE_PASSES`] times.
fn refine(ctx: &mut Context, terms: &mut [Term], weights: &Weights) {
    let y = &ctx.rec.mag_ut;
    for _ in 0..REFINE_PASSES {
        for k in 0..terms.len() {
            let searches = terms[k].effect.search(ctx);
            if searches.is_empty() {
                continue;
            }
            let chi2 = |theta: &[f64]| {
                let mut refs = as_refs(terms);
                refs[k].1 = theta;
                let b = build(ctx, &refs);
                fit(&b.design, y, Some(&b.fixed), weights, &ctx.split.holdout)
                    .ok()
                    .map(|f| f.chi2_fit)
            };
            if let Some(opt) = minimize(&searches, chi2) {
                terms[k].theta = opt.theta;
                terms[k].theta_sd = opt.sd;
            }
        }
        ctx.command_lead = calibrate_timing(ctx, terms, weights);
    }
}

/// The moment within each interval at which logged command changes take effect, searched in
/// 0..1.
fn calibrate_timing(ctx: &Context, terms: &[Term], weights: &Weights) -> f64 {
    let y = &ctx.rec.mag_ut;
    let refs = as_refs(terms);
    let chi2 = |lead: f64| {
        let b = build_with_lead(ctx, &refs, lead);
        fit(&b.design, y, Some(&b.fixed), weights, &ctx.split.holdout)
            .ok()
            .map(|f| f.chi2_fit)
    };
    crate::optimize::minimize(
        &[crate::Search {
            name: "command_lead",
            unit: "interval",
            lo: 0.0,
            hi: 1.0,
            log: false,
            points: 5,
        }],
        |t| chi2(t[0]),
    )
    .map_or(0.5, |o| o.theta[0])
}

/// The spread of a model's prediction between the two extreme moments at which each logged
/// command change could have happened (start or end of its interval): it sets the timing part
/// of every row's variance.
fn timing_spread(ctx: &Context, terms: &[Term], coef: &[[f64; 3]]) -> Vec<Vec3> {
    let refs = as_refs(terms);
    let (early, late) = (
        build_with_lead(ctx, &refs, 0.0),
        build_with_lead(ctx, &refs, 1.0),
    );
    let (a, b) = (early.design.predict(coef), late.design.predict(coef));
    (0..a.len())
        .map(|r| (b[r] + late.fixed[r]) - (a[r] + early.fixed[r]))
        .collect()
}

/// Diagnoses `rec` (named `origin` in messages) against the nominal scenario.
pub fn diagnose(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    config: &ValidConfig,
) -> Result<Diagnosis, DiagnoseError> {
    let cfg = config.params();
    let bad = |message: String| DiagnoseError::Recording {
        origin: origin.into(),
        message,
    };
    let motors = nominal.params().motors.count;
    let n_cols = rec.motor_count();
    if n_cols != motors && n_cols != 1 {
        return Err(bad(format!(
            "{n_cols} motor command columns, but the scenario {} has motors.count = {motors}: \
             expected {motors} thr_N columns (or one thr column for all motors)",
            nominal.origin()
        )));
    }
    let split = Split::new(&rec.t_s, cfg.block_s, cfg.holdout_every);
    if split.holdout_blocks() < MIN_HOLDOUT_BLOCKS || split.fit_rows() < 50 {
        return Err(bad(format!(
            "{} rows in {} held-out blocks of {:.2} s: expected at least 50 rows to fit and {} \
             held-out blocks (a longer recording, or a shorter block_s)",
            rec.len(),
            split.holdout_blocks(),
            split.block_s,
            MIN_HOLDOUT_BLOCKS
        )));
    }
    let mut scenario = nominal.params().clone();
    // The program is the recording's; the nominal stand's own logging delay is physics.
    scenario.study = Default::default();
    let nominal_trace = replay(&scenario, &rec.t_s, &rec.thr, None, 0.5);
    let avionics = scenario.supply.avionics_current_a();
    let max_motor_a = nominal_trace
        .total_a
        .iter()
        .map(|a| a - avionics)
        .fold(0.0, f64::max);
    if max_motor_a <= 0.0 {
        return Err(bad(format!(
            "the motors never run under the nominal physics (dead zone {}): expected commands \
             above the dead zone",
            scenario.motors.dead_zone
        )));
    }
    let ctx = Context {
        rec,
        nominal: &scenario,
        split: &split,
        nominal_trace: &nominal_trace,
        rec_origin: origin.to_string(),
        command_lead: 0.5,
    };
    let mut ctx = ctx;
    ctx.command_lead = calibrate_timing(&ctx, &[], &Weights(vec![[1.0; 3]; rec.len()]));
    let base_lead = ctx.command_lead;
    let rows = Rows::new(rec, &split.block);
    let y = &rec.mag_ut;
    let all_rows = vec![true; rec.len()];

    // Baseline.
    let ModelFit {
        built: base_built,
        fitted: base_fit,
        weights: base_w,
        noise: base_noise,
    } = fit_model(&ctx, &[], None)?;
    let base_resid = base_fit.residuals(y);
    let base_rmse = holdout_rmse(&base_resid, &split.holdout);
    let base_z = standardized(&base_resid, &base_w);
    let base_white = whiteness(&base_z, &split);
    let white_threshold = cfg.significance / 3.0;
    let base_structured = base_white.iter().any(|&p| p < white_threshold);

    // Forward search.
    let effects = catalog();
    let mut terms: Vec<Term> = Vec::new();
    let mut rounds = Vec::new();
    let mut reports: Vec<EffectReport> = Vec::new();
    let mut stages = vec![("baseline".to_string(), base_resid.clone())];
    let mut current = (base_fit.clone(), base_w.clone());
    while terms.len() < cfg.max_terms {
        let (cur_fit, w) = &current;
        let before = cur_fit.residuals(y);
        // Gatekeeping: the family of candidate tests is opened only when the global test
        // rejects white noise for the baseline, so a clean recording stays clean however many
        // candidates there are (the first round is still tried, for the record). Once there
        // is a mismatch, later rounds rely on the targeted candidate tests: a transient effect
        // (a delay at each step) can leave a residual the omnibus test calls white after a
        // first term, while its own test sees it plainly.
        let white = if rounds.is_empty() {
            base_white
        } else {
            whiteness(&standardized(&before, w), &split)
        };
        let structured = !rounds.is_empty() || base_structured;
        let open: Vec<&dyn Effect> = effects
            .iter()
            .map(|e| e.as_ref())
            .filter(|e| !terms.iter().any(|t| t.effect.name() == e.name()))
            .collect();
        let tried: Vec<Candidate> = open
            .par_iter()
            .map(|e| {
                if e.applies(&ctx) {
                    try_candidate(&ctx, &terms, *e, w, &before)
                } else {
                    Candidate::not_fitted(*e, "does not apply to this recording")
                }
            })
            .collect();
        let k = tried.iter().filter(|c| c.fitted.is_some()).count().max(1);
        let threshold = cfg.significance / k as f64;
        let best = tried
            .iter()
            .enumerate()
            .filter(|_| structured)
            .filter(|(_, c)| c.result.p_value.is_some_and(|p| p < threshold))
            .filter(|(_, c)| c.result.improvement.is_some_and(|i| i > 0.0))
            .max_by(|a, b| {
                a.1.result
                    .improvement
                    .partial_cmp(&b.1.result.improvement)
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .map(|(i, _)| i);
        let accepted = best.map(|i| open[i].name().to_string());
        let mut round = Round {
            threshold,
            candidates: tried.iter().map(|c| c.result.clone()).collect(),
            accepted: accepted.clone(),
            whiteness_p: Some(white),
        };
        let Some(i) = best else {
            rounds.push(round);
            break;
        };
        let (theta, theta_sd, fitted) = tried[i].fitted.clone().expect("accepted means fitted");
        let after = fitted.residuals(y);
        // Where the new term changes the prediction, in noise units.
        let change: Vec<Vec3> = standardized(
            &fitted
                .pred
                .iter()
                .zip(&cur_fit.pred)
                .map(|(a, b)| a - b)
                .collect::<Vec<_>>(),
            w,
        );
        reports.push(EffectReport {
            name: open[i].name().into(),
            params: Vec::new(),
            explanation: open[i].explanation().into(),
            located: locate(&rows, &change, &all_rows, Signal::Change, cfg.significance),
            holdout_rmse_before_ut: holdout_rmse(&before, &split.holdout),
            holdout_rmse_after_ut: holdout_rmse(&after, &split.holdout),
            p_value: tried[i].result.p_value.unwrap_or(1.0),
        });
        stages.push((format!("+ {}", open[i].name()), after));
        terms.push(Term {
            effect: open[i],
            theta,
            theta_sd,
        });
        // The new term was fitted with the others' parameters held; they and the moment of
        // the interval at which commands act are refitted with it, so that the misfit a
        // held parameter leaves is not offered to the next round as a new effect.
        refine(&mut ctx, &mut terms, w);
        let m = fit_model(&ctx, &terms, Some(w))?;
        current = (m.fitted, m.weights);
        round.accepted = accepted;
        rounds.push(round);
    }

    // Final joint model; the accepted effects switched on with its values in the augmented
    // scenario, which also gives their parameters.
    let ModelFit {
        built: final_built,
        fitted: final_fit,
        weights: final_w,
        noise: final_noise,
    } = fit_model(&ctx, &terms, Some(&current.1))?;
    let mut augmented = scenario.clone();
    for (t, (report, cols)) in terms
        .iter()
        .zip(reports.iter_mut().zip(&final_built.term_columns))
    {
        report.params = t.effect.switch_on(
            &ctx,
            &mut augmented,
            &EffectFit {
                theta: &t.theta,
                theta_sd: &t.theta_sd,
                coef: &final_fit.coef[cols.clone()],
                coef_sd: &final_fit.coef_sd[cols.clone()],
            },
        );
    }
    let as_model =
        |terms: &[Term], built: &Built, fitted: &Fitted, noise: &VarianceModel, lead: f64| {
            crate::augmented_model::AugmentedModel {
                format: crate::augmented_model::FORMAT.into(),
                version: crate::augmented_model::VERSION,
                recording: origin.into(),
                nominal_scenario: nominal.to_toml(),
                command_lead: lead,
                block_s: split.block_s,
                holdout_every: cfg.holdout_every,
                effects: terms
                    .iter()
                    .map(|t| crate::augmented_model::AugmentedTerm {
                        name: t.effect.name().into(),
                        theta: t.theta.clone(),
                    })
                    .collect(),
                columns: built.design.names.clone(),
                coefficients: fitted.coef.clone(),
                noise: Some(noise.to_noise(built.full_load_a)),
            }
        };
    let model = as_model(
        &terms,
        &final_built,
        &final_fit,
        &final_noise,
        ctx.command_lead,
    );
    let baseline_model = as_model(&[], &base_built, &base_fit, &base_noise, base_lead);
    let final_resid = final_fit.residuals(y);
    let final_z = standardized(&final_resid, &final_w);
    let final_white = whiteness(&final_z, &split);
    let mut verdict: Vec<String> = terms.iter().map(|t| t.effect.name().to_string()).collect();
    if final_white.iter().any(|&p| p < white_threshold) {
        let rmse = holdout_rmse(&final_resid, &split.holdout);
        reports.push(EffectReport {
            name: UNEXPLAINED.into(),
            params: Vec::new(),
            explanation: "Structure remains in the held-out residuals that no catalog term \
                          explains; see where it is located."
                .into(),
            located: locate(
                &rows,
                &final_z,
                &split.holdout,
                Signal::Residual,
                cfg.significance,
            ),
            holdout_rmse_before_ut: rmse,
            holdout_rmse_after_ut: rmse,
            p_value: final_white.iter().cloned().fold(1.0, f64::min),
        });
        verdict.push(UNEXPLAINED.into());
    }

    // The simulation of the augmented scenario against the recording.
    let augmented = augmented.check(&format!("augmented {}", nominal.origin()), None)?;
    let sim_after = {
        let tr = replay(
            augmented.params(),
            &rec.t_s,
            &rec.thr,
            None,
            ctx.command_lead,
        );
        let design = Design::baseline(&tr);
        let f = fit(&design, y, Some(&tr.extra_ut), &final_w, &split.holdout).map_err(|_| {
            DiagnoseError::Singular {
                origin: origin.into(),
                message: "the augmented simulation cannot be calibrated".into(),
            }
        })?;
        holdout_rmse(&f.residuals(y), &split.holdout)
    };

    let baseline = Baseline {
        holdout_rmse_ut: base_rmse,
        structured: base_structured,
        whiteness_p: base_white,
        located: (base_structured || !terms.is_empty()).then(|| {
            locate(
                &rows,
                &base_z,
                &split.holdout,
                Signal::Residual,
                cfg.significance,
            )
        }),
        calibration: base_built
            .design
            .names
            .iter()
            .zip(base_fit.coef.iter().zip(&base_fit.coef_sd))
            .flat_map(|(name, (c, sd))| Param::axes(&format!("{name}_ut"), *c, *sd, "µT per unit"))
            .chain([Param::new(
                "command_lead",
                base_lead,
                None,
                "fraction of the interval before a row",
            )])
            .collect(),
    };
    Ok(Diagnosis {
        format: FORMAT.into(),
        version: VERSION,
        recording: origin.into(),
        scenario: nominal.origin().into(),
        verdict,
        baseline,
        effects: reports,
        simulation: SimulationAgreement {
            holdout_rmse_before_ut: base_rmse,
            holdout_rmse_after_ut: sim_after,
        },
        rounds,
        series: series(rec, &split.holdout, &stages),
        settings: Settings {
            significance: cfg.significance,
            holdout_every: cfg.holdout_every,
            block_s: split.block_s,
            rows: [split.fit_rows(), rec.len() - split.fit_rows()],
        },
        augmented_scenario: augmented.to_toml(),
        model: Some(model),
        baseline_model: Some(baseline_model),
    })
}

/// Held-out residuals of every stage at no more than [`SERIES_POINTS`] rows.
fn series(rec: &Recording, holdout: &[bool], stages: &[(String, Vec<Vec3>)]) -> Series {
    let held: Vec<usize> = (0..rec.len()).filter(|&r| holdout[r]).collect();
    let stride = held.len().div_ceil(SERIES_POINTS).max(1);
    let rows: Vec<usize> = held.into_iter().step_by(stride).collect();
    Series {
        t_s: rows.iter().map(|&r| rec.t_s[r]).collect(),
        throttle: rows.iter().map(|&r| rec.overall_throttle(r)).collect(),
        stages: stages
            .iter()
            .map(|(label, resid)| Stage {
                label: label.clone(),
                residual_ut: rows.iter().map(|&r| resid[r].into()).collect(),
            })
            .collect(),
    }
}
