//! One Monte Carlo run: simulate an identification and a validation series, fit every method,
//! judge each on the validation series against the simulator's truth.
use magstand_core::{Recording, Vec3};
use magstand_ident::metrics::Evaluation;
use magstand_ident::{Dataset, InputKind};
use magstand_sim::ValidScenario;
use rand::SeedableRng;

use crate::StudyError;
use crate::config::ValidStudy;
use crate::crlb::{self, Bound};

/// Throttle bins of the error-against-throttle figures: `[i/BINS, (i+1)/BINS)`, the last one
/// closed.
pub const BINS: usize = 10;

/// What one method gave in one run.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodOutcome {
    /// Run index.
    pub run: usize,
    /// Seed of the run's identification series (validation and draws derive from it).
    pub seed: u64,
    /// Method id.
    pub method: String,
    /// Why the method failed in this run, if it did (e.g. singular data).
    pub error: Option<String>,
    /// The figures, when it did not fail.
    pub figures: Option<Figures>,
}

/// Accuracy figures of one fitted model on the validation series.
#[derive(Debug, Clone, PartialEq)]
pub struct Figures {
    /// RMSE of the predicted against the true disturbance per axis, µT.
    pub rmse_axis_ut: [f64; 3],
    /// RMSE of the error vector's norm, µT.
    pub rmse_ut: f64,
    /// RMS eq. 20 error with the motors running (norm over axes), % of the field norm.
    pub e20_rms_pct: f64,
    /// Worst level-mean heading error before compensation, degrees.
    pub heading_before_deg: f64,
    /// Worst level-mean heading error after compensation, degrees.
    pub heading_after_deg: f64,
    /// RMSE of the error vector's norm per throttle bin, µT (NaN where no rows fall).
    pub bin_rmse_ut: [f64; BINS],
    /// Parameter errors against the pseudo-true parameters, per axis (fixed structure only).
    pub param_error: Option<[Vec<f64>; 3]>,
    /// Diagonal of the run's CRLB per axis (fixed structure only).
    pub crlb_diag: Option<[Vec<f64>; 3]>,
}

/// A well-mixed 64-bit seed from the study seed and an index (SplitMix64 finalizer), so runs
/// get unrelated random streams whatever their order or shard.
pub fn derive_seed(seed: u64, index: u64) -> u64 {
    magstand_core::seeds::derive(seed, index.wrapping_add(1))
}

/// The identification and validation scenarios of run `run`, with its parameter draws.
pub fn run_scenarios(
    study: &ValidStudy,
    seed: u64,
) -> Result<(ValidScenario, ValidScenario), StudyError> {
    let vary = &study.scenario.params().study;
    if vary.vary.is_empty() {
        return Ok((study.identification.clone(), study.validation.clone()));
    }
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(derive_seed(seed, 0xD1A5));
    let draws = vary.draw(&mut rng);
    Ok((
        study.identification.with_overrides(&draws)?,
        study.validation.with_overrides(&draws)?,
    ))
}

/// The identification series of run `run`: its seed, its scenario (with the run's parameter
/// draws) and its recording, exactly as the study fits it.
pub fn identification_series(
    study: &ValidStudy,
    run: usize,
) -> Result<(u64, ValidScenario, Recording), StudyError> {
    let seed = derive_seed(study.config.seed, run as u64);
    let (ident_s, _) = run_scenarios(study, seed)?;
    let ident = magstand_sim::simulate(&ident_s, seed);
    Ok((seed, ident_s, ident))
}

/// Runs run `run` of the study: its identification and validation series simulated together
/// ([`magstand_sim::simulate_batch`]), every method fitted on the first and judged on the second.
pub fn run_one(study: &ValidStudy, run: usize) -> Result<Vec<MethodOutcome>, StudyError> {
    let seed = derive_seed(study.config.seed, run as u64);
    let (ident_s, valid_s) = run_scenarios(study, seed)?;
    let mut series =
        magstand_sim::simulate_batch(&[(&ident_s, seed), (&valid_s, derive_seed(seed, 0x7A11D))])
            .into_iter();
    let (ident, valid) = (
        series.next().expect("an identification series per run"),
        series.next().expect("a validation series per run"),
    );
    Ok(judge(study, run, seed, &ident, &valid))
}

