//! `magstand compensate`.
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::files;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::{Recording, Vec3, recording_csv};
use magstand_diagnose::model_choice::DisturbanceModel;
use magstand_ident::metrics::{Evaluation, against_truth};
use magstand_ident::{Model, flight};

/// Arguments of `magstand compensate`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct CompensateArgs {
    /// Model file written by `magstand fit`, or an augmented model written by
    /// `magstand diagnose --model-out`.
    #[arg(long)]
    model: PathBuf,
    /// Recording to compensate.
    #[arg(long)]
    recording: PathBuf,
    /// Output CSV: the recording with mag_*_ut compensated, plus dist_*_ut and sd_*_ut.
    #[arg(long)]
    out: PathBuf,
    /// Update the local linear model's coefficients row by row while compensating (recursive
    /// least squares, forgetting weighted by each local model's membership), so that it
    /// follows a disturbance that drifts. Each row is compensated with the prediction made
    /// before it updates the model. On a restrained stand: the update takes each row's
    /// deviation from the model's motors-off field as the disturbance.
    #[arg(long)]
    adapt: bool,
    /// Forgetting factor of --adapt per row, 0.9 to 0.999999: the memory is about
    /// 1 / (1 - forgetting) rows.
    #[arg(long, default_value_t = 0.99, requires = "adapt")]
    forgetting: f64,
}

/// Prints the RMSE against ground truth of a simulated recording.
fn print_truth(rmse_ut: Option<[f64; 3]>) {
    if let Some(e) = rmse_ut {
        println!(
            "against ground truth: predicted-disturbance RMSE x {:.3} y {:.3} z {:.3} uT",
            e[0], e[1], e[2]
        );
    }
}

/// Compensates with an augmented model from `magstand diagnose`.
fn print_augmented(
    a: &CompensateArgs,
    model: &magstand_diagnose::AugmentedModel,
    rec: &Recording,
    dist: &[Vec3],
) {
    let effects: Vec<&str> = model.effects.iter().map(|e| e.name.as_str()).collect();
    println!(
        "compensated {} rows with the augmented physics (nominal stand{}) -> {}",
        rec.len(),
        if effects.is_empty() {
            String::new()
        } else {
            format!(" + {}", effects.join(" + "))
        },
        a.out.display()
    );
    print_truth(against_truth(rec, dist).map(|(e, _)| e));
}

/// Compensates with the recursive estimation (`--adapt`).
fn run_adaptive(a: &CompensateArgs, model: &Model, origin: &str) -> Result<()> {
    use magstand_ident::adaptive::{AdaptConfig, compensate_adaptive};
    let cfg = AdaptConfig {
        forgetting: a.forgetting,
    }
    .check()
    .map_err(|e| anyhow::anyhow!(crate::fit_cmd::in_flag_terms(&e.to_string())))?;
    let rec = files::read_recording(&a.recording)?;
    MagnetometerSlot::agreeing_with(model.magnetometer, &rec, &a.recording)?;
    let adapted = compensate_adaptive(model, &rec, origin, &cfg)?;
    files::ensure_parent(&a.out)?;
    recording_csv::write(&adapted.recording, &a.out)?;
    warn_beyond_identified(model, &rec, origin);
    println!(
        "compensated {} rows with the model's coefficients updated row by row (forgetting {}, memory about {:.0} rows) -> {}",
        rec.len(),
        a.forgetting,
        1.0 / (1.0 - a.forgetting),
        a.out.display()
    );
    if let Some((adapt, _)) = against_truth(&rec, &adapted.dist_ut) {
        let fixed = against_truth(&rec, &model.dist_column(&rec)).map(|(e, _)| e);
        println!(
            "against ground truth: predicted-disturbance RMSE x {:.3} y {:.3} z {:.3} uT (the fixed model: {})",
            adapt[0],
            adapt[1],
            adapt[2],
            fixed.map_or("-".into(), |e| format!(
                "x {:.3} y {:.3} z {:.3} uT",
                e[0], e[1], e[2]
            ))
        );
    }
    Ok(())
}

