//! `magstand export` from the command line: a clean parameter file on stdout, the cost of the
//! linear form on stderr, bad settings named, inputs never overwritten.
mod common;
use common::{magstand, simulate_quick_tables};

#[test]
fn export_writes_parameter_files_and_refuses_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    simulate_quick_tables(&p("sim"));
    let model = p("m.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &p("sim/recording.csv"),
        "--model-out",
        &model,
        "--rbf",
        "3",
        "--estimation",
        "global",
    ]);
    assert!(r.ok, "{}", r.stderr);

    let r = magstand(&["export", "--model", &model, "--to", "ardupilot"]);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stdout
            .lines()
            .filter(|l| !l.starts_with('#'))
            .all(|l| l.split(',').count() == 2),
        "{}",
        r.stdout
    );
    assert!(
        r.stdout.contains("COMPASS_MOT_Z,") && r.stderr.contains("heading error"),
        "{}",
        r.stderr
    );

    let r = magstand(&[
        "export",
        "--model",
        &model,
        "--to",
        "px4",
        "--instance",
        "1",
        "--out",
        &p("px4.params"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let text = std::fs::read_to_string(p("px4.params")).unwrap();
    assert!(
        text.contains("CAL_MAG1_ZCOMP") && text.contains("CAL_MAG_COMP_TYP\t1"),
        "{text}"
    );

    let r = magstand(&["export", "--model", &model, "--to", "c", "--out", &p("m.h")]);
    assert!(
        r.ok && std::fs::read_to_string(p("m.h"))
            .unwrap()
            .contains("magstand_dist"),
        "{}",
        r.stderr
    );

    let r = magstand(&[
        "export",
        "--model",
        &model,
        "--to",
        "ardupilot",
        "--instance",
        "4",
    ]);
    assert!(!r.ok && r.stderr.contains("--instance 4"), "{}", r.stderr);
    let r = magstand(&["export", "--model", &model, "--to", "px4", "--out", &model]);
    assert!(
        !r.ok && r.stderr.contains("refusing to overwrite"),
        "{}",
        r.stderr
    );
    let r = magstand(&["export", "--model", &p("sim/recording.csv"), "--to", "px4"]);
    assert!(!r.ok && r.stderr.contains("recording.csv"), "{}", r.stderr);
}

#[test]
fn export_writes_per_motor_rust_and_json_forms() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    // ArduPilot's own per-motor procedure: each motor stepped alone.
    let r = magstand(&[
        "simulate",
        "--scenario",
        "builtin:per-motor-steps",
        "--out",
        &p("sim"),
        "--set",
        "program.dwell_s=0.5",
        "--set",
        "stand.enabled=false",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let rec = p("sim/recording.csv");
    let motors = p("motors.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &rec,
        "--model-out",
        &motors,
        "--inputs",
        "motors",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let r = magstand(&[
        "export",
        "--model",
        &motors,
        "--to",
        "ardupilot-per-motor",
        "--recording",
        &rec,
    ]);
    assert!(r.ok, "{}", r.stderr);
    for name in ["COMPASS_PMOT_EN,1", "COMPASS_PMOT_EXP,", "COMPASS_PMOT4_Z,"] {
        assert!(r.stdout.contains(name), "{name} not in\n{}", r.stdout);
    }
    assert!(r.stderr.contains("per-motor form"), "{}", r.stderr);
    // Without the recording it says what it needs.
    let r = magstand(&["export", "--model", &motors, "--to", "ardupilot-per-motor"]);
    assert!(!r.ok && r.stderr.contains("--recording"), "{}", r.stderr);

    // JSON with the per-motor set, and a line per ampere from the recording's bat_a.
    let r = magstand(&[
        "export",
        "--model",
        &motors,
        "--to",
        "json",
        "--recording",
        &rec,
        "--input",
        "current",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let doc: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(doc["linear"]["ardupilot"]["COMPASS_MOTCT"], 2.0);
    assert_eq!(
        doc["per_motor"]["compensation_mg"]
            .as_array()
            .unwrap()
            .len(),
        4
    );

    // The full model of the overall throttle as a no_std Rust module.
    let thr = p("thr.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &rec,
        "--model-out",
        &thr,
        "--rbf",
        "3",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let r = magstand(&[
        "export",
        "--model",
        &thr,
        "--to",
        "rust",
        "--out",
        &p("m.rs"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let module = std::fs::read_to_string(p("m.rs")).unwrap();
    assert!(
        module.contains("pub fn dist_ut(raw: f64) -> [f64; 3]"),
        "{module}"
    );
    let r = magstand(&["export", "--model", &motors, "--to", "rust"]);
    assert!(!r.ok && r.stderr.contains("per-motor"), "{}", r.stderr);
}