/// Fits every method on run `run`'s identification series and judges it on the validation
/// series.
fn judge(
    study: &ValidStudy,
    run: usize,
    seed: u64,
    ident: &Recording,
    valid: &Recording,
) -> Vec<MethodOutcome> {
    let needs_bound = study.methods.iter().any(|m| m.fixed_structure);
    let bound = if needs_bound {
        crlb::fixed_structure_bound(ident)
    } else {
        None
    };
    let origin = format!("run {run} identification series");
    // The methods on one input share its identification data (and the grouping of its rows):
    // built once per input, every input's sharing one copy of the deviations, times and split.
    let mut datasets: Vec<(InputKind, Result<Dataset, String>)> = Vec::new();
    for m in &study.methods {
        if let magstand_ident::methods::Fitter::Config(c) = &m.fitter
            && !datasets.iter().any(|(k, _)| *k == c.input)
        {
            let d = match datasets.iter().find_map(|(_, d)| d.as_ref().ok()) {
                Some(first) => first.with_input(ident, c.input),
                None => Dataset::from_recording(ident, c.input, &origin),
            };
            datasets.push((c.input, d.map_err(|e| e.to_string())));
        }
    }
    let dataset_of = |input: InputKind| -> Result<&Dataset, String> {
        match datasets.iter().find(|(k, _)| *k == input) {
            Some((_, Ok(d))) => Ok(d),
            Some((_, Err(e))) => Err(e.clone()),
            // Every method's input has its dataset by construction above.
            None => Err(format!(
                "{origin}: no identification data for input {input:?}"
            )),
        }
    };
    study
        .methods
        .iter()
        .map(|m| {
            let judged = match &m.fitter {
                magstand_ident::methods::Fitter::Config(config) => config
                    .clone()
                    .check()
                    .map_err(|e| e.to_string())
                    .and_then(|c| {
                        // Judged against the truth below: no training fit for a held-out
                        // error the study does not report.
                        dataset_of(config.input)
                            .and_then(|d| c.fit_to_predict(d).map_err(|e| e.to_string()))
                    })
                    .and_then(|model| {
                        let predicted = model.dist_column(valid);
                        within_range(figures(
                            &predicted,
                            Vec3::from(model.reference_ut),
                            Some(&model),
                            valid,
                            if m.fixed_structure {
                                bound.as_ref()
                            } else {
                                None
                            },
                        ))
                    }),
                other => physics_family(other, ident, &origin, valid)
                    .and_then(|(dist, r)| within_range(figures(&dist, r, None, valid, None))),
            };
            let (error, figures) = match judged {
                Ok(f) => (None, Some(f)),
                Err(e) => (Some(e), None),
            };
            MethodOutcome {
                run,
                seed,
                method: m.id.to_string(),
                error,
                figures,
            }
        })
        .collect()
}

/// The figures, or why the run counts as failed: a figure beyond
/// [`crate::runs_csv::MAX_FIGURE`] is a diverged fit, which runs.csv could not hold and the
/// summary's sums would not survive.
fn within_range(f: Figures) -> Result<Figures, String> {
    let params = |v: &Option<[Vec<f64>; 3]>| -> Vec<f64> {
        v.iter()
            .flat_map(|axes| axes.iter().flatten().copied())
            .collect()
    };
    let all = f
        .rmse_axis_ut
        .iter()
        .chain(&[
            f.rmse_ut,
            f.e20_rms_pct,
            f.heading_before_deg,
            f.heading_after_deg,
        ])
        .chain(&f.bin_rmse_ut)
        .copied()
        .chain(params(&f.param_error))
        .chain(params(&f.crlb_diag))
        .collect::<Vec<f64>>();
    match all
        .iter()
        .find(|v| v.is_finite() && v.abs() > crate::runs_csv::MAX_FIGURE)
    {
        Some(v) => Err(format!(
            "the fit diverged: a figure of {v:e} is beyond {:e}",
            crate::runs_csv::MAX_FIGURE
        )),
        None => Ok(f),
    }
}

