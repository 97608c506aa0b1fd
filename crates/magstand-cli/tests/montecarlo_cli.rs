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
