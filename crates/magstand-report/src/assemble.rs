//! Puts the figures of a recording, a model and a Monte Carlo study together into one page.
use magstand_core::{Recording, Vec3};
use magstand_ident::Model;
use magstand_ident::methods;
use magstand_ident::metrics::Evaluation;
use magstand_study::{FigureId, MethodOutcome, Summary};

use crate::page::{Report, Section};
use crate::{ReportError, figures, montecarlo};

/// What a report shows.
pub struct ReportInputs<'a> {
    /// The recording (a validation run, ideally: not the one the model was fitted on).
    pub recording: &'a Recording,
    /// A short name for it (its path).
    pub recording_name: String,
    /// The model to judge, if any.
    pub model: Option<&'a Model>,
    /// A physics model (`magstand fit --method physics`) to judge, if any.
    pub physics: Option<&'a magstand_diagnose::AugmentedModel>,
    /// A mismatch diagnosis of the recording, if any.
    pub diagnosis: Option<&'a magstand_diagnose::Diagnosis>,
    /// A Monte Carlo study's summary and rows, if any.
    pub study: Option<(&'a Summary, &'a [MethodOutcome])>,
    /// What was run, shown in the header.
    pub provenance: Vec<(String, String)>,
}

fn f3(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3}")
    } else {
        "-".into()
    }
}

