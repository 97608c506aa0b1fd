//! Regression: `magstand export` checked `--instance` only on the local linear path; a
//! physics model exported with `--to px4 --instance 7` wrote `CAL_MAG7_*COMP`, a parameter no
//! PX4 has (a wrong firmware parameter). The settings are now checked once, before any model
//! is read, for every kind of model.
mod common;
use common::{magstand, simulate_bench_stair};

#[test]
fn a_physics_export_refuses_an_instance_the_autopilot_does_not_have() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    simulate_bench_stair(&p("a"), None, &[]);
    let rec = p("a/recording.csv");
    let model = p("physics.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &rec,
        "--model-out",
        &model,
        "--method",
        "physics",
    ]);
    assert!(r.ok, "{}", r.stderr);
    for (target, instance, why) in [
        ("px4", "7", "CAL_MAG0 to CAL_MAG3"),
        ("ardupilot", "4", "numbered 1 to 3"),
        ("ardupilot-per-motor", "2", "first compass only"),
    ] {
        let out = p(&format!("{target}.params"));
        let r = magstand(&[
            "export",
            "--model",
            &model,
            "--to",
            target,
            "--recording",
            &rec,
            "--instance",
            instance,
            "--out",
            &out,
        ]);
        assert!(
            !r.ok && r.stderr.contains(why),
            "{target} {instance}: {}",
            r.stderr
        );
        assert!(
            !std::path::Path::new(&out).exists(),
            "{target}: {out} written"
        );
    }
}
