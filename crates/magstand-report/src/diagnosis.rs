//! The diagnosis section: residuals before and after each accepted effect, against time and
//! throttle, where the mismatch was located, and the named effects with their parameters.
use magstand_diagnose::Diagnosis;

use crate::ReportError;
use crate::chart::{Series, XyChart};
use crate::page::Section;

const AXES: [&str; 3] = ["x", "y", "z"];

/// One figure per axis of the held-out residual of every stage against `x`.
fn residual_charts(
    d: &Diagnosis,
    name: &str,
    what: &str,
    x_label: &str,
    x: &[f64],
) -> Result<Vec<(String, String)>, ReportError> {
    let mut out = Vec::new();
    for (a, axis) in AXES.iter().enumerate() {
        let mut chart = XyChart::new(
            &format!("{name}-{axis}"),
            &format!("Held-out residual, {axis} axis, against {what}"),
            x_label,
            "residual (µT)",
        );
        let last = d.series.stages.len().saturating_sub(1);
        for (k, stage) in d.series.stages.iter().enumerate() {
            // First and last stage only when there are many, to keep the plot readable.
            if k != 0 && k != last {
                continue;
            }
            chart = chart.with(Series::dots(
                stage.label.clone(),
                x.iter()
                    .zip(&stage.residual_ut)
                    .map(|(x, r)| (*x, r[a]))
                    .collect(),
                if k == 0 { 7 } else { 0 },
            ));
        }
        out.push((format!("{name}-{axis}"), chart.to_svg()?));
    }
    Ok(out)
}

fn f3(v: [f64; 3]) -> String {
    format!("{:.3} / {:.3} / {:.3}", v[0], v[1], v[2])
}

/// Each `name = value ± sd unit`, then what they rest on, each basis once with the names
/// resting on it (a per-motor term's gains share one), joined by `; `.
fn with_bases(params: &[&magstand_diagnose::Param]) -> String {
    params
        .iter()
        .map(|p| p.shown())
        .chain(magstand_diagnose::Param::bases_in_words(
            params.iter().copied(),
        ))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Builds the diagnosis section.
pub fn section(d: &Diagnosis) -> Result<Section, ReportError> {
    let mut s = Section::new("Mismatch diagnosis");
    s.text.push(if d.verdict.is_empty() {
        "Verdict: no significant mismatch. The held-out residuals of the calibrated nominal \
         simulation are white noise with the load-dependent variance."
            .into()
    } else {
        format!("Verdict: {}.", d.verdict.join(", "))
    });
    // What qualifies the verdict, as the command line prints it: the recording's doubts, a
    // flight's preparation, a supply nobody stated, structure too small to name.
    s.text
        .extend(d.warnings.iter().map(|w| format!("Warning: {w}")));
    s.text.push(format!(
        "Nominal physics: {}. Held-out RMSE x / y / z of its calibrated replay: {} µT; \
         simulation against recording after the accepted effects: {} µT.",
        d.scenario,
        f3(d.baseline.holdout_rmse_ut),
        f3(d.simulation.holdout_rmse_after_ut)
    ));
    if let Some(l) = &d.baseline.located {
        s.text.push(format!(
            "Where the baseline mismatch lives: axes {}, throttle {:.2}..{:.2}, time {:.0}..{:.0} s, \
             {} ramps, {}, motors: {}.",
            if l.axes.is_empty() { "-".into() } else { l.axes.join(", ") },
            l.throttle_range[0],
            l.throttle_range[1],
            l.time_span_s[0],
            l.time_span_s[1],
            l.direction,
            l.phase,
            l.motors
        ));
    }
    let constants: Vec<&magstand_diagnose::Param> = d.baseline.stand_constants().collect();
    if !constants.is_empty() {
        s.text.push(format!(
            "Stand constants the scenario does not state, calibrated from the recording: {}.",
            with_bases(&constants)
        ));
    }
    let rows: Vec<Vec<String>> = d
        .effects
        .iter()
        .map(|e| {
            vec![
                match &e.form {
                    Some(form) => format!("{} (form {form})", e.name),
                    None => e.name.clone(),
                },
                e.explanation.clone(),
                with_bases(&e.params.iter().collect::<Vec<_>>()),
                format!(
                    "throttle {:.2}..{:.2}, {:.0}..{:.0} s, {} ramps, {}",
                    e.located.throttle_range[0],
                    e.located.throttle_range[1],
                    e.located.time_span_s[0],
                    e.located.time_span_s[1],
                    e.located.direction,
                    e.located.phase
                ),
                f3(e.holdout_rmse_before_ut),
                f3(e.holdout_rmse_after_ut),
                format!("{:.1e}", e.p_value),
            ]
        })
        .collect();
    if !rows.is_empty() {
        s.tables.push((
            [
                "effect",
                "physics",
                "parameters",
                "located",
                "held-out RMSE before (µT)",
                "after (µT)",
                "p",
            ]
            .iter()
            .map(|h| h.to_string())
            .collect(),
            rows,
        ));
    }
    for (name, svg) in residual_charts(
        d,
        "diagnosis-residual-time",
        "time",
        "time (s)",
        &d.series.t_s,
    )? {
        s.figure(&name, "Held-out residual against time: black: the calibrated nominal simulation; blue: after the accepted effects.", svg);
    }
    for (name, svg) in residual_charts(
        d,
        "diagnosis-residual-throttle",
        "throttle",
        "overall throttle (0..1)",
        &d.series.throttle,
    )? {
        s.figure(
            &name,
            "Held-out residual against throttle, before and after.",
            svg,
        );
    }
    Ok(s)
}
