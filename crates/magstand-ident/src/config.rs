//! Fit settings: an unchecked [`FitConfig`] becomes a [`ValidFitConfig`] through
//! [`FitConfig::check`], and only a valid one can [`Fit`].
use magstand_core::rbf::RbfPartition;
use magstand_core::{Recording, Vec3};

use crate::baseline;
use crate::dataset::{Dataset, HOLDOUT_EVERY, InputKind, STRUCTURE_SCORE_BLOCK};
use crate::local_linear::{self, Estimation, NetEquations};
use crate::model::{FitSummary, IdentifiedRange, Model, Structure};
use crate::noise_model::SdModel;
use crate::structure;
use crate::{FitSetting, IdentError};

/// Which model family to fit.
#[derive(Debug, Clone, PartialEq)]
pub enum Family {
    /// RBF-blended local linear models with fixed centres and widths.
    LocalLinear {
        /// RBF centres on the normalized input.
        centers: Vec<f64>,
        /// Width parameters `eps` (eq. 13), one per centre.
        widths: Vec<f64>,
        /// Local or global estimation.
        estimation: Estimation,
    },
    /// Local linear models whose number, centres and widths are chosen from the data.
    Automatic {
        /// Largest number of local models.
        max_models: usize,
        /// Local or global estimation.
        estimation: Estimation,
    },
    /// ArduPilot compassmot's running average through the origin.
    ArduPilot,
    /// PX4's least-squares line, slope only.
    Px4,
    /// A cubic with intercept.
    Cubic,
}

/// Unchecked fit settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FitConfig {
    /// Model family.
    pub family: Family,
    /// Model input.
    pub input: InputKind,
    /// Weight rows by the inverse of the fitted noise variance (heteroscedastic least squares).
    pub weighted: bool,
    /// Knots of the noise sd model.
    pub sd_knots: usize,
}

impl FitConfig {
    /// The paper's method: 3 local models at 0, 0.5, 1, width 4, local estimation, unweighted.
    pub fn paper() -> Self {
        Self::fixed(vec![0.0, 0.5, 1.0], 4.0, Estimation::Local)
    }

    /// Fixed centres sharing one width.
    pub fn fixed(centers: Vec<f64>, eps: f64, estimation: Estimation) -> Self {
        let widths = vec![eps; centers.len()];
        Self {
            family: Family::LocalLinear {
                centers,
                widths,
                estimation,
            },
            input: InputKind::Throttle,
            weighted: false,
            sd_knots: 11,
        }
    }

    /// `k` evenly spaced centres on 0..1 with the paper's width-to-spacing ratio (`eps = 2 (k-1)`).
    pub fn evenly_spaced(k: usize, estimation: Estimation) -> Self {
        Self::fixed(evenly_spaced_centers(k), paper_ratio_width(k), estimation)
    }

    /// A fixed local linear structure from what a user stated, the rest by the paper's rules:
    /// `centers` (or `rbf` of them evenly spaced on 0..1, or the paper's 0, 0.5, 1), `width`
    /// (or the paper's width-to-spacing ratio, [`paper_ratio_width`]), `estimation` (or the
    /// paper's local estimation), unweighted. Centres and a count that disagree are refused.
    pub fn stated_structure(
        centers: Option<Vec<f64>>,
        rbf: Option<usize>,
        width: Option<f64>,
        estimation: Option<Estimation>,
    ) -> Result<Self, IdentError> {
        let centers = match (centers, rbf) {
            (Some(c), Some(k)) if c.len() != k => {
                return Err(IdentError::InvalidSetting {
                    setting: FitSetting::Centers,
                    value: format!("{} centres", c.len()),
                    expected: format!("as many centres as local models ({k})"),
                });
            }
            (Some(c), _) => c,
            (None, Some(k)) => evenly_spaced_centers(k),
            (None, None) => evenly_spaced_centers(3),
        };
        let eps = width.unwrap_or(paper_ratio_width(centers.len()));
        Ok(
            Self::fixed(centers, eps, estimation.unwrap_or(Estimation::Local))
                .with_weighting(false),
        )
    }

    /// The automatic structure with at most `max_models` local models and `estimation` (global
    /// when not stated), inverse-variance weighted.
    pub fn automatic_with(max_models: usize, estimation: Option<Estimation>) -> Self {
        Self {
            family: Family::Automatic {
                max_models,
                estimation: estimation.unwrap_or(Estimation::Global),
            },
            ..Self::automatic()
        }
    }

