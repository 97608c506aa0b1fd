//! The paper's figures for a recording and a model: the recording against time, deviation
//! against throttle (Fig. 2/3), the RBF weights (Fig. 6), the model over the data with a band of
//! two predicted sd (Fig. 7), the noise sd, the eq. 20 error (Fig. 8) and the heading error
//! before and after compensation.
use magstand_core::{AXES, Recording, Vec3};
use magstand_ident::metrics::Evaluation;
use magstand_ident::{InputKind, Model, Structure, motors_off_rows};

use crate::ReportError;
use crate::chart::{Series, XyChart};

/// At most this many points per series, so a long recording still gives a light figure.
pub const MAX_POINTS: usize = 1200;

fn stride(n: usize) -> usize {
    n.div_ceil(MAX_POINTS).max(1)
}

/// The motors-off mean field (eq. 9 reference), or `None` without motors-off rows.
fn motors_off_reference(rec: &Recording) -> Option<Vec3> {
    magstand_ident::motors_off_reference(rec, &motors_off_rows(rec))
}

/// Motor commands against time.
pub fn throttle_against_time(rec: &Recording) -> Result<String, ReportError> {
    let s = stride(rec.len());
    let mut chart = XyChart::new(
        "throttle-vs-time",
        "Motor commands",
        "time (s)",
        "command (0..1)",
    );
    let names: Vec<String> = if rec.overall_only {
        vec!["thr".into()]
    } else {
        (1..=rec.thr.len()).map(|m| format!("thr_{m}")).collect()
    };
    for (m, name) in names.iter().enumerate() {
        let pts = (0..rec.len())
            .step_by(s)
            .map(|r| (rec.t_s[r], rec.thr[m][r]))
            .collect();
        chart = chart.with(Series::line(name.clone(), pts, m));
    }
    chart.to_svg()
}

/// The three magnetometer axes against time.
pub fn field_against_time(rec: &Recording) -> Result<String, ReportError> {
    let s = stride(rec.len());
    let mut chart = XyChart::new("field-vs-time", "Magnetometer", "time (s)", "field (µT)");
    for (a, axis) in AXES.iter().enumerate() {
        let pts = (0..rec.len())
            .step_by(s)
            .map(|r| (rec.t_s[r], rec.mag_ut[r][a]))
            .collect();
        chart = chart.with(Series::dots(format!("mag_{axis}_ut"), pts, a));
    }
    chart.to_svg()
}

/// Deviation from the motors-off reading against overall throttle per axis (the paper's Fig.
/// 2/3): samples as dots, level means as lines.
pub fn deviation_against_throttle(rec: &Recording) -> Result<String, ReportError> {
    let reference = motors_off_reference(rec).ok_or_else(|| ReportError::Empty {
        figure: "deviation-vs-throttle".into(),
        message: "the recording has no motors-off rows to take the eq. 9 reference from".into(),
    })?;
    let s = stride(rec.len());
    let mut chart = XyChart::new(
        "deviation-vs-throttle",
        "Deviation from the motors-off reading (eq. 9)",
        "overall throttle (0..1)",
        "m - m(motors off) (µT)",
    );
    for (a, axis) in AXES.iter().enumerate() {
        let pts = (0..rec.len())
            .step_by(s)
            .map(|r| (rec.overall_throttle(r), rec.mag_ut[r][a] - reference[a]))
            .collect();
        chart = chart.with(Series::dots(format!("{axis} axis"), pts, a));
    }
    chart.to_svg()
}

/// The model's input at a row, in raw units (throttle 0..1 or amperes), for x axes.
fn raw_input(model: &Model, rec: &Recording, row: usize) -> f64 {
    model.input.raw(rec, row)
}

fn input_label(model: &Model) -> &'static str {
    match model.input.kind {
        InputKind::Current => "supply current (A)",
        _ => "overall throttle (0..1)",
    }
}

/// The model's disturbance and sd along its input (equal commands for per-motor models).
fn curve(model: &Model, points: usize) -> Vec<(f64, Vec3, Vec3)> {
    let spec = &model.input;
    let mut s = model.scratch();
    (0..=points)
        .map(|i| {
            let raw = spec.lo + (spec.hi - spec.lo) * i as f64 / points as f64;
            let d = model.dist_at_input(raw, &mut s);
            let sd = model
                .sd
                .as_ref()
                .map(|m| m.sd(spec.normalize(raw)))
                .unwrap_or_else(Vec3::zeros);
            (raw, d, sd)
        })
        .collect()
}

