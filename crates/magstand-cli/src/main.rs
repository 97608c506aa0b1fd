//! `magstand`: magnetometer errors caused by motor currents on multirotors.
//!
//! Every subcommand is a thin layer over the library crates: it parses arguments, reads and
//! writes files (atomically, never over an input), shows progress, and prints summaries.
//! Errors go to stderr with a non-zero exit code.
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod check_cmd;
mod compensate_cmd;
mod demo;
mod diagnose_cmd;
mod export_cmd;
mod files;
mod fit_cmd;
mod flag_terms;
mod import_cmd;
mod montecarlo_cmd;
mod progress;
mod report_cmd;
mod simulate_cmd;

/// Magnetometer disturbance from motor currents: simulate a restrained test stand, identify and
/// compensate the disturbance.
#[derive(Parser)]
#[command(name = "magstand", version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a restrained test-stand run from a scenario file.
    Simulate(simulate_cmd::SimulateArgs),
    /// Identify the motor disturbance of a recording and write the model.
    Fit(fit_cmd::FitArgs),
    /// Remove a model's predicted disturbance from a recording.
    Compensate(compensate_cmd::CompensateArgs),
    /// Locate a mismatch between a recording and the nominal simulation, name the physics left
    /// out, model it, and show the fit improve.
    Diagnose(diagnose_cmd::DiagnoseArgs),
    /// Export a model as PX4 or ArduPilot parameters, a C header, a Rust module or a JSON table.
    Export(export_cmd::ExportArgs),
    /// A PX4 ULog or ArduPilot DataFlash log as a recording (magnetometer, motors, battery,
    /// attitude, armed and landed state), with its segments, gaps and resets reported.
    Import(import_cmd::ImportArgs),
    /// Monte Carlo accuracy study against the Cramer-Rao bound (parallel, shardable).
    Montecarlo(montecarlo_cmd::MonteCarloArgs),
    /// Write an HTML report with the figures of a recording, a model and a study.
    Report(report_cmd::ReportArgs),
    /// Run the embedded paper-like scenario end to end and print what it shows.
    Demo(demo::DemoArgs),
    /// Check that the disturbance is still recovered: run the checks of a file (accuracy
    /// against the truth, diagnosis, firmware export) and fail when a limit is not met.
    Check(check_cmd::CheckArgs),
}

/// Keeps the memory a command frees for its next allocations. A fit or a diagnosis allocates
/// and drops columns of a recording's length (megabytes each) many times over; glibc served
/// each from a fresh mapping and unmapped it on free, and faulting the zeroed pages back in
/// cost a fifth of a long fit's CPU. Every allocation now comes from the heap, which is
/// trimmed only beyond 1 GiB free at its top: a 1,000,000-row fit, a diagnosis and a study
/// run 6 to 16 % faster with the same output bytes, and peak memory is what the work holds at
/// once, as before (a few % more for the heap's fragments; results/BENCHMARKS.md).
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: called first in main, before any thread exists or allocates concurrently;
    // mallopt only sets allocator thresholds and reports (0) a value it does not take.
    unsafe {
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

fn main() -> ExitCode {
    // `magstand fit ... | head` closes stdout early. Rust ignores SIGPIPE, so the next print
    // would panic; a command-line tool should end quietly as `cat` does.
    #[cfg(unix)]
    // SAFETY: called first in main, before any thread exists; SIG_DFL is a valid disposition.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    keep_freed_memory();
    // Ctrl-C or SIGTERM in the middle of a write: remove the half-written temporaries and
    // leave every target as it was. (SIGKILL cannot be caught; the next write of the same
    // file removes a temporary whose process is gone.)
    if let Err(e) = ctrlc::set_handler(|| {
        magstand_core::atomic_file::remove_pending_temporaries();
        std::process::exit(130);
    }) {
        eprintln!(
            "warning: cannot handle Ctrl-C and SIGTERM ({e}); an interrupted write may leave a hidden .tmp file"
        );
    }
    // No output may replace a file this run has read, under whatever path it is named.
    magstand_core::input_file::protect_inputs();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(a) => simulate_cmd::run(a),
        Command::Fit(a) => {
            fit_cmd::run(a).map_err(|e| anyhow::anyhow!(fit_cmd::in_flag_terms(&error_text(&e))))
        }
        Command::Compensate(a) => compensate_cmd::run(a),
        Command::Diagnose(a) => diagnose_cmd::run(a),
        Command::Export(a) => export_cmd::run(a).map_err(|e| {
            anyhow::anyhow!(flag_terms::in_flag_terms(
                &error_text(&e),
                &flag_terms::EXPORT_FLAGS
            ))
        }),
        Command::Import(a) => import_cmd::run(a).map_err(|e| {
            anyhow::anyhow!(flag_terms::in_flag_terms(
                &error_text(&e),
                &flag_terms::IMPORT_FLAGS
            ))
        }),
        Command::Montecarlo(a) => montecarlo_cmd::run(a),
        Command::Report(a) => report_cmd::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Check(a) => check_cmd::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_text(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by ": ", leaving out a cause whose text the message
/// already holds (the crates' I/O errors print their source themselves).
fn error_text(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}