    /// Automatic structure with global estimation and inverse-variance weighting.
    pub fn automatic() -> Self {
        Self {
            family: Family::Automatic {
                max_models: 10,
                estimation: Estimation::Global,
            },
            input: InputKind::Throttle,
            weighted: true,
            sd_knots: 11,
        }
    }

    /// A baseline family.
    pub fn baseline(family: Family) -> Self {
        Self {
            family,
            input: InputKind::Throttle,
            weighted: false,
            sd_knots: 11,
        }
    }

    /// With another input.
    pub fn with_input(mut self, input: InputKind) -> Self {
        self.input = input;
        self
    }

    /// With or without inverse-variance weighting.
    pub fn with_weighting(mut self, weighted: bool) -> Self {
        self.weighted = weighted;
        self
    }

    /// Checks every setting.
    pub fn check(self) -> Result<ValidFitConfig, IdentError> {
        let bad = |setting: FitSetting, value: String, expected: &str| {
            Err(IdentError::InvalidSetting {
                setting,
                value,
                expected: expected.into(),
            })
        };
        match &self.family {
            Family::LocalLinear {
                centers, widths, ..
            } => {
                if centers.is_empty() || centers.len() > 50 {
                    return bad(
                        FitSetting::LocalModels,
                        centers.len().to_string(),
                        "1..=50 local models",
                    );
                }
                if let Some(c) = centers
                    .iter()
                    .find(|c| !(c.is_finite() && (-1.0..=2.0).contains(*c)))
                {
                    return bad(
                        FitSetting::Centers,
                        c.to_string(),
                        "finite centres in -1..=2 (the input is normalized to 0..1)",
                    );
                }
                if let Some(w) = widths
                    .iter()
                    .find(|w| !(w.is_finite() && **w > 0.0 && **w <= 1e4))
                {
                    return bad(
                        FitSetting::Widths,
                        w.to_string(),
                        "a width parameter in (0, 10000]",
                    );
                }
                if widths.len() != centers.len() {
                    return bad(
                        FitSetting::Widths,
                        widths.len().to_string(),
                        "one width per centre",
                    );
                }
            }
            Family::Automatic { max_models, .. } => {
                if !(1..=30).contains(max_models) {
                    return bad(FitSetting::MaxModels, max_models.to_string(), "1..=30");
                }
            }
            Family::ArduPilot | Family::Px4 | Family::Cubic => {
                if self.input == InputKind::Motors {
                    return bad(
                        FitSetting::Input,
                        "motors".into(),
                        "throttle or current for the straight-line and cubic baselines",
                    );
                }
            }
        }
        if !(2..=101).contains(&self.sd_knots) {
            return bad(FitSetting::SdKnots, self.sd_knots.to_string(), "2..=101");
        }
        Ok(ValidFitConfig(self))
    }
}

/// `k` centres evenly spaced on 0..1 (one centre sits at 0.5).
pub fn evenly_spaced_centers(k: usize) -> Vec<f64> {
    (0..k)
        .map(|i| {
            if k > 1 {
                i as f64 / (k - 1) as f64
            } else {
                0.5
            }
        })
        .collect()
}

/// Width parameter with the paper's width-to-spacing ratio for `k` evenly spaced centres
/// (`eps = 2 (k-1)`: 4 for the paper's 3 centres).
pub fn paper_ratio_width(k: usize) -> f64 {
    2.0 * (k.max(2) - 1) as f64
}

/// Checked fit settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidFitConfig(FitConfig);

/// Something that fits a model to identification data.
pub trait Fit {
    /// What the fit returns.
    type Output;
    /// Fits.
    fn fit(&self, data: &Dataset) -> Result<Self::Output, IdentError>;
}

/// Something that predicts the disturbance at a row of a recording.
pub trait Predict {
    /// Predicted disturbance for every row, µT.
    fn predict(&self, rec: &Recording) -> Vec<Vec3>;
}

impl Predict for Model {
    fn predict(&self, rec: &Recording) -> Vec<Vec3> {
        self.dist_column(rec)
    }
}

impl ValidFitConfig {
    /// The settings.
    pub fn config(&self) -> &FitConfig {
        &self.0
    }