/// The physics or the chosen family fitted on the identification series; its predicted
/// disturbance on the validation series and its motors-off field. The nominal stand is the
/// unstated one: a study's user has not told the model anything about the stand.
fn physics_family(
    fitter: &magstand_ident::methods::Fitter,
    ident: &Recording,
    origin: &str,
    valid: &Recording,
) -> Result<(Vec<Vec3>, Vec3), String> {
    use magstand_diagnose::model_choice::{choose_model, fit_physics, identification_split};
    let e = |e: magstand_diagnose::DiagnoseError| e.to_string();
    let nominal = magstand_diagnose::unstated_nominal().map_err(e)?;
    let name = "validation series";
    if *fitter == magstand_ident::methods::Fitter::Physics {
        let split = identification_split(ident).check().map_err(e)?;
        let p = fit_physics(ident, origin, &nominal, &split).map_err(e)?;
        return Ok((
            p.model.dist_column(valid, name).map_err(e)?,
            p.model.reference_ut(),
        ));
    }
    let (chosen, _) = choose_model(ident, origin, &nominal, None).map_err(e)?;
    let reference = match &chosen {
        magstand_diagnose::model_choice::DisturbanceModel::LocalLinear(m) => {
            Vec3::from(m.reference_ut)
        }
        magstand_diagnose::model_choice::DisturbanceModel::Physics(m) => m.reference_ut(),
    };
    Ok((chosen.dist_column(valid, name).map_err(e)?, reference))
}

fn figures(
    predicted: &[Vec3],
    reference_ut: Vec3,
    model: Option<&magstand_ident::Model>,
    valid: &Recording,
    bound: Option<&Bound>,
) -> Figures {
    let ev = Evaluation::from_prediction_at(reference_ut, valid, predicted);
    let truth = valid
        .truth
        .as_ref()
        .expect("simulated recordings carry the truth");
    let mut sum = [0.0; BINS];
    let mut count = [0usize; BINS];
    let mut total = 0.0;
    for (k, (p, t)) in predicted.iter().zip(&truth.dist_ut).enumerate() {
        let e2 = (p - t).norm_squared();
        total += e2;
        let bin = ((valid.overall_throttle(k) * BINS as f64) as usize).min(BINS - 1);
        sum[bin] += e2;
        count[bin] += 1;
    }
    let bin_rmse_ut = std::array::from_fn(|b| {
        if count[b] == 0 {
            f64::NAN
        } else {
            (sum[b] / count[b] as f64).sqrt()
        }
    });
    let rmse_axis_ut = ev.truth_rmse_ut.unwrap_or([f64::NAN; 3]);
    let param_error = bound.and_then(|b| {
        let est = crlb::flatten(model?)?;
        Some(std::array::from_fn(|a| {
            est[a].iter().zip(&b.truth[a]).map(|(e, t)| e - t).collect()
        }))
    });
    Figures {
        rmse_axis_ut,
        rmse_ut: (total / valid.len().max(1) as f64).sqrt(),
        e20_rms_pct: Vec3::from(ev.e20_rms_pct).norm(),
        heading_before_deg: ev.heading_before_max_deg,
        heading_after_deg: ev.heading_after_max_deg,
        bin_rmse_ut,
        crlb_diag: param_error.as_ref().and(bound.map(|b| b.crlb_diag.clone())),
        param_error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fine() -> Figures {
        Figures {
            rmse_axis_ut: [0.1, 0.2, 0.3],
            rmse_ut: 0.4,
            e20_rms_pct: 1.0,
            heading_before_deg: 5.0,
            heading_after_deg: 0.5,
            bin_rmse_ut: [f64::NAN; BINS],
            param_error: None,
            crlb_diag: None,
        }
    }

    /// Regression: a diverged fit's figure of 1.8e308 was written to runs.csv, which merge
    /// then refused to read (figures are bounded by MAX_FIGURE there). The run now counts as
    /// failed, with why, and what is written can be read back.
    #[test]
    fn a_diverged_fit_is_a_failed_run_that_runs_csv_can_hold() {
        assert!(within_range(fine()).is_ok());
        let mut huge = fine();
        huge.param_error = Some([vec![1.7e308], vec![0.0], vec![0.0]]);
        let why = within_range(huge).unwrap_err();
        assert!(why.contains("diverged") && why.contains("1.7e308"), "{why}");
        let outcome = MethodOutcome {
            run: 0,
            seed: 1,
            method: "px4".into(),
            error: Some(why),
            figures: None,
        };
        let bytes = crate::runs_csv::to_bytes(&[outcome]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("runs.csv");
        std::fs::write(&path, bytes).unwrap();
        let back = crate::runs_csv::read(&path).unwrap();
        assert!(back[0].error.as_deref().unwrap().contains("diverged"));
    }
}
