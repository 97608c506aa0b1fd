//! `magstand simulate`.
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::files;
use crate::progress::SimulationBar;
use magstand_core::{atomic_file, recording_csv};
use magstand_logs::log_writer::{LogWriteOptions, stage_dataflash, stage_ulog};
use magstand_sim::{Scenario, simulate_observed};

/// Arguments of `magstand simulate`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct SimulateArgs {
    /// Scenario file (TOML), or `builtin:NAME` for a shipped scenario.
    #[arg(long)]
    scenario: String,
    /// Output folder: receives recording.csv and scenario.toml (the resolved scenario).
    #[arg(long)]
    out: PathBuf,
    /// Random seed (default: the scenario's `seed`).
    #[arg(long)]
    seed: Option<u64>,
    /// Override a scenario value, e.g. `--set supply.capacity_ah=1.3` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    overrides: Vec<String>,
    /// Also write the run as a PX4 ULog (recording.ulg) and an ArduPilot DataFlash log
    /// (recording.bin), for `magstand import` and other log tools.
    #[arg(long)]
    logs: bool,
}

/// Loads a scenario from a path or `builtin:NAME`, with overrides, and checks it.
pub fn load_scenario(spec: &str, overrides: &[String]) -> Result<magstand_sim::ValidScenario> {
    Ok(Scenario::load_spec(spec, overrides)?)
}

/// Runs `magstand simulate`.
pub fn run(a: SimulateArgs) -> Result<()> {
    let created = !a.out.exists();
    let result = run_into(&a);
    // A failed run leaves no folder it created (only an empty one can be ours to remove).
    if result.is_err() && created {
        let _ = std::fs::remove_dir(&a.out);
    }
    result
}

fn run_into(a: &SimulateArgs) -> Result<()> {
    let scenario = load_scenario(&a.scenario, &a.overrides)?;
    let seed = a.seed.unwrap_or(scenario.params().seed);
    files::ensure_dir(&a.out)?;
    let rec_path = a.out.join("recording.csv");
    let scn_path = a.out.join("scenario.toml");
    let log_paths: Vec<(PathBuf, bool)> = if a.logs {
        vec![
            (a.out.join("recording.ulg"), true),
            (a.out.join("recording.bin"), false),
        ]
    } else {
        Vec::new()
    };
    let mut outputs = vec![rec_path.clone(), scn_path.clone()];
    outputs.extend(log_paths.iter().map(|(p, _)| p.clone()));
    files::refuse_overwriting_inputs(&files::scenario_inputs(&a.scenario, &scenario), &outputs)?;
    let rec = simulate_observed(&scenario, seed, &mut SimulationBar::new("simulate"));
    let resolved = format!(
        "# Resolved scenario written by magstand {} from {}; repeat with:\n#   magstand simulate --scenario {} --seed {seed} --out DIR\nseed = {seed}\n{}",
        env!("CARGO_PKG_VERSION"),
        scenario.origin(),
        scn_path.display(),
        strip_seed(&scenario.to_toml()),
    );
    // Every file is written in full before any is renamed into place, so a failure leaves
    // the folder as it was. The renames then go scenario.toml, the logs, recording.csv: a run
    // stopped between two renames never leaves a new recording beside an older scenario.
    let scenario_file = atomic_file::stage_bytes(&scn_path, resolved.as_bytes())?;
    let opts = LogWriteOptions {
        // A stand turned by the gimbal stands in for a flight.
        landed: !scenario.params().motion.is_on(),
        ..LogWriteOptions::default()
    };
    let logs = log_paths
        .iter()
        .map(|(path, ulog)| match ulog {
            true => stage_ulog(&rec, path, &opts),
            false => stage_dataflash(&rec, path, &opts),
        })
        .collect::<Result<Vec<_>, _>>()?;
    let recording = recording_csv::stage(&rec, &rec_path)?;
    scenario_file.commit()?;
    for log in logs {
        log.commit()?;
    }
    recording.commit()?;
    // Files first, then the terminal (a reader that closes stdout early must not cost one).
    for (path, _) in &log_paths {
        println!("wrote {}", path.display());
    }
    println!(
        "wrote {} ({} rows, {:.1} s) and {}",
        rec_path.display(),
        rec.len(),
        rec.t_s.last().copied().unwrap_or(0.0),
        scn_path.display()
    );
    Ok(())
}

/// Removes the top-level `seed = ...` line so the resolved file carries the seed actually used.
fn strip_seed(toml: &str) -> String {
    toml.lines()
        .filter(|l| !l.starts_with("seed = "))
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}
