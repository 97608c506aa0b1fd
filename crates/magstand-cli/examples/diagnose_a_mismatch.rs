//! Diagnose a recording against the stand as stated: the recording's stand heats its board
//! (a thermal offset drift), the stated one does not; the diagnosis names the missing physics
//! with its parameters and shows the held-out fit before and after.
//!
//! `cargo run --release -p magstand-cli --example diagnose_a_mismatch`
use anyhow::Result;
use magstand_diagnose::{DiagnoseConfig, diagnose};
use magstand_sim::{Scenario, simulate};

fn run() -> Result<()> {
    let real = Scenario::load_spec("builtin:thermal", &["program.repeats=2".into()])?;
    // The same stand as its user states it: no board heating.
    let stated = Scenario::load_spec(
        "builtin:thermal",
        &["program.repeats=2".into(), "thermal.enabled=false".into()],
    )?;
    let recording = simulate(&real, 7);
    let d = diagnose(
        &recording,
        "thermal run",
        &stated,
        &DiagnoseConfig::default().check()?,
    )?;
    print!("{}", d.summary());
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
