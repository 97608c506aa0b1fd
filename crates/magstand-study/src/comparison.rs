//! One identification run and one validation run, every method compared: the pipeline of
//! `magstand demo` and of the `identify_and_compensate` example, without their printing and
//! files.
//!
//! Each named method ([`magstand_ident::methods::catalog`]) is fitted on the identification
//! recording and judged on the validation recording; then the automatic choice among model
//! families (`magstand fit` with no options) is made on the identification recording and
//! judged the same way. On simulated recordings the judgement includes the truth.
use magstand_core::Recording;
use magstand_diagnose::model_choice::{DisturbanceModel, choose_model};
use magstand_ident::family_choice::FamilyChoice;
use magstand_ident::methods::{Fitter, Method};
use magstand_ident::metrics::Evaluation;

use crate::StudyError;

/// One method judged on the validation recording.
#[derive(Debug, Clone)]
pub struct Judged {
    /// The method's label (for tables).
    pub label: String,
    /// Its figures on the validation recording.
    pub evaluation: Evaluation,
}

/// Every method compared, and the model the automatic choice kept.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The named methods in the order given, then the automatic choice.
    pub judged: Vec<Judged>,
    /// The model the automatic choice kept, fitted on the identification recording.
    pub chosen: DisturbanceModel,
    /// Why it was kept: every family's held-out error.
    pub choice: FamilyChoice,
}

/// Fits `methods` (those with a single configuration; the others are left out) and the
/// automatic choice on `ident`, and judges each on `valid`. The origins name the recordings
/// in errors.
pub fn identify_and_compensate(
    methods: &[Method],
    ident: &Recording,
    ident_origin: &str,
    valid: &Recording,
    valid_origin: &str,
) -> Result<Comparison, StudyError> {
    let mut judged = Vec::with_capacity(methods.len() + 1);
    for method in methods {
        let Fitter::Config(config) = &method.fitter else {
            continue;
        };
        let model = config.clone().check()?.fit_recording(ident, ident_origin)?;
        judged.push(Judged {
            label: method.label.to_string(),
            evaluation: Evaluation::new(&model, valid),
        });
    }
    // The user has stated nothing about the stand: the physics family calibrates it.
    let (chosen, choice) = choose_model(
        ident,
        ident_origin,
        &magstand_diagnose::unstated_nominal()?,
        None,
    )?;
    judged.push(Judged {
        label: format!("magstand fit default ({} chosen)", chosen.family()),
        evaluation: Evaluation::from_prediction_at(
            chosen.reference_ut(),
            valid,
            &chosen.dist_column(valid, valid_origin)?,
        ),
    });
    Ok(Comparison {
        judged,
        chosen,
        choice,
    })
}
