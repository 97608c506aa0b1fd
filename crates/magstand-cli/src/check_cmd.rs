//! `magstand check`: ground-truth recovery as a gate in the user's CI. Every entry of the check
//! file is checked before anything runs; the limits are then measured, printed as a table and,
//! with `--junit`, written as JUnit XML. Exits non-zero when any limit fails.
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use crate::files;
use crate::progress::RunsBar;
use magstand_check::{CheckFile, failures, junit_xml, run_check, table, work_units};

/// Arguments of `magstand check`.
#[derive(Args)]
pub struct CheckArgs {
    /// The check file: `[[check]]` entries with a scenario, a method, runs, a seed and limits.
    checks: PathBuf,
    /// Also write the outcome as JUnit XML here (one test suite per check, one test case per
    /// limit).
    #[arg(long)]
    junit: Option<PathBuf>,
    /// Worker threads (default: all cores; 1 to 1024). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
}

/// Runs `magstand check`.
pub fn run(a: CheckArgs) -> Result<()> {
    let checks = CheckFile::load(&a.checks)?.check()?;
    if let Some(junit) = &a.junit {
        let mut inputs = vec![a.checks.clone()];
        inputs.extend(checks.input_files());
        files::refuse_overwriting_inputs(&inputs, &[junit])?;
    }
    let mut outcomes = Vec::with_capacity(checks.checks.len());
    for check in &checks.checks {
        let bar = RunsBar::new(&check.name, work_units(check));
        outcomes.push(run_check(check, a.threads.map(usize::from), &bar)?);
    }
    print!("{}", table(&outcomes));
    if let Some(junit) = &a.junit {
        let xml = junit_xml(&checks.origin, &outcomes)?;
        files::ensure_parent(junit)?;
        magstand_core::atomic_file::write_bytes(junit, xml.as_bytes())?;
        println!("\nwrote {}", junit.display());
    }
    let failed: usize = outcomes
        .iter()
        .map(|c| c.results.iter().filter(|r| !r.passed).count())
        .sum();
    let total: usize = outcomes.iter().map(|c| c.results.len()).sum();
    if failed > 0 {
        eprint!("\n{}", failures(&outcomes));
        bail!("{failed} of {total} limits failed");
    }
    println!("\nall {total} limits of {} checks hold", outcomes.len());
    Ok(())
}
