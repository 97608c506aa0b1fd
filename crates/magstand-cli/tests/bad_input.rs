//! The command line on bad input: a clear message naming the key, file, row or column, a
//! non-zero exit, no panic, and nothing written.
mod common;

fn magstand(args: &[&str]) -> (bool, String) {
    let r = common::magstand(args);
    (r.ok, r.stderr)
}

#[test]
fn out_of_range_scenario_value_names_the_key_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let (ok, err) = magstand(&[
        "simulate",
        "--scenario",
        "builtin:czyba2015-stair",
        "--out",
        out.to_str().unwrap(),
        "--set",
        "supply.capacity_ah=-1",
    ]);
    assert!(
        !ok && err.contains("supply.capacity_ah") && err.contains("> 0"),
        "{err}"
    );
    assert!(!out.exists(), "nothing may be written");
    let (ok, err) = magstand(&[
        "simulate",
        "--scenario",
        "builtin:czyba2015-stair",
        "--out",
        out.to_str().unwrap(),
        "--set",
        "program.max=1.5",
    ]);
    assert!(!ok && err.contains("program.max"), "{err}");
}

#[test]
fn unknown_scenario_key_and_missing_file_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s.toml");
    std::fs::write(&s, "name = \"x\"\n[program]\nkind = \"stair\"\nsteps = 3\ndwell_s = 1.0\n[motors]\ncuont = 4\n").unwrap();
    let (ok, err) = magstand(&[
        "simulate",
        "--scenario",
        s.to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(
        !ok && err.contains("cuont") && err.contains("s.toml"),
        "{err}"
    );
    let (ok, err) = magstand(&[
        "simulate",
        "--scenario",
        "no-such.toml",
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("no-such.toml"), "{err}");
}

#[test]
fn fit_names_file_row_and_column_and_compensate_refuses_to_overwrite_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let r = dir.path().join("r.csv");
    std::fs::write(&r, "t_s,thr,mag_x_ut,mag_y_ut\n0,0,1,2\n").unwrap();
    let m = dir.path().join("m.json");
    let (ok, err) = magstand(&[
        "fit",
        "--recording",
        r.to_str().unwrap(),
        "--model-out",
        m.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.contains("r.csv") && err.contains("mag_z_ut"),
        "{err}"
    );
    std::fs::write(
        &r,
        "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,0,1,2,3\n1,0.5,1,nan,3\n",
    )
    .unwrap();
    let (ok, err) = magstand(&[
        "fit",
        "--recording",
        r.to_str().unwrap(),
        "--model-out",
        m.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.contains("row 2") && err.contains("mag_y_ut"),
        "{err}"
    );
    assert!(!m.exists());
    // A real run, then compensate onto its own input.
    let run = dir.path().join("run");
    let (ok, err) = magstand(&[
        "simulate",
        "--scenario",
        "builtin:czyba2015-tables",
        "--out",
        run.to_str().unwrap(),
        "--set",
        "program.steps=10",
    ]);
    assert!(ok, "{err}");
    let rec = run.join("recording.csv");
    let (ok, err) = magstand(&[
        "fit",
        "--recording",
        rec.to_str().unwrap(),
        "--model-out",
        m.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let before = std::fs::read(&rec).unwrap();
    let (ok, err) = magstand(&[
        "compensate",
        "--model",
        m.to_str().unwrap(),
        "--recording",
        rec.to_str().unwrap(),
        "--out",
        rec.to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("refusing to overwrite"), "{err}");
    assert_eq!(before, std::fs::read(&rec).unwrap());
}

#[test]
fn same_seed_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str| {
        let out = dir.path().join(name);
        let (ok, err) = magstand(&[
            "simulate",
            "--scenario",
            "builtin:bench-supply-stair",
            "--out",
            out.to_str().unwrap(),
            "--seed",
            "4",
            "--set",
            "program.steps=3",
        ]);
        assert!(ok, "{err}");
        (
            std::fs::read(out.join("recording.csv")).unwrap(),
            std::fs::read(out.join("scenario.toml")).unwrap(),
        )
    };
    let (a, b) = (run("a"), run("b"));
    assert_eq!(a.0, b.0);
    assert_ne!(a.1.len(), 0);
}
