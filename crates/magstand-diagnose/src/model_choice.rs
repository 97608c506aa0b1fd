//! The stand's physics as a fitted model (`magstand fit --method physics`), and the automatic
//! choice among model families that `magstand fit` makes by default.
//!
//! # The physics model
//!
//! [`fit_physics`] is the diagnosis's calibration, kept as a model: the recording's own
//! commands replayed through the nominal stand (dead zone, spin-up, the logged supply voltage
//! `bat_v` where there is one, else the stated or default supply, current law), with every constant the scenario leaves out calibrated, the
//! wiring gains, the current-law cubic and the motors-off field fitted by least squares, and
//! any effect the data demand switched on (the diagnosis's forward search: only terms that
//! replicate). It is the same code as `magstand diagnose`, not a copy: the model is the
//! diagnosis's [`AugmentedModel`]. Constants the scenario writes out are held.
//!
//! # The choice
//!
//! [`choose_model`] fits each family on the recording without its held-out time blocks (the
//! identification split: every fifth block of 1/50 of the recording, at most 1 s) and keeps
//! one by the rule of [`magstand_ident::family_choice`]; only the family kept is then fitted
//! on every row (a local linear family's parameters in the table are its training fit's):
//!
//! | family | tried when |
//! |---|---|
//! | `automatic` (local linear, automatic structure, throttle) | always |
//! | `automatic-current` (the same on `bat_a`) | `bat_a` is logged |
//! | `automatic-motors` (the same on each motor's command) | the motor commands differ |
//! | `physics` | a stand recording (not a flight) of at most [`PHYSICS_MAX_ROWS`] rows |
use std::borrow::Cow;

use magstand_core::{Recording, Vec3};
use magstand_ident::family_choice::{Contender, FamilyChoice, FamilyId, choose};
use magstand_ident::{Dataset, FitConfig, InputKind, Model, ValidFitConfig};
use magstand_sim::ValidScenario;

use crate::augmented_model::AugmentedModel;
use crate::diagnosis::Diagnosis;
use crate::{DiagnoseConfig, DiagnoseError};

/// Family id of the physics model.
pub const PHYSICS: &str = magstand_ident::methods::PHYSICS_ID;

/// Most rows the automatic choice fits the physics family on: each of its parameter searches
/// replays the whole recording, about a second per 25,000 rows. A longer recording is fitted
/// by the other families, and the table says why physics was not tried (`fit --method
/// physics` fits it anyway).
pub const PHYSICS_MAX_ROWS: usize = 200_000;

/// The physics model and the diagnosis it came from.
#[derive(Debug, Clone)]
pub struct PhysicsFit {
    /// The calibrated physics.
    pub model: AugmentedModel,
    /// The diagnosis (its calibration and any effects the data demanded).
    pub diagnosis: Diagnosis,
}

/// Fits the stand's physics to `rec` (named `origin`), with the split of `config`.
pub fn fit_physics(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    config: &crate::ValidConfig,
) -> Result<PhysicsFit, DiagnoseError> {
    let diagnosis = crate::pipeline::diagnose_with(
        rec,
        origin,
        nominal,
        config,
        true,
        &crate::observer::Silent,
    )?;
    let mut model = diagnosis
        .model
        .clone()
        .ok_or_else(|| DiagnoseError::Recording {
            origin: origin.into(),
            message: "the calibration gave no model".into(),
        })?;
    model.method = Some(PHYSICS.into());
    Ok(PhysicsFit { model, diagnosis })
}

/// The split settings under which the diagnosis holds out the same rows as an identification
/// fit of `rec` ([`Dataset::holdout_mask`]): blocks of 1/50 of the span (at most 1 s), every
/// fifth held out.
pub fn identification_split(rec: &Recording) -> DiagnoseConfig {
    DiagnoseConfig {
        block_s: Some(magstand_ident::identification_block_s(&rec.t_s)),
        holdout_every: magstand_ident::HOLDOUT_EVERY,
        ..Default::default()
    }
}

/// Every model `magstand compensate` takes: the one a choice kept, or one read from a file
/// (the file's declared format says which).
#[derive(Debug, Clone)]
pub enum DisturbanceModel {
    /// A local linear model (on throttle, current or each motor's command).
    LocalLinear(Box<Model>),
    /// The stand's physics.
    Physics(Box<AugmentedModel>),
}