    /// Builds the dataset from a recording and fits.
    pub fn fit_recording(&self, rec: &Recording, origin: &str) -> Result<Model, IdentError> {
        self.fit(&Dataset::from_recording(rec, self.0.input, origin)?)
    }

    /// As [`ValidFitConfig::fit_recording`], with the eq. 9 reference to use when the
    /// recording has no motors-off rows ([`Dataset::from_recording_or`]).
    pub fn fit_recording_or(
        &self,
        rec: &Recording,
        origin: &str,
        fallback_reference_ut: Option<Vec3>,
    ) -> Result<Model, IdentError> {
        self.fit(&Dataset::from_recording_or(
            rec,
            self.0.input,
            origin,
            fallback_reference_ut,
        )?)
    }

    /// The method's name in the model file: one spelling, the one `runs.csv`, the studies
    /// and `--methods` use where they name the same thing (see [`crate::model::method_name`]).
    fn method_name(&self) -> String {
        let weighted = self.0.weighted;
        let w = if weighted { "-weighted" } else { "" };
        match &self.0.family {
            Family::LocalLinear {
                estimation: Estimation::Local,
                ..
            } => format!("local{w}"),
            Family::LocalLinear {
                estimation: Estimation::Global,
                ..
            } => format!("global{w}"),
            Family::Automatic { estimation, .. } => format!(
                "automatic{}{}",
                if *estimation == Estimation::Local {
                    "-local"
                } else {
                    ""
                },
                if weighted { "" } else { "-unweighted" }
            ),
            Family::ArduPilot => "ardupilot".into(),
            Family::Px4 => "px4".into(),
            Family::Cubic => "cubic".into(),
        }
    }