/// Builds the report.
pub fn build(inputs: &ReportInputs) -> Result<Report, ReportError> {
    let rec = inputs.recording;
    let mut report = Report {
        title: format!("magstand report: {}", inputs.recording_name),
        provenance: inputs.provenance.clone(),
        sections: Vec::new(),
    };

    let mut s = Section::new("The recording");
    let duration = rec.t_s.last().copied().unwrap_or(0.0) - rec.t_s.first().copied().unwrap_or(0.0);
    s.text.push(format!(
        "{} samples over {:.1} s, {} motor command column(s){}{}.",
        rec.len(),
        duration,
        rec.thr.len(),
        if rec.bat_a.is_some() {
            ", supply current"
        } else {
            ""
        },
        if rec.truth.is_some() {
            ", simulator ground truth"
        } else {
            ""
        },
    ));
    s.figure(
        "throttle-vs-time",
        "Motor commands against time.",
        figures::throttle_against_time(rec)?,
    );
    s.figure(
        "field-vs-time",
        "The three magnetometer axes against time.",
        figures::field_against_time(rec)?,
    );
    match figures::deviation_against_throttle(rec) {
        Ok(svg) => s.figure(
            "deviation-vs-throttle",
            "Deviation of each axis from the motors-off reading against overall throttle (the paper's Fig. 2 and 3).",
            svg,
        ),
        Err(e) => s.text.push(format!("No deviation figure: {e}.")),
    }
    report.sections.push(s);

    if let Some(model) = inputs.model {
        let mut s = Section::new("The model");
        s.text.push(format!(
            "Method `{}`, input `{:?}`; {}.",
            model.method,
            model.input.kind,
            match &model.structure {
                magstand_ident::Structure::LocalLinear(n) => format!(
                    "{} local linear models blended by normalized Gaussian RBFs",
                    n.partition.len()
                ),
                magstand_ident::Structure::Polynomial { .. } => "a polynomial".into(),
            }
        ));
        if let Some(sum) = &model.summary {
            s.tables.push((
                ["axis", "RMSE (µT)", "R²", "held-out RMSE (µT)"]
                    .map(String::from)
                    .to_vec(),
                (0..3)
                    .map(|a| {
                        vec![
                            magstand_core::AXES[a].to_string(),
                            f3(sum.rmse_ut[a]),
                            f3(sum.r2[a]),
                            f3(sum.holdout_rmse_ut[a]),
                        ]
                    })
                    .collect(),
            ));
        }
        if let Some(c) = &model.choice {
            push_choice(&mut s, c);
        }
        if let Some(svg) = figures::rbf_weights(model)? {
            s.figure(
                "rbf-weights",
                "Normalized RBF weights of the local models (the paper's Fig. 6).",
                svg,
            );
        }
        for (svg, axis) in figures::model_over_data(model, rec)?
            .into_iter()
            .zip(magstand_core::AXES)
        {
            s.figure(
                &format!("model-{axis}"),
                &format!("{axis} axis: the model with a band of two predicted standard deviations over this recording's samples (the paper's Fig. 7)."),
                svg,
            );
        }
        if let Some(svg) = figures::noise_sd(model)? {
            s.figure(
                "noise-sd",
                "The noise standard deviation the model predicts against its input.",
                svg,
            );
        }
        report.sections.push(s);

        report.sections.push(compensation_section(
            inputs,
            &model.method,
            Evaluation::new(model, rec),
        )?);
    }

    if let Some(physics) = inputs.physics {
        let mut s = Section::new("The model");
        let effects: Vec<&str> = physics.effects.iter().map(|e| e.name.as_str()).collect();
        s.text.push(format!(
            "The stand's physics, calibrated: the recording's commands replayed through the nominal stand{}, with {} fitted numbers (wiring gains on the motor currents, a cubic in rotor speed for the current law, the motors-off field and the command timing).",
            if effects.is_empty() {
                String::new()
            } else {
                format!(" with {}", effects.join(", "))
            },
            physics.parameter_count()
        ));
        if let Some(c) = &physics.choice {
            push_choice(&mut s, c);
        }
        report.sections.push(s);
        let dist = physics.dist_column(rec, &inputs.recording_name)?;
        let ev = Evaluation::from_prediction_at(physics.reference_ut(), rec, &dist);
        report
            .sections
            .push(compensation_section(inputs, "physics", ev)?);
    }

    if let Some(d) = inputs.diagnosis {
        report.sections.push(crate::diagnosis::section(d)?);
    }

    if let Some((summary, outcomes)) = inputs.study {
        let mut s = Section::new("Monte Carlo study");
        s.text.push(format!(
            "{} runs of {} (seed {}); every figure is measured on a validation series against the simulator's truth.",
            summary.study.runs, summary.study.scenario, summary.study.seed
        ));
        s.tables.push((
            [
                "method",
                "RMSE median (µT)",
                "RMSE 5-95 % (µT)",
                "heading after, median (°)",
                "crlb_ratio",
                "failed",
            ]
            .map(String::from)
            .to_vec(),
            summary
                .methods
                .iter()
                .map(|m| {
                    let r = m.figure(FigureId::RmseUt);
                    vec![
                        m.label.clone(),
                        r.map(|r| f3(r.p50)).unwrap_or_else(|| "-".into()),
                        r.map(|r| format!("{} - {}", f3(r.p5), f3(r.p95)))
                            .unwrap_or_else(|| "-".into()),
                        m.figure(FigureId::HeadingAfterDeg)
                            .map(|h| f3(h.p50))
                            .unwrap_or_else(|| "-".into()),
                        m.crlb_ratio.map(f3).unwrap_or_else(|| "-".into()),
                        m.failures.to_string(),
                    ]
                })
                .collect(),
        ));
        s.figure(
            "mc-error-vs-throttle",
            "Disturbance error against throttle over the runs: median with the 5-95 % band.",
            montecarlo::error_against_throttle(summary)?,
        );
        for m in summary.methods.iter().filter(|m| !m.parameters.is_empty()) {
            s.figure(
                &format!("mc-parameter-errors-{}", m.method),
                &format!(
                    "{}: parameter errors over the runs with the Cramer-Rao bound's normal curve.",
                    m.label
                ),
                montecarlo::parameter_errors(summary, outcomes, &m.method)?,
            );
        }
        report.sections.push(s);
    }
    Ok(report)
}

