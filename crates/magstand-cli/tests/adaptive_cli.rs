//! `magstand compensate --adapt` and `magstand export --to c-adaptive|rust-adaptive` from the
//! command line: the recursion runs, writes what `compensate` writes, names bad settings, and
//! refuses models it cannot update.
mod common;
use common::{magstand, simulate_quick_tables};

#[test]
fn adaptive_compensation_and_its_export_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    simulate_quick_tables(&p("sim"));
    let rec = p("sim/recording.csv");
    let model = p("m.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &rec,
        "--model-out",
        &model,
        "--rbf",
        "3",
        "--estimation",
        "global",
    ]);
    assert!(r.ok, "{}", r.stderr);

    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &rec,
        "--out",
        &p("c.csv"),
        "--adapt",
    ]);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stdout.contains("updated row by row") && r.stdout.contains("the fixed model"),
        "{}",
        r.stdout
    );
    let header = std::fs::read_to_string(p("c.csv")).unwrap();
    let header = header.lines().next().unwrap();
    assert!(
        header.contains("dist_x_ut") && header.contains("sd_z_ut"),
        "{header}"
    );

    // A forgetting factor out of range is named with its flag, and nothing is written.
    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &rec,
        "--out",
        &p("bad.csv"),
        "--adapt",
        "--forgetting",
        "1.5",
    ]);
    assert!(
        !r.ok && r.stderr.contains("--forgetting") && r.stderr.contains("1.5"),
        "{}",
        r.stderr
    );
    assert!(!dir.path().join("bad.csv").exists());

    for (target, marker) in [
        ("c-adaptive", "magstand_adapt_step"),
        ("rust-adaptive", "pub fn step"),
    ] {
        let r = magstand(&[
            "export",
            "--model",
            &model,
            "--to",
            target,
            "--forgetting",
            "0.995",
        ]);
        assert!(r.ok && r.stdout.contains(marker), "{target}: {}", r.stderr);
    }
    let r = magstand(&[
        "export",
        "--model",
        &model,
        "--to",
        "px4",
        "--forgetting",
        "0.99",
    ]);
    assert!(!r.ok && r.stderr.contains("--forgetting"), "{}", r.stderr);

    // The autopilots' straight line has no local models to update.
    let line = p("px4.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &rec,
        "--model-out",
        &line,
        "--method",
        "px4",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let r = magstand(&[
        "compensate",
        "--model",
        &line,
        "--recording",
        &rec,
        "--out",
        &p("c2.csv"),
        "--adapt",
    ]);
    assert!(!r.ok && r.stderr.contains("polynomial"), "{}", r.stderr);
}
