//! Every reproducer in tests/data/bad-inputs through every subcommand that takes its kind of
//! file: recordings through fit, compensate, diagnose and report; model and diagnosis files
//! through compensate, export (each target) and report; scenarios through simulate, diagnose
//! and montecarlo. Whatever the exit, nothing panics or aborts and no input changes; an exit
//! of 0 comes only with outputs whose every number is finite (no NaN, inf or, in a model or
//! an export, null).
//!
//! Bounded time is not asserted with a clock: the bounds are the documented ones (rows, a
//! simulated duration, substeps per stretch), and a run that broke them would hang this test,
//! which CI's time limit turns into a failure.
mod common;

use std::path::{Path, PathBuf};

use magstand_core::file_fuzzing::non_finite_word;

fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(files_under(&p));
        } else {
            out.push(p);
        }
    }
    out.sort();
    out
}

fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    files_under(dir)
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect()
}

/// Fails unless every number in every file under `out` is finite.
fn assert_finite_outputs(args: &[String], out: &Path) {
    for f in files_under(out) {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let ext = f.extension().map(|e| e.to_string_lossy().into_owned());
        let Ok(text) = std::fs::read_to_string(&f) else {
            continue; // binary logs are checked by their own readers' tests
        };
        match ext.as_deref() {
            Some("csv" | "params" | "param" | "h" | "rs" | "toml") => {
                if let Some(w) = non_finite_word(&text) {
                    panic!("{args:?} exited 0 but wrote `{w}` into {}", f.display());
                }
            }
            // serde_json writes a non-finite number as null: a model or an export never has
            // one; a diagnosis has optional fields, which are null by design.
            Some("json") if name != "diagnosis.json" => {
                let v: serde_json::Value = serde_json::from_str(&text)
                    .unwrap_or_else(|e| panic!("{args:?}: {} is not JSON: {e}", f.display()));
                assert!(
                    !v.to_string().contains("null"),
                    "{args:?} exited 0 but wrote null into {}",
                    f.display()
                );
            }
            _ => {}
        }
    }
}

#[test]
fn every_bad_input_through_every_subcommand() {
    let folder = PathBuf::from(common::test_data("bad-inputs", ""));
    let before = snapshot(&folder);
    let dir = tempfile::tempdir().unwrap();
    let stair = folder.join("small-stair.csv").display().to_string();
    let good_model = dir.path().join("good-model.json").display().to_string();
    let r = common::magstand(&["fit", "--recording", &stair, "--model-out", &good_model]);
    assert!(r.ok, "{}", r.stderr);

    let mut runs = 0;
    let mut refused = 0;
    for input in files_under(&folder) {
        let f = input.display().to_string();
        let commands: Vec<Vec<&str>> = match input.extension().and_then(|e| e.to_str()) {
            Some("csv") => vec![
                vec!["fit", "--recording", &f, "--model-out", "{out}/model.json"],
                vec![
                    "compensate",
                    "--model",
                    &good_model,
                    "--recording",
                    &f,
                    "--out",
                    "{out}/c.csv",
                ],
                vec![
                    "diagnose",
                    "--recording",
                    &f,
                    "--json",
                    "{out}/diagnosis.json",
                    "--model-out",
                    "{out}/augmented.json",
                    "--augmented",
                    "{out}/augmented.toml",
                ],
                vec!["report", "--recording", &f, "--out", "{out}/report"],
            ],
            Some("json") => {
                let mut c = vec![
                    vec![
                        "compensate",
                        "--model",
                        &f,
                        "--recording",
                        &stair,
                        "--out",
                        "{out}/c.csv",
                    ],
                    vec![
                        "report",
                        "--recording",
                        &stair,
                        "--model",
                        &f,
                        "--out",
                        "{out}/report",
                    ],
                    vec![
                        "report",
                        "--recording",
                        &stair,
                        "--diagnosis",
                        &f,
                        "--out",
                        "{out}/r2",
                    ],
                ];
                for (to, name) in [
                    ("px4", "p.params"),
                    ("ardupilot", "a.param"),
                    ("c", "m.h"),
                    ("rust", "m.rs"),
                    ("json", "table.json"),
                ] {
                    c.push(vec!["export", "--model", &f, "--to", to, "--out", name]);
                }
                c
            }
            Some("toml") => vec![
                vec!["simulate", "--scenario", &f, "--out", "{out}/sim"],
                vec![
                    "diagnose",
                    "--scenario",
                    &f,
                    "--recording",
                    &stair,
                    "--json",
                    "{out}/diagnosis.json",
                ],
                vec![
                    "montecarlo",
                    "--scenario",
                    &f,
                    "--runs",
                    "2",
                    "--methods",
                    "px4",
                    "--out",
                    "{out}/study",
                ],
            ],
            _ => continue,
        };
        for (k, command) in commands.iter().enumerate() {
            let out = dir.path().join(format!(
                "{}-{k}",
                input.file_name().unwrap().to_string_lossy()
            ));
            std::fs::create_dir(&out).unwrap();
            let o = out.display().to_string();
            let args: Vec<String> = command
                .iter()
                .map(|a| match *a {
                    // Export names a bare file: put it in the run's folder.
                    "p.params" | "a.param" | "m.h" | "m.rs" | "table.json" => format!("{o}/{a}"),
                    a => a.replace("{out}", &o),
                })
                .collect();
            let argv: Vec<&str> = args.iter().map(String::as_str).collect();
            let r = common::magstand(&argv);
            runs += 1;
            if r.ok {
                assert_finite_outputs(&args, &out);
            } else {
                refused += 1;
                assert!(
                    r.stderr.starts_with("error: ") && r.stderr.len() < 4000,
                    "{argv:?}: an error is one short message:\n{}",
                    r.stderr
                );
            }
        }
    }
    eprintln!("{refused} of {runs} runs refused");
    assert_eq!(
        snapshot(&folder),
        before,
        "an input in the bad-inputs folder changed"
    );
    // Most reproducers are refused; the valid bases and some commands on them succeed.
    assert!(
        runs > 60 && refused > runs / 2,
        "{refused} of {runs} runs refused"
    );
}