    /// One structure fitted on `rows`, with inverse-variance reweighting when configured.
    /// Returns the structure, and with `want_sd` (or when reweighting) the noise model of its
    /// residuals and the residuals themselves; and what a fit on more rows can reuse.
    fn fit_rows(
        &self,
        data: &Dataset,
        rows: &(dyn Fn(usize) -> bool + Sync),
        select: &(dyn Fn(usize) -> bool + Sync),
        want_sd: bool,
    ) -> Result<RowsFit, IdentError> {
        let unit = |_: usize| Vec3::repeat(1.0);
        // A long recording chooses its structure, and settles its noise weights, on every
        // `stride`-th row: the choice needs rows in every input bin and the noise law (a spline
        // over at most 101 knots) a few hundred per knot, not all of them. The coefficients,
        // residuals and noise model kept are then fitted on every row, once.
        let stride = data.len().div_ceil(structure::MAX_CHOICE_ROWS).max(1);
        let fit_with = |rows: &(dyn Fn(usize) -> bool + Sync),
                        weight: &(dyn Fn(usize) -> Vec3 + Sync),
                        weight_at: &dyn Fn(f64) -> Vec3|
         -> Result<(Structure, Option<NetEquations>), IdentError> {
            let (part, estimation) = match &self.0.family {
                Family::LocalLinear {
                    centers,
                    widths,
                    estimation,
                } => (
                    RbfPartition::new(centers.clone(), widths.clone())
                        .expect("checked in FitConfig::check"),
                    *estimation,
                ),
                Family::Automatic {
                    max_models,
                    estimation,
                } => {
                    // Choose on the fitting rows only: fit on some, score on others. A long
                    // recording chooses on every `stride`-th of them: the choice needs rows
                    // in every input bin, not all of them, and the coefficients are then
                    // fitted on every row.
                    let fit_part = |k: usize| k.is_multiple_of(stride) && rows(k) && !select(k);
                    let score_part = |k: usize| k.is_multiple_of(stride) && rows(k) && select(k);
                    (
                        structure::choose(
                            data,
                            *estimation,
                            *max_models,
                            &fit_part,
                            &score_part,
                            weight,
                            weight_at,
                        )?,
                        *estimation,
                    )
                }
                Family::ArduPilot => return Ok((baseline::ardupilot(data, rows)?, None)),
                Family::Px4 => return Ok((baseline::polynomial(data, 1, false, rows)?, None)),
                Family::Cubic => return Ok((baseline::polynomial(data, 3, true, rows)?, None)),
            };
            let (net, equations) =
                local_linear::fit_keeping_equations(data, &part, estimation, rows, weight)?;
            Ok((Structure::LocalLinear(net), equations))
        };
        let residual_sd = |s: &Structure| self.residuals_and_noise(data, s, rows);
        let estimation = self.local_estimation();
        let reweight = self.0.weighted && estimation.is_some();
        // A long recording settles its noise weights on the rows its structure search uses,
        // then fits the weighted coefficients on every row once (after the passes).
        let sampled = reweight && stride > 1;
        let spread = |k: usize| k.is_multiple_of(stride) && rows(k);
        let on: &(dyn Fn(usize) -> bool + Sync) = if sampled { &spread } else { rows };
        // The noise model of a structure's residuals on `on`, with every row's residuals when
        // `on` is every row.
        let noise_of = |s: &Structure| -> (Option<SdModel>, Option<Vec<Vec3>>) {
            if sampled {
                let r = unnamed_model(data, s.clone()).residuals_at(data, &spread);
                (SdModel::fit(&data.u, &r, spread, self.0.sd_knots), None)
            } else {
                let (sd, r) = residual_sd(s);
                (sd, Some(r))
            }
        };
        let (mut s, mut equations) = fit_with(on, &unit, &|_| Vec3::repeat(1.0))?;
        // The noise model that weighted the fit kept (none: unit weights).
        let mut weights_sd: Option<SdModel> = None;
        // A fit with what a fit on more rows can reuse, before any noise model is kept.
        let with_training = |s: Structure, weights: Option<SdModel>, equations| RowsFit {
            training: Some(TrainingFit {
                structure: s.clone(),
                weights,
                equations,
                sampled,
            }),
            structure: s,
            sd: None,
            residuals: None,
        };
        // The noise model costs a pass over the data: only when it weights or is kept.
        if !reweight && !want_sd {
            return Ok(with_training(s, None, equations));
        }
        let (mut sd, mut r) = noise_of(&s);
        if reweight {
            // Two reweighting passes: the second noise model comes from residuals of a fit that
            // no longer over-follows the noisiest samples. The first chooses the structure
            // again under its weights. So does the second on a short recording: on a noisy
            // real log of a few thousand rows the second choice differs from the first, and
            // keeping the first lost held-out accuracy there. A long recording's noise model,
            // settled on tens of thousands of spread rows, hardly moves between the passes:
            // its second pass refits the coefficients only (the same structure on the bench's
            // million rows, at a fifth of the fit's time).
            for pass in 0..2 {
                let Some(noise) = sd.clone() else { break };
                let w_at = |u: f64| weights_of(Some(&noise), u);
                let w = |k: usize| w_at(data.u[k]);
                (s, equations) = match (&s, estimation) {
                    (Structure::LocalLinear(net), Some(estimation)) if pass > 0 && sampled => {
                        let (net, equations) = local_linear::fit_keeping_equations(
                            data,
                            &net.partition,
                            estimation,
                            on,
                            &w,
                        )?;
                        (Structure::LocalLinear(net), equations)
                    }
                    _ => fit_with(on, &w, &w_at)?,
                };
                weights_sd = Some(noise.clone());
                if pass == 1 && !want_sd && !sampled {
                    // Nothing reads the last noise model: no pass follows to weight, and the
                    // fit does not keep one.
                    (sd, r) = (None, None);
                    break;
                }
                (sd, r) = noise_of(&s);
            }
        }
        if sampled {
            // The structure stays as the spread rows chose it; its coefficients take every row.
            if let (Structure::LocalLinear(net), Some(estimation)) = (&s, estimation) {
                let w = |k: usize| weights_of(sd.as_ref(), data.u[k]);
                let every;
                (every, equations) = local_linear::fit_keeping_equations(
                    data,
                    &net.partition,
                    estimation,
                    rows,
                    &w,
                )?;
                s = Structure::LocalLinear(every);
                weights_sd = sd.clone();
            }
            if !want_sd {
                // A training fit: its caller takes its residuals with the identified range set.
                return Ok(with_training(s, weights_sd, equations));
            }
            let (all_sd, all_r) = residual_sd(&s);
            (sd, r) = (all_sd, Some(all_r));
        }
        Ok(RowsFit {
            sd,
            residuals: r,
            ..with_training(s, weights_sd, equations)
        })
    }

