//! Running the built `magstand` binary from the integration tests.
use std::process::Command;

/// What a run of `magstand` gave.
pub struct Run {
    /// Exit status was success.
    pub ok: bool,
    /// Standard output.
    #[allow(dead_code)] // not every test file reads it
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

/// Runs `magstand` with `args`; fails the test on a panic message, whatever the exit status.
pub fn magstand(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_magstand"))
        .args(args)
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    Run {
        ok: out.status.success(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr,
    }
}

/// Simulates a short run of the paper's tables (1 s dwell, no rigid body) into `out`, failing
/// the test if it does not succeed: a quick recording for commands that need one.
#[allow(dead_code)] // not every test file needs a recording
pub fn simulate_quick_tables(out: &str) {
    simulate_quick("builtin:czyba2015-tables", "1.0", out, None, &[]);
}

/// Simulates a short bench-supply stair (2 s dwell, no rigid body) with `seed` (the
/// scenario's own where None) and the extra `key=value` settings `sets` into `out`, failing
/// the test if it does not succeed: a quick stand recording for the physics fit.
#[allow(dead_code)] // not every test file needs a stand recording
pub fn simulate_bench_stair(out: &str, seed: Option<&str>, sets: &[&str]) {
    simulate_quick("builtin:bench-supply-stair", "2.0", out, seed, sets);
}

/// Simulates `scenario` with its program's dwell at `dwell_s` and no rigid body into `out`.
fn simulate_quick(scenario: &str, dwell_s: &str, out: &str, seed: Option<&str>, sets: &[&str]) {
    let dwell = format!("program.dwell_s={dwell_s}");
    let mut args = vec![
        "simulate",
        "--scenario",
        scenario,
        "--out",
        out,
        "--set",
        &dwell,
        "--set",
        "stand.enabled=false",
    ];
    if let Some(seed) = seed {
        args.extend(["--seed", seed]);
    }
    for set in sets {
        args.extend(["--set", set]);
    }
    let r = magstand(&args);
    assert!(r.ok, "{}", r.stderr);
}

/// The path of `name` in the repository's `tests/data/<folder>` (real logs, bad inputs).
#[allow(dead_code)] // not every test file reads checked-in data
pub fn test_data(folder: &str, name: &str) -> String {
    format!(
        "{}/../../tests/data/{folder}/{name}",
        env!("CARGO_MANIFEST_DIR")
    )
}

/// The "field magnitude spread (sd) A -> B uT" of `compensate`'s line for a flight, as
/// [A, B]; empty when the line is not there.
#[allow(dead_code)] // not every test file compensates a flight
pub fn flight_spread(stdout: &str) -> Vec<f64> {
    stdout
        .split("spread (sd) ")
        .nth(1)
        .and_then(|s| s.split(" uT").next())
        .map(|s| s.split(" -> ").filter_map(|v| v.parse().ok()).collect())
        .unwrap_or_default()
}

/// `magstand diagnose --recording R --json J` with `more` options after them, and the
/// diagnosis file it wrote, read as JSON (None where it wrote none).
#[allow(dead_code)] // not every test file diagnoses
pub fn diagnose(
    recording: &std::path::Path,
    json: &std::path::Path,
    more: &[&str],
) -> (Run, Option<serde_json::Value>) {
    let mut args = vec![
        "diagnose",
        "--recording",
        recording.to_str().expect("a UTF-8 path"),
        "--json",
        json.to_str().expect("a UTF-8 path"),
    ];
    args.extend_from_slice(more);
    let r = magstand(&args);
    let d = std::fs::read_to_string(json)
        .ok()
        .map(|text| serde_json::from_str(&text).expect("the diagnosis file is JSON"));
    (r, d)
}

/// `magstand fit --recording R --model-out M` with no other option, as a user's first fit.
#[allow(dead_code)] // not every test file fits
pub fn fit(recording: &str, model_out: &str) -> Run {
    magstand(&["fit", "--recording", recording, "--model-out", model_out])
}

/// Fits a flight recording's model with its Earth field fitted out (`fit --recording R
/// --earth fit --model-out M`), failing the test if it does not succeed.
#[allow(dead_code)] // not every test file fits a flight
pub fn fit_flight(recording: &str, model_out: &str) {
    let r = magstand(&[
        "fit",
        "--recording",
        recording,
        "--earth",
        "fit",
        "--model-out",
        model_out,
    ]);
    assert!(r.ok, "{}", r.stderr);
}
