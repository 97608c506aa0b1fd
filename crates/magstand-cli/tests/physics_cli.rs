//! `magstand fit --method physics` and the default choice from the command line: the physics
//! model file is compensated with and exported over a recording's rows like the others, and
//! what it cannot be (code over one input, a line without rows, an update by --adapt) is
//! refused by name with nothing written.
mod common;
use common::{magstand, simulate_bench_stair};

#[test]
fn a_physics_model_compensates_and_exports_over_a_recordings_rows() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    for (out, seed) in [("a", "1"), ("b", "2")] {
        simulate_bench_stair(&p(out), Some(seed), &[]);
    }
    let (ident, valid) = (p("a/recording.csv"), p("b/recording.csv"));
    let model = p("physics.json");
    let r = magstand(&[
        "fit",
        "--recording",
        &ident,
        "--model-out",
        &model,
        "--method",
        "physics",
    ]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stdout.contains("model: physics"), "{}", r.stdout);
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(
        text.contains("\"format\": \"magstand-augmented-model\"")
            && text.contains("\"method\": \"physics\""),
        "{text}"
    );

    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &valid,
        "--out",
        &p("c.csv"),
    ]);
    assert!(
        r.ok && r.stdout.contains("against ground truth"),
        "{}",
        r.stderr
    );

    let r = magstand(&[
        "export",
        "--model",
        &model,
        "--to",
        "ardupilot",
        "--recording",
        &valid,
        "--out",
        &p("ap.param"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let params = std::fs::read_to_string(p("ap.param")).unwrap();
    for key in ["COMPASS_MOTCT,1", "COMPASS_MOT_X,", "COMPASS_MOT_Z,"] {
        assert!(params.contains(key), "{params}");
    }
    let finite = params
        .lines()
        .filter(|l| l.starts_with("COMPASS_MOT_"))
        .all(|l| {
            l.split(',')
                .nth(1)
                .unwrap()
                .parse::<f64>()
                .unwrap()
                .is_finite()
        });
    assert!(finite, "{params}");

    for (args, why) in [
        (vec!["--to", "px4"], "--recording"),
        (
            vec!["--to", "c", "--recording", valid.as_str()],
            "no form over one input",
        ),
    ] {
        let mut all = vec!["export", "--model", model.as_str(), "--out", "never.h"];
        all.extend(args);
        let r = magstand(&all);
        assert!(!r.ok && r.stderr.contains(why), "{all:?}: {}", r.stderr);
        assert!(!std::path::Path::new("never.h").exists());
    }
    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &valid,
        "--out",
        &p("x.csv"),
        "--adapt",
    ]);
    assert!(!r.ok && r.stderr.contains("--adapt"), "{}", r.stderr);

    // The report judges it like any model: its compensation beside the autopilots' lines.
    let r = magstand(&[
        "report",
        "--recording",
        &valid,
        "--model",
        &model,
        "--out",
        &p("rep"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let page = std::fs::read_to_string(p("rep/index.html")).unwrap();
    assert!(
        page.contains("stand&#39;s physics") || page.contains("stand's physics"),
        "no physics section"
    );
    assert!(page.contains("this model (physics)"), "no compensation row");

    // The default fit prints its table and records it in the model file.
    let chosen = p("chosen.json");
    let r = magstand(&["fit", "--recording", &ident, "--model-out", &chosen]);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stdout.contains("model families") && r.stdout.contains("<- chosen"),
        "{}",
        r.stdout
    );
    let text = std::fs::read_to_string(&chosen).unwrap();
    assert!(
        text.contains("\"choice\"") && text.contains("\"rule\""),
        "{text}"
    );
    // And the report shows the table.
    let r = magstand(&[
        "report",
        "--recording",
        &valid,
        "--model",
        &chosen,
        "--out",
        &p("rep2"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let page = std::fs::read_to_string(p("rep2/index.html")).unwrap();
    assert!(
        page.contains("(kept)") && page.contains("one standard error"),
        "no choice table"
    );
}
