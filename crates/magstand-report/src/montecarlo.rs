//! Figures of a Monte Carlo study: error against throttle with bands, and parameter-error
//! histograms with the Cramer-Rao bound's normal curve over them.
use magstand_study::run::BINS;
use magstand_study::{MethodOutcome, Summary};

use crate::ReportError;
use crate::chart::{HistogramPanel, Series, XyChart, histogram_grid};

/// Median RMSE of the disturbance against throttle per method, with the 5-95 % band over runs.
pub fn error_against_throttle(summary: &Summary) -> Result<String, ReportError> {
    let mut chart = XyChart::new(
        "error-vs-throttle",
        &format!(
            "Disturbance error after identification, {} runs of {} (median, 5-95 % band)",
            summary.study.runs, summary.study.scenario
        ),
        "overall throttle (bin centre, 0..1)",
        "RMSE of predicted vs true disturbance (µT)",
    );
    chart.size = (860, 480);
    for (i, m) in summary.methods.iter().enumerate() {
        let centre = |b: usize| (b as f64 + 0.5) / BINS as f64;
        let pts: Vec<(f64, f64)> = m
            .bins
            .iter()
            .enumerate()
            .filter_map(|(b, s)| Some((centre(b), s.as_ref()?.p50)))
            .collect();
        let band = m
            .bins
            .iter()
            .enumerate()
            .filter_map(|(b, s)| s.as_ref().map(|s| (centre(b), s.p5, s.p95)))
            .collect();
        chart = chart.with(Series::line(m.label.clone(), pts, i).with_band(band));
    }
    chart.to_svg()
}

/// Histograms of a fixed-structure method's parameter errors over runs, each with the normal
/// density N(0, CRLB) that an efficient unbiased estimator would follow.
pub fn parameter_errors(
    summary: &Summary,
    outcomes: &[MethodOutcome],
    method: &str,
) -> Result<String, ReportError> {
    let m = summary.method(method).ok_or_else(|| ReportError::Empty {
        figure: format!("parameter-errors-{method}"),
        message: format!("method `{method}` is not in the study"),
    })?;
    let errors: Vec<&[Vec<f64>; 3]> = outcomes
        .iter()
        .filter(|o| o.method == method)
        .filter_map(|o| o.figures.as_ref()?.param_error.as_ref())
        .collect();
    let panels: Vec<HistogramPanel> = m
        .parameters
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (a, k) = (
                i / magstand_study::crlb::PARAMS_PER_AXIS,
                i % magstand_study::crlb::PARAMS_PER_AXIS,
            );
            HistogramPanel {
                title: format!("{} (sd {:.3}, bound {:.3})", p.name, p.sd, p.crlb_sd),
                values: errors.iter().map(|e| e[a][k]).collect(),
                normal: Some((0.0, p.crlb_sd)),
            }
        })
        .collect();
    histogram_grid(
        &format!("parameter-errors-{method}"),
        &format!(
            "{}: parameter errors over {} runs, with the Cramer-Rao normal curve",
            m.label,
            errors.len()
        ),
        "error (µT per unit)",
        &panels,
        6,
    )
}
