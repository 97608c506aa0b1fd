//! `magstand diagnose`: where a recording and the nominal simulation differ, what physics was
//! left out, and how much better the fit gets with it.
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;

use crate::files;
use crate::flag_terms::{DIAGNOSE_FLAGS, in_flag_terms};
use crate::simulate_cmd::load_scenario;
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::recording_csv;
use magstand_diagnose::{DiagnoseConfig, diagnose_observed, unstated_nominal};

/// Arguments of `magstand diagnose`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct DiagnoseArgs {
    /// Recording CSV.
    #[arg(long)]
    recording: PathBuf,
    /// Nominal scenario (a file, or builtin:NAME); its program is replaced by the recording's
    /// commands. Without it, the default nominal stand (simulator defaults, 12 V bench supply).
    #[arg(long)]
    scenario: Option<String>,
    /// Write the diagnosis as JSON (format magstand-diagnosis, version 1).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the augmented scenario: the nominal one with every accepted effect switched on.
    #[arg(long)]
    augmented: Option<PathBuf>,
    /// Write the augmented model (format magstand-augmented-model): the calibrated nominal
    /// physics with the accepted effects, usable by `magstand compensate --model`.
    #[arg(long = "model-out")]
    model_out: Option<PathBuf>,
    /// Write an HTML report with the residual figures into this folder.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Family-wise significance of each decision.
    #[arg(long, default_value_t = 0.01)]
    significance: f64,
    /// Length of the time blocks, s, every third of which is held out from the fits to judge
    /// them [default: 1/150 of the recording, kept within 0.5..10 s]. A short recording needs
    /// shorter blocks: at least five held out.
    #[arg(long = "block-s")]
    block_s: Option<f64>,
    /// Threads for the candidates (0: all cores; at most 1024).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=1024))]
    threads: u16,
}

/// Runs `magstand diagnose`.
pub fn run(a: DiagnoseArgs) -> Result<()> {
    let page = a.report.as_ref().map(|d| d.join("index.html"));
    let mut outputs: Vec<&std::path::Path> = Vec::new();
    outputs.extend(a.json.as_deref());
    outputs.extend(a.augmented.as_deref());
    outputs.extend(a.model_out.as_deref());
    outputs.extend(page.as_deref());
    // A message that names a setting names its flag; any other keeps its error (and causes).
    let in_flags = |e: magstand_diagnose::DiagnoseError| {
        let text = e.to_string();
        let flagged = in_flag_terms(&text, &DIAGNOSE_FLAGS);
        if flagged == text {
            anyhow::Error::new(e)
        } else {
            anyhow::anyhow!(flagged)
        }
    };
    let config = DiagnoseConfig {
        significance: a.significance,
        block_s: a.block_s,
        ..Default::default()
    }
    .check()
    .map_err(in_flags)?;
    let nominal = match &a.scenario {
        Some(s) => load_scenario(s, &[])?,
        None => unstated_nominal()?,
    };
    let mut inputs = vec![a.recording.clone()];
    if let Some(s) = &a.scenario {
        inputs.extend(files::scenario_inputs(s, &nominal));
    }
    files::refuse_overwriting_inputs(&inputs, &outputs)?;
    let rec = recording_csv::read(&a.recording)?;
    let name = a.recording.display().to_string();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(usize::from(a.threads))
        .build()
        .context("starting the worker threads")?;
    let mut d = {
        // Cleared from the terminal before the summary is printed.
        let spinner = crate::progress::DiagnosisSpinner::new(&name);
        pool.install(|| diagnose_observed(&rec, &name, &nominal, &config, &spinner))
            .map_err(in_flags)?
    };
    // The model file names the magnetometer the recording is of, for `export`.
    if a.model_out.is_some()
        && let Some(m) = d.model.as_mut()
    {
        m.magnetometer = MagnetometerSlot::of_recording(&rec, &a.recording)?;
        m.magnetometer_to_body = SensorToBody::of_recording(&rec, &a.recording)?;
    }
    // Every file first, then the terminal: a reader that closes stdout early must not cost
    // an output.
    let mut wrote = Vec::new();
    if let Some(p) = &a.json {
        files::ensure_parent(p)?;
        d.save(p)?;
        wrote.push(p.clone());
    }
    if let Some(p) = &a.augmented {
        files::ensure_parent(p)?;
        magstand_core::atomic_file::write_bytes(p, d.augmented_scenario.as_bytes())?;
        wrote.push(p.clone());
    }
    if let (Some(p), Some(m)) = (&a.model_out, &d.model) {
        files::ensure_parent(p)?;
        m.save(p)?;
        wrote.push(p.clone());
    }
    if let Some(dir) = &a.report {
        let mut prov = crate::report_cmd::provenance();
        prov.push(("recording".into(), name.clone()));
        prov.push(("nominal scenario".into(), nominal.origin().into()));
        let read: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
        wrote.push(crate::report_cmd::write_report(
            &read,
            &rec,
            &name,
            None,
            Some(&d),
            None,
            prov,
            dir,
        )?);
    }
    print!("{}", d.summary());
    for p in wrote {
        println!("wrote {}", p.display());
    }
    Ok(())
}
