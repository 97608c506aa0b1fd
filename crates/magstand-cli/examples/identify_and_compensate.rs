//! The library pipeline of `magstand demo`, without the printing and the files: simulate an
//! identification stair and a validation stair of the paper-like stand, fit the named methods
//! and the automatic choice among model families on the first, judge each on the second
//! against the simulator's truth, and compensate the validation run with the chosen model.
//! `magstand demo` calls the same [`identify_and_compensate`].
//!
//! `cargo run --release -p magstand-cli --example identify_and_compensate`
use anyhow::{Context, Result};
use magstand_core::Vec3;
use magstand_sim::{Scenario, simulate};
use magstand_study::comparison::identify_and_compensate;

fn run() -> Result<()> {
    // A shorter stair than the shipped one, so the example runs in seconds.
    let short = ["program.dwell_s=3.0".to_string()];
    let ident_s = Scenario::load_spec("builtin:czyba2015-stair", &short)?;
    let mut down = short.to_vec();
    down.push("program.direction=\"down\"".into());
    let valid_s = Scenario::load_spec("builtin:czyba2015-stair", &down)?;
    let ident = simulate(&ident_s, 1);
    let valid = simulate(&valid_s, 2);

    // The paper's model and magstand's automatic structure, then the automatic choice.
    let methods: Vec<_> = magstand_ident::methods::catalog()
        .into_iter()
        .filter(|m| ["paper-local", "automatic"].contains(&m.id))
        .collect();
    let comparison =
        identify_and_compensate(&methods, &ident, "identification", &valid, "validation")?;
    for j in &comparison.judged {
        let truth = j
            .evaluation
            .truth_rmse_ut
            .context("a simulated recording carries its truth")?;
        println!(
            "{:40} disturbance error against the truth {:.3} µT",
            j.label,
            Vec3::from(truth).norm()
        );
    }
    let compensated = comparison.chosen.compensate(&valid, "validation")?;
    println!(
        "{} rows compensated with the chosen family, {}: {}",
        compensated.len(),
        comparison.chosen.family(),
        comparison.choice.reason
    );
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
