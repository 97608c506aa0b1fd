//! Regression: a JSON document of another kind given where a diagnosis is read (a model file
//! as `report --diagnosis`) was refused with the first field the diagnosis has and the model
//! lacks ("missing field `recording` at line 197"), which does not say what is wrong. The
//! document's own `format` is now read first and named.
mod common;

use common::magstand;

#[test]
fn a_model_given_as_a_diagnosis_is_named_as_a_model() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).display().to_string();
    common::simulate_quick_tables(&p("run"));
    let recording = format!("{}/recording.csv", p("run"));
    let r = magstand(&[
        "fit",
        "--recording",
        &recording,
        "--model-out",
        &p("m.json"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    std::fs::write(p("plain.json"), r#"{"verdict": []}"#).unwrap();
    for (document, said) in [
        (
            "m.json",
            "this is a `magstand-model` document: expected a `magstand-diagnosis` one",
        ),
        (
            "plain.json",
            "no `format` field: expected a `magstand-diagnosis` document",
        ),
    ] {
        let r = magstand(&[
            "report",
            "--recording",
            &recording,
            "--diagnosis",
            &p(document),
            "--out",
            &p("report"),
        ]);
        assert!(!r.ok, "{document}: {}", r.stdout);
        assert!(
            r.stderr.contains(&p(document)) && r.stderr.contains(said),
            "{document}: {}",
            r.stderr
        );
        assert!(!std::path::Path::new(&p("report")).exists());
    }
}