/// Whether any motor's command differs from another's in at least 1 % of the rows by more
/// than 0.001: only then can a per-motor model be told from a throttle one.
fn commands_differ(rec: &Recording) -> bool {
    if rec.overall_only || rec.thr.len() < 2 {
        return false;
    }
    let differing = (0..rec.len())
        .filter(|&r| {
            let (lo, hi) = rec
                .thr
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), m| {
                    (a.min(m[r]), b.max(m[r]))
                });
            hi - lo > 1e-3
        })
        .count();
    differing * 100 >= rec.len()
}

/// Fits every family that applies to `rec` and keeps one by the rule of
/// [`magstand_ident::family_choice`]. `fallback_reference_ut` is a flight's motors-off field
/// (see [`Dataset::from_recording_or`]); `nominal` is the stand the physics family starts from.
pub fn choose_model(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    fallback_reference_ut: Option<Vec3>,
) -> Result<(DisturbanceModel, FamilyChoice), DiagnoseError> {
    // The throttle family's data, which every recording can take (its failure is the
    // recording's, and says so); the other inputs' data share its deviations, times and split.
    let base = Dataset::from_recording_or(rec, InputKind::Throttle, origin, fallback_reference_ut)?;
    // Each local family's training fit only: the held-out residuals judge it, and only the
    // family chosen is then fitted on every row.
    let local = |input: InputKind| -> Result<LocalFamily, DiagnoseError> {
        let cfg: ValidFitConfig = FitConfig::automatic().with_input(input).check()?;
        let data = match input {
            InputKind::Throttle => Cow::Borrowed(&base),
            _ => Cow::Owned(base.with_input(rec, input)?),
        };
        let held = cfg.held_out(&data)?;
        Ok(LocalFamily { cfg, data, held })
    };
    let physics = || -> Result<PhysicsFit, String> {
        if magstand_ident::flight::is_flight(rec) {
            return Err("not tried: a flight, not a restrained stand".into());
        }
        if rec.len() > PHYSICS_MAX_ROWS {
            return Err(format!(
                "not tried: {} rows, above the {PHYSICS_MAX_ROWS} the choice fits it on (the physics method asked for alone fits it anyway)",
                rec.len()
            ));
        }
        let split = identification_split(rec)
            .check()
            .map_err(|e| e.to_string())?;
        fit_physics(rec, origin, nominal, &split).map_err(|e| e.to_string())
    };
    let tried = |applies: bool, input: InputKind, why: &str| {
        if applies {
            local(input).map_err(|e| e.to_string())
        } else {
            Err(why.to_string())
        }
    };
    // Four independent fits: two pairs, one per core.
    let ((throttle, current), (motors, physics)) = rayon::join(
        || {
            rayon::join(
                || local(InputKind::Throttle),
                || {
                    tried(
                        rec.bat_a.is_some(),
                        InputKind::Current,
                        "not tried: no `bat_a` column",
                    )
                },
            )
        },
        || {
            rayon::join(
                || {
                    tried(
                        commands_differ(rec),
                        InputKind::Motors,
                        "not tried: the motor commands never differ",
                    )
                },
                physics,
            )
        },
    );
    let throttle = throttle?;
    // The split every family is judged on: the identification fit's held-out rows, which the
    // physics fit held out too (one split, `magstand_core::held_out`, same blocks).
    let mask = &throttle.held.mask;
    // The throttle family's data hold the recording's times and their split, made once.
    let blocks = throttle.data.time_blocks();
    let physics_residuals = physics.as_ref().map_err(Clone::clone).and_then(|p| {
        let reading = p
            .model
            .reading_column(rec, origin)
            .map_err(|e| e.to_string())?;
        Ok(rec
            .mag_ut
            .iter()
            .zip(&reading)
            .zip(mask)
            .filter(|(_, held)| **held)
            .map(|((m, r), _)| m - r)
            .collect::<Vec<Vec3>>())
    });
    let contenders = vec![
        local_contender(FamilyId::Throttle, Ok(&throttle)),
        local_contender(FamilyId::Current, current.as_ref()),
        local_contender(FamilyId::Motors, motors.as_ref()),
        Contender {
            family: FamilyId::Physics,
            parameters: physics.as_ref().map_or(0, |p| p.model.parameter_count()),
            residuals_ut: physics_residuals.map(Into::into),
        },
    ];
    let choice = choose(&contenders, mask, &blocks).ok_or_else(|| DiagnoseError::Recording {
        origin: origin.into(),
        message: "no model family could be judged on the held-out rows".into(),
    })?;
    let with_choice = |family: LocalFamily| -> Result<DisturbanceModel, DiagnoseError> {
        let mut m = family.cfg.fit_judged(&family.data, &family.held)?;
        m.choice = Some(choice.clone());
        Ok(DisturbanceModel::LocalLinear(Box::new(m)))
    };
    let chosen = match choice.chosen {
        FamilyId::Physics => {
            let mut m = physics
                .map_err(|message| DiagnoseError::Recording {
                    origin: origin.into(),
                    message,
                })?
                .model;
            m.choice = Some(choice.clone());
            DisturbanceModel::Physics(Box::new(m))
        }
        FamilyId::Current => with_choice(current.map_err(unreachable_err(origin))?)?,
        FamilyId::Motors => with_choice(motors.map_err(unreachable_err(origin))?)?,
        _ => with_choice(throttle)?,
    };
    Ok((chosen, choice))
}

