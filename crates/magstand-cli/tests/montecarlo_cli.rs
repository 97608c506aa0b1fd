//! `magstand montecarlo` from the command line: bad settings fail before any run with the
//! setting named and nothing written; a sharded study merges into the single-machine summary;
//! a sweep tabulates every value.
mod common;

fn magstand(args: &[&str]) -> (bool, String, String) {
    let r = common::magstand(args);
    (r.ok, r.stdout, r.stderr)
}

const QUICK: [&str; 6] = [
    "--set",
    "program.dwell_s=1.0",
    "--set",
    "stand.enabled=false",
    "--methods",
    "px4,global-weighted",
];

#[test]
fn bad_settings_are_named_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let o = out.to_str().unwrap();
    let base = [
        "montecarlo",
        "--scenario",
        "builtin:czyba2015-tables",
        "--out",
        o,
    ];
    for (extra, needle) in [
        (vec!["--runs", "10", "--shard", "4/3"], "--shard"),
        (
            vec!["--runs", "10", "--methods", "px4,nonsense"],
            "nonsense",
        ),
        (vec!["--runs", "1"], "--runs"),
        (vec!["--runs", "10", "--threads", "0"], "--threads"),
        (
            vec!["--runs", "10", "--sweep", "program.steps=10,0"],
            "program.steps",
        ),
        (vec!["--runs", "10", "--sweep", "program.steps"], "--sweep"),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(extra.iter().copied()).collect();
        let (ok, _, err) = magstand(&args);
        assert!(!ok && err.contains(needle), "{extra:?}: {err}");
    }
    assert!(!out.join("runs.csv").exists(), "nothing may be written");
    let (ok, _, err) = magstand(&["montecarlo", "merge", "/nonexistent/shard", "--out", o]);
    assert!(!ok && err.contains("/nonexistent/shard"), "{err}");
}

#[test]
fn shards_merge_to_the_single_machine_summary_and_sweeps_tabulate() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let study = |extra: &[&str]| {
        let mut args = vec![
            "montecarlo",
            "--scenario",
            "builtin:czyba2015-tables",
            "--runs",
            "4",
        ];
        args.extend(QUICK);
        args.extend(extra);
        let (ok, stdout, err) = magstand(&args);
        assert!(ok, "{err}");
        stdout
    };
    study(&["--out", &p("whole"), "--threads", "2"]);
    study(&["--out", &p("s1"), "--shard", "1/2", "--threads", "1"]);
    study(&["--out", &p("s2"), "--shard", "2/2", "--threads", "1"]);
    assert!(!dir.path().join("s1/SUMMARY.json").exists());
    let (ok, _, err) = magstand(&[
        "montecarlo",
        "merge",
        &p("s2"),
        &p("s1"),
        "--out",
        &p("merged"),
    ]);
    assert!(ok, "{err}");
    for f in ["SUMMARY.json", "runs.csv"] {
        let a = std::fs::read(dir.path().join("whole").join(f)).unwrap();
        let b = std::fs::read(dir.path().join("merged").join(f)).unwrap();
        assert!(
            a == b,
            "{f} differs between the whole study and the merged shards"
        );
    }
    let svg = std::fs::read_to_string(dir.path().join("whole/error-vs-throttle.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("RMSE"));

    let stdout = study(&["--out", &p("sweep"), "--sweep", "program.dwell_s=0.5,2.0"]);
    let table = std::fs::read_to_string(dir.path().join("sweep/sweep.csv")).unwrap();
    assert_eq!(table.lines().count(), 1 + 2 * 2, "{table}");
    assert!(
        table.lines().nth(1).unwrap().starts_with("0.5,px4,"),
        "{table}"
    );
    assert!(stdout.contains("program.dwell_s"), "{stdout}");
    // Longer dwell, more data: the weighted fit's median error is lower.
    let p50 = |v: &str| -> f64 {
        table
            .lines()
            .find(|l| l.starts_with(&format!("{v},global-weighted,")))
            .unwrap()
            .split(',')
            .nth(2)
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!(p50("2.0") < p50("0.5"), "{table}");
}

#[test]
fn a_report_shows_a_study_beside_a_recording_and_model() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let mut args = vec![
        "montecarlo",
        "--scenario",
        "builtin:czyba2015-tables",
        "--runs",
        "3",
    ];
    args.extend(QUICK);
    let study_dir = p("study");
    args.extend(["--out", &study_dir]);
    let (ok, _, err) = magstand(&args);
    assert!(ok, "{err}");
    let sim = p("sim");
    let (ok, _, err) = magstand(&[
        "simulate",
        "--scenario",
        "builtin:czyba2015-tables",
        "--out",
        &sim,
        "--set",
        "program.dwell_s=1.0",
        "--set",
        "stand.enabled=false",
    ]);
    assert!(ok, "{err}");
    let rec = p("sim/recording.csv");
    let model = p("m.json");
    let (ok, _, err) = magstand(&["fit", "--recording", &rec, "--model-out", &model]);
    assert!(ok, "{err}");
    let out = p("report");
    let (ok, stdout, err) = magstand(&[
        "report",
        "--recording",
        &rec,
        "--model",
        &model,
        "--montecarlo",
        &study_dir,
        "--out",
        &out,
    ]);
    assert!(ok && stdout.contains("index.html"), "{err}");
    let html = std::fs::read_to_string(dir.path().join("report/index.html")).unwrap();
    for needle in [
        "The recording",
        "The model",
        "Compensation",
        "Monte Carlo study",
        "id=\"fig-mc-error-vs-throttle\"",
        "id=\"fig-mc-parameter-errors-global-weighted\"",
        "id=\"fig-rbf-weights\"",
        "id=\"fig-heading-vs-throttle\"",
        "magstand report --recording",
    ] {
        assert!(html.contains(needle), "report lacks {needle}");
    }
    assert!(dir.path().join("report/mc-error-vs-throttle.svg").exists());
    // A report never writes over its inputs.
    let (ok, _, err) = magstand(&["report", "--recording", &rec, "--out", &p("sim")]);
    assert!(ok, "{err}");
    let (ok, _, err) = magstand(&[
        "report",
        "--recording",
        &p("report/index.html"),
        "--out",
        &p("report"),
    ]);
    assert!(!ok && err.contains("index.html"), "{err}");
}