    /// The fit on every row of the structure a training fit chose. Unweighted, or on a long
    /// recording, its noise weights (none, or settled on tens of thousands of spread rows) are
    /// kept and its normal equations take the rows it left out (`left_out`), so the rows it
    /// summed are not summed again. On a shorter one the noise model of a few hundred or
    /// thousand rows may not carry to the rows left out (a spline extrapolated to a tiny sd
    /// gives a row all the weight): the structure is refitted on every row with its own
    /// reweighting, as a stated structure would be. `None` when the training fit left nothing to reuse (a polynomial).
    fn refit_every_row(
        &self,
        data: &Dataset,
        training: &TrainingFit,
        left_out: &(dyn Fn(usize) -> bool + Sync),
    ) -> Option<Result<RowsFit, IdentError>> {
        let Structure::LocalLinear(net) = &training.structure else {
            return None;
        };
        let estimation = self.local_estimation()?;
        // Unit weights carry to any row; estimated ones only from a long recording.
        let trusted = training.weights.is_none() || training.sampled;
        let (Some(equations), true) = (&training.equations, trusted) else {
            let stated = ValidFitConfig(FitConfig {
                family: Family::LocalLinear {
                    centers: net.partition.centers().to_vec(),
                    widths: net.partition.widths().to_vec(),
                    estimation,
                },
                ..self.0.clone()
            });
            let select = stated.structure_score_rows(data);
            return Some(stated.fit_rows(data, &|_| true, &select, true));
        };
        let w = |k: usize| weights_of(training.weights.as_ref(), data.u[k]);
        let fitted = {
            let mut equations = equations.clone();
            equations.add_rows(data, left_out, &w);
            equations.solve(data)
        };
        Some(fitted.map(|net| {
            let s = Structure::LocalLinear(net);
            let (sd, r) = self.residuals_and_noise(data, &s, &|_| true);
            RowsFit {
                sd,
                residuals: Some(r),
                structure: s,
                training: None,
            }
        }))
    }

    /// The estimation of a local linear family; `None` for the autopilots' lines and the cubic.
    fn local_estimation(&self) -> Option<Estimation> {
        match &self.0.family {
            Family::LocalLinear { estimation, .. } | Family::Automatic { estimation, .. } => {
                Some(*estimation)
            }
            _ => None,
        }
    }

    /// A structure's residuals at every row, and the noise model of those on `rows`.
    fn residuals_and_noise(
        &self,
        data: &Dataset,
        s: &Structure,
        rows: &(dyn Fn(usize) -> bool + Sync),
    ) -> (Option<SdModel>, Vec<Vec3>) {
        let r = unnamed_model(data, s.clone()).residuals(data);
        (SdModel::fit(&data.u, &r, rows, self.0.sd_knots), r)
    }
}

/// A model of structure `s` on `data`'s input, without a name or a noise model: what a fit's
/// residuals are taken from before the model it keeps is made.
fn unnamed_model(data: &Dataset, s: Structure) -> Model {
    Model::new("", data.spec.clone(), data.reference_ut, s, None)
}

/// Inverse-variance weights per axis at normalized input `u` under `noise` (unit weights
/// without one).
fn weights_of(noise: Option<&SdModel>, u: f64) -> Vec3 {
    noise.map_or(Vec3::repeat(1.0), |noise| {
        noise.sd(u).map(|s| 1.0 / (s * s))
    })
}

/// What a fit leaves on the rows it held out: the evidence a comparison of models rests on.
#[derive(Debug, Clone)]
pub struct HeldOut {
    /// Whether each row was held out of the training fit ([`Dataset::holdout_mask`]).
    pub mask: Vec<bool>,
    /// Residual of the training fit (fitted without the held-out rows) at each held-out row,
    /// in row order, µT (the other rows are not evidence, and not computed).
    pub residuals_ut: Vec<Vec3>,
    /// Parameters of the training fit: the model those residuals judge.
    pub parameters: usize,
    /// What the fit on every row reuses.
    training: Option<TrainingFit>,
}

impl Fit for ValidFitConfig {
    type Output = Model;

    fn fit(&self, data: &Dataset) -> Result<Model, IdentError> {
        Ok(self.fit_holding_out(data)?.0)
    }
}

impl ValidFitConfig {
    /// Fits, and returns with the model the training fit's residuals that gave its held-out
    /// RMSE (at no extra cost: the fit makes them anyway).
    pub fn fit_holding_out(&self, data: &Dataset) -> Result<(Model, HeldOut), IdentError> {
        let held = self.held_out(data)?;
        let model = self.fit_judged(data, &held)?;
        Ok((model, held))
    }

