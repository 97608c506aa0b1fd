//! `magstand export` from the command line: a clean parameter file on stdout, the cost of the
//! linear form on stderr, bad settings named, inputs never overwritten.
mod common;
use common::magstand;

#[test]
fn export_writes_parameter_files_and_refuses_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let r = magstand(&[
        "simulate",
        "--scenario",
        "builtin:czyba2015-tables",
        "--out",
        &p("sim"),
        "--set",
        "program.dwell_s=1.0",
        "--set",
        "stand.enabled=false",
    ]);
    assert!(r.ok, "{}", r.stderr);
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
