//! The README's first command, `magstand demo`: simulates the paper-like stand, fits every
//! method and the default choice, judges them against the truth, and writes the model, the
//! compensated validation run and the report.
mod common;
use common::magstand;

#[test]
fn the_demo_runs_and_writes_what_it_says() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let r = magstand(&["demo", "--out", out.to_str().unwrap()]);
    assert!(r.ok, "{}", r.stderr);
    for line in [
        "model families",
        "magstand fit default (",
        "no compensation",
    ] {
        assert!(r.stdout.contains(line), "no `{line}` in:\n{}", r.stdout);
    }
    for file in [
        "identification.csv",
        "validation.csv",
        "model.json",
        "validation-compensated.csv",
        "report/index.html",
    ] {
        assert!(out.join(file).is_file(), "{file} not written");
    }
    // The default choice's row: a finite error against the truth, far below no compensation.
    let value = |label: &str| -> f64 {
        let line = r.stdout.lines().find(|l| l.starts_with(label)).unwrap();
        line[label.len()..]
            .split_whitespace()
            .find_map(|w| w.parse().ok())
            .unwrap()
    };
    let (none, chosen) = (value("no compensation"), value("magstand fit default ("));
    assert!(
        chosen.is_finite() && chosen < 0.1 * none,
        "chosen {chosen} µT, uncompensated {none} µT"
    );
}