    /// The first half of [`fit_holding_out`](Self::fit_holding_out): the training fit without
    /// the held-out time blocks, and its residuals at every row (the evidence a choice among
    /// families rests on; only the family chosen then needs
    /// [`fit_judged`](Self::fit_judged)).
    pub fn held_out(&self, data: &Dataset) -> Result<HeldOut, IdentError> {
        let holdout = data.holdout_mask();
        let select = self.structure_score_rows(data);
        let train = |k: usize| !holdout[k];
        let fitted = self.fit_rows(data, &train, &select, false)?;
        let mut train_model = unnamed_model(data, fitted.structure);
        // Held-out blocks beyond the training rows' range see the continuation a user's later
        // rows would.
        train_model.identified =
            IdentifiedRange::of_rows(&data.u, train, data.spec.normalize(data.spec.off_raw));
        // Only the held-out rows' residuals are evidence: the others are not computed.
        let residuals_ut = train_model.residuals_where(data, &|k| holdout[k]);
        Ok(HeldOut {
            mask: holdout,
            residuals_ut,
            parameters: train_model.parameter_count(),
            training: fitted.training,
        })
    }

    /// The model fitted on every row, without a summary, and its residuals: what
    /// [`fit_judged`](Self::fit_judged) summarizes, for a caller that judges the model by
    /// other means (a Monte Carlo study, against the simulator's truth) and needs no training
    /// fit.
    pub fn fit_every_row(&self, data: &Dataset) -> Result<(Model, Vec<Vec3>), IdentError> {
        let select = self.structure_score_rows(data);
        let fitted = self.fit_rows(data, &|_| true, &select, true)?;
        Ok(self.model_of(data, fitted))
    }

    /// The model fitted on every row for its predictions alone: no noise model (a weighted
    /// fit still settles its weights) and no residuals, the passes a Monte Carlo study, which
    /// judges the predictions against the simulator's truth, would throw away. The structure
    /// and coefficients are [`fit_every_row`](Self::fit_every_row)'s.
    pub fn fit_to_predict(&self, data: &Dataset) -> Result<Model, IdentError> {
        let select = self.structure_score_rows(data);
        let fitted = self.fit_rows(data, &|_| true, &select, false)?;
        let mut model = self.named_model(data, fitted.structure, None);
        model.identified = IdentifiedRange::of(&data.u, data.spec.normalize(data.spec.off_raw));
        Ok(model)
    }

    /// The model of `structure` fitted on `data`, named for this configuration.
    fn named_model(&self, data: &Dataset, structure: Structure, sd: Option<SdModel>) -> Model {
        Model::new(
            &self.method_name(),
            data.spec.clone(),
            data.reference_ut,
            structure,
            sd,
        )
    }

    /// The model of a fit on every row, and its residuals.
    fn model_of(&self, data: &Dataset, fitted: RowsFit) -> (Model, Vec<Vec3>) {
        let RowsFit {
            structure,
            sd,
            residuals,
            ..
        } = fitted;
        let mut model = self.named_model(data, structure, sd);
        // Residuals and statistics come from the model as fitted; the identified range (and
        // with it the continuation beyond) is set afterwards, and changes nothing inside it.
        let r = residuals.unwrap_or_else(|| model.residuals(data));
        model.identified = IdentifiedRange::of(&data.u, data.spec.normalize(data.spec.off_raw));
        (model, r)
    }