/// A local linear family as the choice judges it: its training fit's held-out residuals,
/// borrowed.
fn local_contender<'a>(
    family: FamilyId,
    fit: Result<&'a LocalFamily<'_>, &String>,
) -> Contender<'a> {
    Contender {
        family,
        parameters: fit.map_or(0, |f| f.held.parameters),
        residuals_ut: fit
            .map(|f| f.held.residuals_ut.as_slice().into())
            .map_err(Clone::clone),
    }
}

/// A local linear family's training fit, with what its fit on every row needs.
struct LocalFamily<'d> {
    cfg: ValidFitConfig,
    data: Cow<'d, Dataset>,
    held: magstand_ident::HeldOut,
}

/// A chosen family's fit failing: cannot happen (only scored families are chosen), but is an
/// error rather than a panic.
fn unreachable_err(origin: &str) -> impl Fn(String) -> DiagnoseError + '_ {
    move |message| DiagnoseError::Recording {
        origin: origin.into(),
        message,
    }
}

impl DisturbanceModel {
    /// Reads a model file of either format (`magstand-model` or `magstand-augmented-model`),
    /// by the `format` it declares.
    pub fn load(path: &std::path::Path) -> Result<Self, DiagnoseError> {
        let text =
            magstand_core::input_file::read_document(path).map_err(|source| DiagnoseError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let origin = path.display().to_string();
        // Parsed once: the declared format picks the reader of the same document.
        let value: serde_json::Value = match serde_json::from_str(&text) {
            Ok(v) => v,
            // Not JSON: the model reader's error says so, naming the file.
            Err(_) => {
                return Ok(DisturbanceModel::LocalLinear(Box::new(Model::from_json(
                    &text, &origin,
                )?)));
            }
        };
        if value.get("format").and_then(|f| f.as_str()) == Some(crate::augmented_model::FORMAT) {
            return Ok(DisturbanceModel::Physics(Box::new(
                AugmentedModel::from_value(value, path)?,
            )));
        }
        Ok(DisturbanceModel::LocalLinear(Box::new(Model::from_value(
            value, &origin,
        )?)))
    }

    /// The motors-off field the model fitted, µT.
    pub fn reference_ut(&self) -> Vec3 {
        match self {
            DisturbanceModel::LocalLinear(m) => Vec3::from(m.reference_ut),
            DisturbanceModel::Physics(m) => m.reference_ut(),
        }
    }

    /// The family id.
    pub fn family(&self) -> &str {
        match self {
            DisturbanceModel::LocalLinear(m) => m
                .choice
                .as_ref()
                .map_or(m.method.as_str(), |c| c.chosen.id()),
            DisturbanceModel::Physics(_) => PHYSICS,
        }
    }

    /// Predicted disturbance at every row of `rec` (named `origin` in errors), µT.
    pub fn dist_column(&self, rec: &Recording, origin: &str) -> Result<Vec<Vec3>, DiagnoseError> {
        match self {
            DisturbanceModel::LocalLinear(m) => {
                rec.check()?;
                Ok(m.dist_column(rec))
            }
            DisturbanceModel::Physics(m) => m.dist_column(rec, origin),
        }
    }

    /// The recording with the predicted disturbance removed and `dist_*_ut` (and `sd_*_ut`
    /// where the model has a noise law) added.
    pub fn compensate(&self, rec: &Recording, origin: &str) -> Result<Recording, DiagnoseError> {
        match self {
            DisturbanceModel::LocalLinear(m) => Ok(m.compensate(rec, origin)?),
            DisturbanceModel::Physics(m) => m.compensate(rec, origin),
        }
    }

    /// Writes the model file, atomically.
    pub fn save(&self, path: &std::path::Path) -> Result<(), DiagnoseError> {
        match self {
            DisturbanceModel::LocalLinear(m) => Ok(m.save(path)?),
            DisturbanceModel::Physics(m) => m.save(path),
        }
    }
}
