//! The library pipeline of `magstand demo`, without the printing: simulate an identification
//! stair and a validation stair of the paper-like stand, fit the paper's model and the
//! automatic one, compensate the validation run and compare each with the simulator's truth.
//!
//! `cargo run --release -p magstand-cli --example identify_and_compensate`
use anyhow::{Context, Result};
use magstand_core::Vec3;
use magstand_ident::{FitConfig, metrics::Evaluation};
use magstand_sim::{Scenario, simulate};

fn run() -> Result<()> {
    // A shorter stair than the shipped one, so the example runs in seconds.
    let short = ["program.dwell_s=3.0".to_string()];
    let ident_s = Scenario::load_spec("builtin:czyba2015-stair", &short)?;
    let mut down = short.to_vec();
    down.push("program.direction=\"down\"".into());
    let valid_s = Scenario::load_spec("builtin:czyba2015-stair", &down)?;
    let ident = simulate(&ident_s, 1);
    let valid = simulate(&valid_s, 2);

    for (name, config) in [
        ("paper: 3 RBF, local", FitConfig::paper()),
        ("automatic structure", FitConfig::automatic()),
    ] {
        let model = config.check()?.fit_recording(&ident, "identification")?;
        let compensated = model.compensate(&valid, "validation")?;
        let truth = Evaluation::new(&model, &valid)
            .truth_rmse_ut
            .context("a simulated recording carries its truth")?;
        println!(
            "{name:22} disturbance error against the truth {:.3} µT; {} rows compensated",
            Vec3::from(truth).norm(),
            compensated.len()
        );
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