/// The compensation by `label`'s model (judged as `this`) beside the autopilots' lines
/// fitted on the same recording.
fn compensation_section(
    inputs: &ReportInputs,
    label: &str,
    this: Evaluation,
) -> Result<Section, ReportError> {
    let rec = inputs.recording;
    let mut s = Section::new("Compensation");
    let mut evals = vec![(format!("this model ({label})"), this)];
    // The autopilots' lines, fitted on this same recording: what a user of either gets today.
    for id in ["px4", "ardupilot"] {
        let m = methods::by_id(id).expect("catalog ids");
        match m
            .config
            .clone()
            .check()
            .and_then(|c| c.fit_recording(rec, &inputs.recording_name))
        {
            Ok(line) => evals.push((
                format!("{} (fitted here)", m.label),
                Evaluation::new(&line, rec),
            )),
            Err(e) => s.text.push(format!(
                "{} could not be fitted on this recording: {e}",
                m.label
            )),
        }
    }
    s.figure(
            "e20-vs-throttle",
            "Mean error per throttle level after compensation, in % of the field norm (eq. 20, the paper's Fig. 8).",
            figures::e20_against_throttle(&evals[0].0, &evals[0].1)?,
        );
    s.figure(
            "heading-vs-throttle",
            "Apparent heading error of each level's mean field, before and after compensation, beside the straight-line fits the autopilots use.",
            figures::heading_against_throttle(&evals)?,
        );
    let mut head = [
        "method",
        "worst heading error (°)",
        "interference (% of field)",
        "eq. 20 RMS (%)",
    ]
    .map(String::from)
    .to_vec();
    if rec.truth.is_some() {
        head.push("RMSE against true disturbance (µT)".into());
    }
    let mut rows = vec![{
        let e = &evals[0].1;
        let mut r = vec![
            "no compensation".to_string(),
            f3(e.heading_before_max_deg),
            f3(e.interference_before_pct),
            "-".into(),
        ];
        if let Some(d) = e.truth_rms_dist_ut {
            r.push(f3(Vec3::from(d).norm()));
        }
        r
    }];
    for (label, e) in &evals {
        let mut r = vec![
            label.clone(),
            f3(e.heading_after_max_deg),
            f3(e.interference_after_pct),
            f3(Vec3::from(e.e20_rms_pct).norm()),
        ];
        if let Some(t) = e.truth_rmse_ut {
            r.push(f3(Vec3::from(t).norm()));
        }
        rows.push(r);
    }
    s.tables.push((head, rows));
    Ok(s)
}

/// The table of an automatic choice among model families, and why the kept one won.
fn push_choice(s: &mut Section, c: &magstand_ident::family_choice::FamilyChoice) {
    s.text.push(format!(
        "The family was chosen by `magstand fit`: every family that applies was fitted without the held-out time blocks and judged on {} held-out rows in {} blocks. Rule: {}. Kept: {}: {}.",
        c.holdout_rows, c.holdout_blocks, c.rule, c.chosen, c.reason
    ));
    s.tables.push((
        [
            "family",
            "parameters",
            "held-out RMSE x / y / z (µT)",
            "excess over the lowest (µT²)",
        ]
        .map(String::from)
        .to_vec(),
        c.families
            .iter()
            .map(|f| match (f.holdout_rmse_ut, f.parameters) {
                (Some(r), Some(p)) => vec![
                    if f.family == c.chosen {
                        format!("{} (kept)", f.family)
                    } else {
                        f.family.to_string()
                    },
                    p.to_string(),
                    format!("{} / {} / {}", f3(r[0]), f3(r[1]), f3(r[2])),
                    format!(
                        "{:.2e} ± {:.1e}",
                        f.excess_ut2.unwrap_or(0.0),
                        f.excess_se_ut2.unwrap_or(0.0)
                    ),
                ],
                _ => vec![
                    f.family.to_string(),
                    "-".into(),
                    f.note.clone().unwrap_or_else(|| "not scored".into()),
                    "-".into(),
                ],
            })
            .collect(),
    ));
}