    /// Rows that score a structure search: their own blocks, never the held-out ones.
    fn structure_score_rows<'d>(&self, data: &'d Dataset) -> impl Fn(usize) -> bool + Sync + 'd {
        let blocks = &data.split().block;
        move |k: usize| blocks[k] % HOLDOUT_EVERY == STRUCTURE_SCORE_BLOCK
    }

    /// The second half of [`fit_holding_out`](Self::fit_holding_out): the fit on every row,
    /// with its summary's held-out RMSE from `held`, the training fit of the same data.
    pub fn fit_judged(&self, data: &Dataset, held: &HeldOut) -> Result<Model, IdentError> {
        let (holdout, r_train) = (&held.mask, &held.residuals_ut);
        // The structure the held-out rows judged, fitted on every row; a fit without one to
        // reuse (a polynomial) is fitted anew.
        let left_out = |k: usize| holdout[k];
        let refit = held
            .training
            .as_ref()
            .and_then(|t| self.refit_every_row(data, t, &left_out));
        let (mut model, r) = match refit {
            Some(fitted) => self.model_of(data, fitted?),
            None => self.fit_every_row(data)?,
        };
        let holdout_rows = holdout.iter().filter(|h| **h).count();
        let rms = |rows: &mut dyn Iterator<Item = Vec3>, n: usize| -> [f64; 3] {
            let s = rows.fold(Vec3::zeros(), |acc, v| acc + v.component_mul(&v));
            [0, 1, 2].map(|a| (s[a] / n.max(1) as f64).sqrt())
        };
        let rmse_ut = rms(&mut r.iter().copied(), r.len());
        let holdout_rmse_ut = rms(&mut r_train.iter().copied(), holdout_rows);
        let mean = data.y.iter().sum::<Vec3>() / data.len() as f64;
        let var = data.y.iter().fold(Vec3::zeros(), |acc, y| {
            acc + (y - mean).component_mul(&(y - mean))
        }) / data.len() as f64;
        let r2 = [0, 1, 2].map(|a| {
            if var[a] > 0.0 {
                1.0 - rmse_ut[a].powi(2) / var[a]
            } else {
                0.0
            }
        });
        let terms = match &model.structure {
            Structure::LocalLinear(n) => n.partition.len(),
            Structure::Polynomial { coefficients } => {
                coefficients[0].iter().filter(|c| **c != 0.0).count()
            }
        };
        model.summary = Some(FitSummary {
            rows: data.len(),
            holdout_rows,
            rmse_ut,
            r2,
            holdout_rmse_ut,
            terms,
        });
        Ok(model)
    }
}

/// What a fit on chosen rows gives.
struct RowsFit {
    /// The structure fitted.
    structure: Structure,
    /// The noise model of its residuals, when asked for.
    sd: Option<SdModel>,
    /// Its residuals at every row, when asked for.
    residuals: Option<Vec<Vec3>>,
    /// What a fit on more rows can reuse.
    training: Option<TrainingFit>,
}

/// What a training fit keeps for the fit on every row ([`ValidFitConfig::fit_judged`]): the
/// structure it chose, the noise model that weighted its coefficients, and their normal
/// equations where they were summed row by row. The model kept is then the structure the
/// held-out error judged, fitted on every row with the same weights.
#[derive(Debug, Clone)]
struct TrainingFit {
    structure: Structure,
    weights: Option<SdModel>,
    equations: Option<NetEquations>,
    /// Whether the noise weights were settled on rows spread over a long recording (tens of
    /// thousands): only then are they trusted for the rows the training fit left out.
    sampled: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::local_linear::LocalLinearNet;

    /// A slow ramp of `n` rows whose input never repeats, a curved deviation and noise growing
    /// with the input: the inputs are not grouped, so a training fit keeps its normal
    /// equations.
    fn ramp(n: usize) -> Dataset {
        let mut rec = Recording {
            thr: vec![vec![]],
            overall_only: true,
            ..Default::default()
        };
        let off = n / 12;
        for k in 0..n {
            let u = if k < off {
                0.0
            } else {
                (k - off) as f64 / (n - off) as f64
            };
            rec.t_s.push(k as f64 * 0.01);
            rec.thr[0].push(u);
            let noise = (0.05 + 0.4 * u) * ((k as f64) * 12.9898).sin();
            rec.mag_ut.push(
                Vec3::new(20.0 + 6.0 * u * u, 1.0 - 3.0 * u, 45.0 + 9.0 * u.powi(3))
                    + Vec3::repeat(noise),
            );
        }
        Dataset::from_recording(&rec, InputKind::Throttle, "ramp").unwrap()
    }

