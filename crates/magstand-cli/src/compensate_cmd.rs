//! `magstand compensate`.
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::files;
use magstand_core::recording_csv;
use magstand_ident::Model;
use magstand_ident::metrics::Evaluation;

/// Arguments of `magstand compensate`.
#[derive(Args)]
pub struct CompensateArgs {
    /// Model file written by `magstand fit`.
    #[arg(long)]
    model: PathBuf,
    /// Recording to compensate.
    #[arg(long)]
    recording: PathBuf,
    /// Output CSV: the recording with mag_*_ut compensated, plus dist_*_ut and sd_*_ut.
    #[arg(long)]
    out: PathBuf,
}

/// Runs `magstand compensate`.
pub fn run(a: CompensateArgs) -> Result<()> {
    files::refuse_overwriting_inputs(&[&a.model, &a.recording], &[&a.out])?;
    let model = Model::load(&a.model)?;
    let rec = recording_csv::read(&a.recording)?;
    let out = model.compensate(&rec, &a.recording.display().to_string())?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        files::ensure_dir(dir)?;
    }
    recording_csv::write(&out, &a.out)?;
    let ev = Evaluation::new(&model, &rec);
    println!(
        "compensated {} rows -> {}; heading error (worst level) {:.2} deg -> {:.2} deg; interference {:.1} % -> {:.1} %",
        rec.len(),
        a.out.display(),
        ev.heading_before_max_deg,
        ev.heading_after_max_deg,
        ev.interference_before_pct,
        ev.interference_after_pct
    );
    if let Some(e) = ev.truth_rmse_ut {
        println!(
            "against ground truth: predicted-disturbance RMSE x {:.3} y {:.3} z {:.3} uT",
            e[0], e[1], e[2]
        );
    }
    Ok(())
}
