//! Regression: a black-box test found files and settings that made magstand panic, hang,
//! abort on allocation, write NaN or inf (into recordings, models and firmware parameter
//! files) or misread its input. The reproducers are in tests/data/bad-inputs (README there).
//! Each one now gives a clear error that names the file, key or column, with a non-zero
//! exit, no panic, no output file, and its inputs unchanged; the bounded ones finish (the
//! work of a replay is bounded by its rows, a simulation by a documented duration).
mod common;

use std::path::Path;

fn bad(name: &str) -> String {
    common::test_data("bad-inputs", name)
}

/// Runs `args` (with `{out}` replaced by a fresh output path), expects a clean refusal whose
/// message contains every one of `said`, and checks that no output was written and the
/// named inputs are byte-identical afterwards.
fn refused(args: &[&str], said: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.file");
    let out_s = out.display().to_string();
    let args: Vec<String> = args.iter().map(|a| a.replace("{out}", &out_s)).collect();
    let inputs: Vec<(String, Vec<u8>)> = args
        .iter()
        .filter(|a| Path::new(a).is_file())
        .map(|a| (a.clone(), std::fs::read(a).unwrap()))
        .collect();
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = common::magstand(&argv);
    assert!(!r.ok, "{argv:?} succeeded:\n{}\n{}", r.stdout, r.stderr);
    for s in said {
        assert!(
            r.stderr.contains(s),
            "{argv:?}: expected {s:?} in:\n{}",
            r.stderr
        );
    }
    assert!(!out.exists(), "{argv:?} left {out_s} behind");
    for (path, before) in inputs {
        assert_eq!(std::fs::read(&path).unwrap(), before, "{path} changed");
    }
}

#[test]
fn non_finite_and_absurd_values_are_refused_where_they_are_read() {
    let f = bad("diagnose-panic-1e308.csv");
    refused(
        &["diagnose", "--recording", &f],
        &[&f, "row 525", "mag_x_ut"],
    );
    refused(
        &["fit", "--recording", &f, "--model-out", "{out}"],
        &[&f, "mag_x_ut"],
    );
    let t = bad("last-row-t-1e300.csv");
    refused(
        &[
            "compensate",
            "--model",
            &bad("augmented-lag.json"),
            "--recording",
            &t,
            "--out",
            "{out}",
        ],
        &[&t, "t_s"],
    );
}

#[test]
fn crafted_model_files_are_refused_at_load() {
    let stair = bad("small-stair.csv");
    for (model, key) in [
        ("model-width-1e300.json", "widths"),
        ("model-coef-1e308.json", "coefficients"),
    ] {
        let m = bad(model);
        refused(
            &[
                "compensate",
                "--model",
                &m,
                "--recording",
                &stair,
                "--out",
                "{out}",
            ],
            &[&m, key],
        );
        for to in ["px4", "ardupilot"] {
            refused(
                &["export", "--model", &m, "--to", to, "--out", "{out}"],
                &[&m, key],
            );
        }
    }
    for model in ["model-motors-usize-max.json", "model-poly-motors-1e12.json"] {
        let m = bad(model);
        refused(
            &["export", "--model", &m, "--to", "px4", "--out", "{out}"],
            &[&m, "input.motors"],
        );
    }
    for (model, key) in [
        ("aug-holdout-every-0.json", "holdout_every"),
        ("aug-theta-empty.json", "theta"),
        ("aug-hysteresis-theta-empty.json", "theta"),
    ] {
        refused(
            &[
                "compensate",
                "--model",
                &bad(model),
                "--recording",
                &stair,
                "--out",
                "{out}",
            ],
            &[key],
        );
    }
    refused(
        &[
            "compensate",
            "--model",
            &bad("aug-current-lag-negative.json"),
            "--recording",
            &bad("small-lag.csv"),
            "--out",
            "{out}",
        ],
        &["current_lag", "positive"],
    );
}

#[test]
fn silent_misreads_are_named() {
    let f = bad("missing-thr_2.csv");
    refused(
        &["fit", "--recording", &f, "--model-out", "{out}"],
        &[&f, "thr_2", "thr_3"],
    );
    let f = bad("diagnose-constant-mag.csv");
    refused(&["diagnose", "--recording", &f], &[&f, "does not respond"]);
    // `fit` took the stuck axis for a disturbance of zero, fitted with no error at all, and
    // wrote the model (whose firmware parameters were zeros) with exit 0.
    refused(
        &["fit", "--recording", &f, "--model-out", "{out}"],
        &[&f, "does not respond", "mag_"],
    );
    refused(
        &[
            "export",
            "--model",
            &bad("augmented-lag.json"),
            "--to",
            "px4",
            "--instance",
            "99",
            "--out",
            "{out}",
        ],
        &[],
    );
}

#[test]
fn work_is_bounded_by_the_input_not_by_its_numbers() {
    for set in [
        "program.dwell_s=1e9",
        "program.off_s=1e6",
        "program.steps=100000",
    ] {
        refused(
            &[
                "simulate",
                "--scenario",
                "builtin:czyba2015-stair",
                "--set",
                set,
                "--out",
                "{out}",
            ],
            &["program", "36000"],
        );
    }
    refused(
        &["fit", "--recording", "/dev/zero", "--model-out", "{out}"],
        &["/dev/zero", "not a regular file"],
    );
    refused(&["montecarlo", "--threads", "20000"], &["1..=1024"]);
    refused(
        &[
            "simulate",
            "--scenario",
            "builtin:czyba2015-stair",
            "--set",
            "magnetometer.soft_iron=[[1e308,1e308,1e308],[0,1,0],[0,0,1]]",
            "--out",
            "{out}",
        ],
        // Refused where it is read, naming the row of the matrix, before any simulation.
        &["magnetometer.soft_iron[0]", "at most"],
    );
}

#[test]
fn a_clock_in_microseconds_is_diagnosed_in_bounded_time() {
    // Before, the replay's cost grew with the time span: this never finished.
    let r = common::magstand(&["diagnose", "--recording", &bad("time-in-microseconds.csv")]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stdout.contains("verdict"), "{}", r.stdout);
}

#[test]
fn an_import_window_that_is_not_a_time_is_refused() {
    // Before, `--from-s nan` compared false with every time and was reported as every sample
    // "dropped outside the window".
    let log = common::test_data("real-logs", "px4-fmuv3-uavcan-esc-status.ulg");
    for (flag, value) in [("--from-s", "nan"), ("--to-s", "inf"), ("--from-s", "-inf")] {
        let arg = format!("{flag}={value}");
        refused(
            &["import", "--ulog", &log, &arg, "--out", "{out}"],
            &[flag, "expected a finite time"],
        );
    }
    refused(
        &[
            "import", "--ulog", &log, "--from-s", "300", "--to-s", "200", "--out", "{out}",
        ],
        &["the window is empty"],
    );
}

#[test]
fn a_flight_log_given_as_a_recording_is_named_with_the_import_that_reads_it() {
    // Before, the CSV parser's complaint: "row 0: malformed CSV: ... invalid utf-8".
    let ulog = common::test_data("real-logs", "px4-fmuv3-uavcan-esc-status.ulg");
    refused(
        &["fit", "--recording", &ulog, "--model-out", "{out}"],
        &["a PX4 ULog log, not a recording", "magstand import --ulog"],
    );
    let bin = common::test_data("real-logs", "ardupilot-copter462-pixhawk4-first80k.bin");
    refused(
        &["diagnose", "--recording", &bin, "--json", "{out}"],
        &["an ArduPilot DataFlash log", "magstand import --dataflash"],
    );
}