/// Normalized RBF weights against the input (the paper's Fig. 6).
pub fn rbf_weights(model: &Model) -> Result<Option<String>, ReportError> {
    let Structure::LocalLinear(net) = &model.structure else {
        return Ok(None);
    };
    let spec = &model.input;
    let mut chart = XyChart::new(
        "rbf-weights",
        &format!(
            "Normalized RBF weights of the {} local models",
            net.partition.len()
        ),
        input_label(model),
        "weight phi_i",
    );
    let grid: Vec<f64> = (0..=200).map(|i| i as f64 / 200.0).collect();
    for i in 0..net.partition.len() {
        let pts = grid
            .iter()
            .map(|&u| (spec.denormalize(u), net.partition.weights(u)[i]))
            .collect();
        chart = chart.with(Series::line(
            format!("model {} (centre {:.2})", i + 1, net.partition.centers()[i]),
            pts,
            i,
        ));
    }
    chart.to_svg().map(Some)
}

/// Model curve with a band of two predicted sd over the data, one chart per axis (Fig. 7).
pub fn model_over_data(model: &Model, rec: &Recording) -> Result<Vec<String>, ReportError> {
    let reference = motors_off_reference(rec).unwrap_or(Vec3::from(model.reference_ut));
    let c = curve(model, 200);
    let s = stride(rec.len());
    AXES.iter()
        .enumerate()
        .map(|(a, axis)| {
            let data = (0..rec.len())
                .step_by(s)
                .map(|r| (raw_input(model, rec, r), rec.mag_ut[r][a] - reference[a]))
                .collect();
            let line = c.iter().map(|(x, d, _)| (*x, d[a])).collect();
            let band = c
                .iter()
                .map(|(x, d, sd)| (*x, d[a] - 2.0 * sd[a], d[a] + 2.0 * sd[a]))
                .collect();
            XyChart::new(
                &format!("model-{axis}"),
                &format!("{axis} axis: model (±2 predicted sd) over the data"),
                input_label(model),
                &format!("deviation on {axis} (µT)"),
            )
            .with(Series::dots("data", data, 5))
            .with(Series::line(format!("model ({})", model.method), line, 3).with_band(band))
            .to_svg()
        })
        .collect()
}

/// The noise sd model against the input.
pub fn noise_sd(model: &Model) -> Result<Option<String>, ReportError> {
    if model.sd.is_none() {
        return Ok(None);
    }
    let c = curve(model, 100);
    let mut chart = XyChart::new(
        "noise-sd",
        "Noise standard deviation (grows with load: eta in eq. 8)",
        input_label(model),
        "sd (µT)",
    );
    for (a, axis) in AXES.iter().enumerate() {
        chart = chart.with(Series::line(
            format!("{axis} axis"),
            c.iter().map(|(x, _, sd)| (*x, sd[a])).collect(),
            a,
        ));
    }
    chart.to_svg().map(Some)
}

/// Eq. 20 error per axis against throttle level after compensation (the paper's Fig. 8).
pub fn e20_against_throttle(label: &str, ev: &Evaluation) -> Result<String, ReportError> {
    let mut chart = XyChart::new(
        "e20-vs-throttle",
        &format!("Error after compensation, % of the field norm (eq. 20): {label}"),
        "overall throttle (0..1)",
        "mean error (% of |m|)",
    );
    for (a, axis) in AXES.iter().enumerate() {
        chart = chart.with(Series::line(
            format!("{axis} axis"),
            ev.levels
                .iter()
                .map(|l| (l.throttle, l.e20_pct[a]))
                .collect(),
            a,
        ));
    }
    chart.to_svg()
}

/// Apparent heading error before and after compensation against throttle, one line per
/// method.
pub fn heading_against_throttle(evals: &[(String, Evaluation)]) -> Result<String, ReportError> {
    let Some((_, first)) = evals.first() else {
        return Err(ReportError::Empty {
            figure: "heading-vs-throttle".into(),
            message: "no methods".into(),
        });
    };
    let mut chart = XyChart::new(
        "heading-vs-throttle",
        "Apparent heading error of each level's mean field",
        "overall throttle (0..1)",
        "|heading error| (degrees)",
    )
    .with(
        Series::line(
            "no compensation",
            first
                .levels
                .iter()
                .map(|l| (l.throttle, l.heading_before_deg))
                .collect(),
            7,
        )
        .dashed(),
    );
    for (i, (label, ev)) in evals.iter().enumerate() {
        chart = chart.with(Series::line(
            label.clone(),
            ev.levels
                .iter()
                .map(|l| (l.throttle, l.heading_after_deg))
                .collect(),
            i,
        ));
    }
    chart.to_svg()
}
