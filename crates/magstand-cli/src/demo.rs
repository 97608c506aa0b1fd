//! `magstand demo`: the embedded paper-like scenario end to end. Simulate an identification
//! stair and a separate validation stair (going down, another seed), fit the autopilots'
//! lines, the paper's model and magstand's, compensate the validation run, and print the
//! before/after table.
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::fit_cmd::print_summary;
use crate::progress::SimulationBar;
use crate::simulate_cmd::load_scenario;
use magstand_core::{Vec3, recording_csv};
use magstand_ident::metrics::Evaluation;

/// Arguments of `magstand demo`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct DemoArgs {
    /// Folder for the demo's files.
    #[arg(long, default_value = "magstand-demo")]
    out: PathBuf,
    /// Random seed of the identification run (validation uses seed + 1).
    #[arg(long, default_value_t = 3)]
    seed: u64,
}

/// Runs the demo.
pub fn run(a: DemoArgs) -> Result<()> {
    crate::files::ensure_dir(&a.out)?;
    let ident_s = load_scenario("builtin:czyba2015-stair", &[])?;
    let valid_s = load_scenario(
        "builtin:czyba2015-stair",
        &["program.direction=\"down\"".into()],
    )?;
    let ident = magstand_sim::simulate_observed(
        &ident_s,
        a.seed,
        &mut SimulationBar::new("identification run"),
    );
    let valid = magstand_sim::simulate_observed(
        &valid_s,
        a.seed + 1,
        &mut SimulationBar::new("validation run"),
    );
    let ident_path = a.out.join("identification.csv");
    let valid_path = a.out.join("validation.csv");
    recording_csv::write(&ident, &ident_path)?;
    recording_csv::write(&valid, &valid_path)?;
    println!(
        "Simulated {}: identification stair up ({} samples), validation stair down ({} samples)\n",
        ident_s.params().name,
        ident.len(),
        valid.len()
    );

    // The library pipeline (the `identify_and_compensate` example runs the same).
    let valid_name = valid_path.display().to_string();
    let comparison = magstand_study::comparison::identify_and_compensate(
        &magstand_ident::methods::catalog(),
        &ident,
        &ident_path.display().to_string(),
        &valid,
        &valid_name,
    )?;
    let truth_rmse = |ev: &Evaluation| ev.truth_rmse_ut.map_or(f64::NAN, |e| Vec3::from(e).norm());
    let table: Vec<_> = comparison
        .judged
        .iter()
        .map(|j| (j.label.clone(), truth_rmse(&j.evaluation), &j.evaluation))
        .collect();
    let model = &comparison.chosen;
    crate::fit_cmd::print_choice(&comparison.choice);
    if let magstand_diagnose::model_choice::DisturbanceModel::LocalLinear(m) = model {
        print_summary(m);
    }
    let model_path = a.out.join("model.json");
    model.save(&model_path)?;
    let comp_path = a.out.join("validation-compensated.csv");
    recording_csv::write(&model.compensate(&valid, &valid_name)?, &comp_path)?;

    let none = table[0]
        .2
        .truth_rms_dist_ut
        .map(|d| Vec3::from(d).norm())
        .unwrap_or(f64::NAN);
    println!("\nOn the validation run (ground truth known):");
    // As wide as the longest method's name, so the numbers stay in their columns.
    let w = table
        .iter()
        .map(|(name, ..)| name.chars().count())
        .fold("no compensation".len(), usize::max);
    println!(
        "{:<w$} {:>14} {:>16} {:>12}",
        "method", "dist_rmse_ut", "worst_heading_deg", "eq20_rms_%"
    );
    println!(
        "{:<w$} {:>14.3} {:>16.2} {:>12}",
        "no compensation", none, table[0].2.heading_before_max_deg, ""
    );
    for (name, rmse, ev) in &table {
        let e20 = Vec3::from(ev.e20_rms_pct).norm();
        println!(
            "{name:<w$} {rmse:>14.3} {:>16.2} {e20:>12.3}",
            ev.heading_after_max_deg
        );
    }
    println!(
        "\nwrote {}, {}, {} and {}",
        ident_path.display(),
        valid_path.display(),
        model_path.display(),
        comp_path.display()
    );
    let mut prov = crate::report_cmd::provenance();
    prov.extend([
        ("scenario".to_string(), ident_s.origin().to_string()),
        (
            "identification".to_string(),
            format!("stair up, seed {} ({})", a.seed, ident_path.display()),
        ),
        (
            "validation".to_string(),
            format!("stair down, seed {} ({})", a.seed + 1, valid_path.display()),
        ),
        (
            "model".to_string(),
            format!("{} ({})", model_path.display(), model.family()),
        ),
    ]);
    // The validation run against its own nominal physics: nothing should be left out.
    let diagnosis = magstand_diagnose::diagnose(
        &valid,
        &valid_path.display().to_string(),
        &valid_s,
        &magstand_diagnose::DiagnoseConfig::default().check()?,
    )?;
    println!(
        "diagnosis of the validation run against its scenario: {}",
        if diagnosis.verdict.is_empty() {
            "no significant mismatch".to_string()
        } else {
            diagnosis.verdict.join(", ")
        }
    );
    let page = crate::report_cmd::write_report(
        &[],
        &valid,
        &valid_path.display().to_string(),
        Some(model),
        Some(&diagnosis),
        None,
        prov,
        &a.out.join("report"),
    )?;
    println!("report: {}", page.display());
    Ok(())
}