    /// The judged structure's partition and its coefficients, asserted against `expected`.
    fn assert_same_coefficients(kept: &LocalLinearNet, expected: &LocalLinearNet, what: &str) {
        for a in 0..3 {
            for (m, (x, y)) in kept.coefficients[a]
                .iter()
                .zip(&expected.coefficients[a])
                .enumerate()
            {
                for (c, d) in x.iter().zip(y) {
                    assert!(
                        (c - d).abs() <= 1e-9 * (1.0 + d.abs()),
                        "{what}: axis {a} model {m}: kept {x:?}, expected {y:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_model_kept_is_the_judged_structure_fitted_on_every_row() {
        let cfg = FitConfig::automatic().check().unwrap();
        let Family::Automatic { estimation, .. } = cfg.config().family else {
            panic!("the automatic family")
        };
        for n in [6_000, 120_000] {
            let data = ramp(n);
            assert!(
                data.group_index().is_none(),
                "a ramp's inputs do not repeat"
            );
            let held = cfg.held_out(&data).unwrap();
            let training = held
                .training
                .as_ref()
                .expect("a local linear fit keeps its training");
            assert!(training.weights.is_some(), "the automatic fit is weighted");
            let Structure::LocalLinear(judged) = &training.structure else {
                panic!("a local linear structure")
            };
            let model = cfg.fit_judged(&data, &held).unwrap();
            let Structure::LocalLinear(kept) = &model.structure else {
                panic!("a local linear structure")
            };
            assert_eq!(
                kept.partition, judged.partition,
                "{n} rows: the structure judged is kept"
            );
            if training.sampled {
                // A long recording: the training rows' equations plus the held-out rows' are
                // the fit on every row with the training fit's noise weights.
                assert!(n > structure::MAX_CHOICE_ROWS, "{n} rows sampled");
                let w = |k: usize| weights_of(training.weights.as_ref(), data.u[k]);
                let direct =
                    local_linear::fit(&data, &kept.partition, estimation, &|_| true, &w).unwrap();
                assert_same_coefficients(kept, &direct, "long recording");
            } else {
                // A short one: the structure refitted on every row with its own reweighting,
                // as a stated structure is.
                assert!(n <= structure::MAX_CHOICE_ROWS, "{n} rows not sampled");
                let stated = ValidFitConfig(FitConfig {
                    family: Family::LocalLinear {
                        centers: judged.partition.centers().to_vec(),
                        widths: judged.partition.widths().to_vec(),
                        estimation,
                    },
                    ..cfg.config().clone()
                });
                let (direct, _) = stated.fit_every_row(&data).unwrap();
                let Structure::LocalLinear(direct) = &direct.structure else {
                    panic!("a local linear structure")
                };
                assert_same_coefficients(kept, direct, "short recording");
            }
            // An unweighted fit's equations carry to any row: the paper's fixed structure
            // reuses them whatever the length.
            let paper = FitConfig::paper().check().unwrap();
            let Family::LocalLinear { estimation, .. } = paper.config().family else {
                panic!("the paper's fixed structure")
            };
            let paper_held = paper.held_out(&data).unwrap();
            let paper_training = paper_held.training.as_ref().unwrap();
            assert!(paper_training.weights.is_none() && paper_training.equations.is_some());
            let paper_model = paper.fit_judged(&data, &paper_held).unwrap();
            let Structure::LocalLinear(paper_kept) = &paper_model.structure else {
                panic!("a local linear structure")
            };
            let unit = |_: usize| Vec3::repeat(1.0);
            let direct =
                local_linear::fit(&data, &paper_kept.partition, estimation, &|_| true, &unit)
                    .unwrap();
            assert_same_coefficients(paper_kept, &direct, "paper fit");
            // The held-out RMSE is the training fit's on the held-out rows, and those rows'
            // only.
            let summary = model.summary.as_ref().unwrap();
            assert!(summary.holdout_rows > 0 && summary.holdout_rows < data.len());
            let held_rows: Vec<usize> = (0..data.len()).filter(|&k| held.mask[k]).collect();
            assert_eq!(held.residuals_ut.len(), held_rows.len());
            assert_eq!(summary.holdout_rows, held_rows.len());
        }
    }

    #[test]
    fn a_structure_stated_by_nothing_is_the_papers() {
        assert_eq!(
            FitConfig::stated_structure(None, None, None, None).unwrap(),
            FitConfig::paper()
        );
        // Four evenly spaced at the paper's ratio: spacing 1/3, width 6.
        let four = FitConfig::stated_structure(None, Some(4), None, None).unwrap();
        assert_eq!(
            four,
            FitConfig::fixed(evenly_spaced_centers(4), 6.0, Estimation::Local)
        );
        let e = FitConfig::stated_structure(Some(vec![0.0, 1.0]), Some(3), None, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("`centers`") && e.contains("(3)"), "{e}");
        assert_eq!(
            FitConfig::automatic_with(10, None),
            FitConfig::automatic(),
            "the automatic defaults"
        );
    }
}