/// What a compensation removed from each row: its predicted disturbance.
fn removed(rec: &Recording, out: &Recording) -> Vec<Vec3> {
    rec.mag_ut
        .iter()
        .zip(&out.mag_ut)
        .map(|(m, c)| m - c)
        .collect()
}

/// How far beyond its identified range, as a fraction of the range, an input must lie to be
/// warned about: a flight fit identifies on delayed (interpolated) inputs, whose peaks are a
/// little lower than the recording's own.
const BEYOND_MARGIN: f64 = 0.05;

/// Warns when rows of `rec` lie beyond the input range the model was identified on: there it
/// continues linearly from its edge, which is safe but not identified.
fn warn_beyond_identified(model: &Model, rec: &Recording, origin: &str) {
    let Some(range) = &model.identified else {
        return;
    };
    let i = &model.input;
    let beyond = (0..rec.len())
        .filter(|&r| !range.contains(i.normalize(i.raw(rec, r)), BEYOND_MARGIN))
        .count();
    if beyond > 0 {
        eprintln!(
            "warning: {origin}: {beyond} of {} rows lie beyond the input range the model was identified on ({:.3}..{:.3}); there it continues linearly from its edge",
            rec.len(),
            i.denormalize(range.lo),
            i.denormalize(range.hi)
        );
    }
}

/// Runs `magstand compensate`.
pub fn run(a: CompensateArgs) -> Result<()> {
    files::refuse_overwriting_inputs(&[&a.model, &a.recording], &[&a.out])?;
    // The library reads either format by the one the file declares.
    let model = DisturbanceModel::load(&a.model)?;
    let origin = a.recording.display().to_string();
    if a.adapt {
        let DisturbanceModel::LocalLinear(m) = &model else {
            anyhow::bail!(
                "{}: --adapt updates a local linear model's coefficients; this is a physics (augmented) model",
                a.model.display()
            );
        };
        return run_adaptive(&a, m, &origin);
    }
    let rec = files::read_recording(&a.recording)?;
    let fitted_on = match &model {
        DisturbanceModel::LocalLinear(m) => m.magnetometer,
        DisturbanceModel::Physics(m) => m.magnetometer,
    };
    MagnetometerSlot::agreeing_with(fitted_on, &rec, &a.recording)?;
    let out = model.compensate(&rec, &origin)?;
    files::ensure_parent(&a.out)?;
    recording_csv::write(&out, &a.out)?;
    // The prediction is what the compensation removed: evaluated once, not again.
    let dist = removed(&rec, &out);
    let model = match &model {
        DisturbanceModel::Physics(m) => {
            print_augmented(&a, m, &rec, &dist);
            return Ok(());
        }
        DisturbanceModel::LocalLinear(m) => m,
    };
    warn_beyond_identified(model, &rec, &origin);
    if flight::is_flight(&rec) {
        // A turning vehicle: the stand's figures (heading at fixed attitude, interference
        // over levels) mean nothing; judge the field's magnitude and the heading instead.
        let f = flight::flight_figures(&rec, &out.mag_ut, None, &origin)?;
        println!(
            "compensated {} rows of a flight -> {}; field magnitude spread (sd) {:.2} -> {:.2} uT; heading error against the attitude-turned Earth field ({}, |e| {:.1} uT) RMS {:.1} -> {:.1} deg, worst {:.1} -> {:.1} deg",
            rec.len(),
            a.out.display(),
            f.norm_sd_ut.0,
            f.norm_sd_ut.1,
            f.earth_source,
            f.earth_ned_ut.norm(),
            f.heading_rms_deg.0,
            f.heading_rms_deg.1,
            f.heading_max_deg.0,
            f.heading_max_deg.1
        );
        print_truth(against_truth(&rec, &dist).map(|(e, _)| e));
        return Ok(());
    }
    let ev = Evaluation::from_prediction(model, &rec, &dist);
    println!(
        "compensated {} rows -> {}; heading error (worst level) {:.2} deg -> {:.2} deg; interference {:.1} % -> {:.1} %",
        rec.len(),
        a.out.display(),
        ev.heading_before_max_deg,
        ev.heading_after_max_deg,
        ev.interference_before_pct,
        ev.interference_after_pct
    );
    print_truth(ev.truth_rmse_ut);
    Ok(())
}
