//! Regression: a black-box test made magstand overwrite its own inputs, replace special files
//! and lose file modes: `montecarlo --json` naming the scenario, `montecarlo merge --json`
//! pointing into a shard (which destroyed it), a scenario named `SUMMARY.json` inside `--out`,
//! `simulate` of a replay whose recording was the `--out` recording, `report` of an input named
//! like one of its figures, `--out` naming a FIFO or `/dev/stdout`, a 0600 output that came
//! back 0644, and a `--sweep` value of `../../../x` that wrote a study outside `--out`. Each
//! is now refused before anything is written, with the paths named, and the input unchanged.
//! Silent misreads of the same run: a shard with a repeated (run, method) row was merged into
//! a wrong summary, `--json` was ignored with `--sweep`, and a wrong type in `--set` was
//! reported at a line of a TOML file the user never wrote.
mod common;

use std::path::{Path, PathBuf};

fn snapshot(paths: &[&Path]) -> Vec<(PathBuf, Vec<u8>)> {
    paths
        .iter()
        .map(|p| (p.to_path_buf(), std::fs::read(p).unwrap()))
        .collect()
}

/// Runs `args`, expects a refusal naming each of `said`, and the files in `keep` unchanged.
fn refused_keeping(args: &[&str], said: &[&str], keep: &[&Path]) {
    let before = snapshot(keep);
    let r = common::magstand(args);
    assert!(!r.ok, "{args:?} succeeded:\n{}", r.stdout);
    for s in said {
        assert!(
            r.stderr.contains(s),
            "{args:?}: expected {s:?} in:\n{}",
            r.stderr
        );
    }
    for (path, bytes) in before {
        assert_eq!(
            std::fs::read(&path).unwrap(),
            bytes,
            "{args:?} changed {}",
            path.display()
        );
    }
}

const QUICK: [&str; 6] = [
    "--set",
    "program.dwell_s=1.0",
    "--set",
    "stand.enabled=false",
    "--methods",
    "px4",
];

fn study_args<'a>(scenario: &'a str, out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "montecarlo",
        "--scenario",
        scenario,
        "--runs",
        "2",
        "--out",
        out,
    ];
    args.extend(QUICK);
    args.extend(extra);
    args
}

#[test]
fn montecarlo_never_writes_over_its_scenario_or_its_shards() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).display().to_string();
    common::simulate_quick_tables(&p("sim"));
    let scenario = p("sim/scenario.toml");
    // --json naming the scenario.
    refused_keeping(
        &study_args(&scenario, &p("study"), &["--json", &scenario]),
        &[&scenario, "input"],
        &[Path::new(&scenario)],
    );
    assert!(!Path::new(&p("study")).exists(), "nothing may be written");
    // A scenario named SUMMARY.json inside --out.
    std::fs::create_dir(p("inside")).unwrap();
    let inside = p("inside/SUMMARY.json");
    std::fs::copy(&scenario, &inside).unwrap();
    refused_keeping(
        &study_args(&inside, &p("inside"), &[]),
        &[&inside, "input"],
        &[Path::new(&inside)],
    );
    assert!(
        !Path::new(&p("inside/runs.csv")).exists(),
        "nothing may be written"
    );

    // merge --json pointing at a shard's own files.
    for k in ["1/2", "2/2"] {
        let shard = p(&format!("shard{}", &k[..1]));
        let r = common::magstand(&study_args(&scenario, &shard, &["--shard", k]));
        assert!(r.ok, "{}", r.stderr);
    }
    let (s1, s2) = (p("shard1"), p("shard2"));
    for target in ["runs.csv", "study.json"] {
        let json = format!("{s1}/{target}");
        refused_keeping(
            &[
                "montecarlo",
                "merge",
                &s1,
                &s2,
                "--out",
                &p("merged"),
                "--json",
                &json,
            ],
            &[&json, "input"],
            &[
                Path::new(&format!("{s1}/runs.csv")),
                Path::new(&format!("{s1}/study.json")),
            ],
        );
    }
    assert!(
        !Path::new(&p("merged/runs.csv")).exists(),
        "nothing may be written"
    );

    // A shard with a repeated (run, method) row, and one missing a row.
    let runs = std::fs::read_to_string(format!("{s1}/runs.csv")).unwrap();
    let lines: Vec<&str> = runs.lines().collect();
    assert!(lines.len() >= 2, "a header and a row: {runs}");
    let repeated = format!("{runs}{}\n", lines[1]);
    std::fs::write(format!("{s1}/runs.csv"), &repeated).unwrap();
    refused_keeping(
        &["montecarlo", "merge", &s1, &s2, "--out", &p("merged")],
        &["runs.csv", "repeats row 1"],
        &[],
    );
    let missing = format!("{}\n", lines[..lines.len() - 1].join("\n"));
    std::fs::write(format!("{s1}/runs.csv"), &missing).unwrap();
    refused_keeping(
        &["montecarlo", "merge", &s1, &s2, "--out", &p("merged")],
        &["runs.csv", "has no row for method `px4`"],
        &[],
    );
}

#[test]
fn a_sweep_stays_inside_out_and_says_what_it_does_not_do() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a/b/c/study");
    let o = out.display().to_string();
    // A value that looks like a path is a folder name inside --out, never a path elsewhere.
    let r = common::magstand(&study_args(
        "builtin:czyba2015-tables",
        &o,
        &["--sweep", "description=../../../x,y"],
    ));
    assert!(r.ok, "{}", r.stderr);
    let outside = dir.path().join("a/x");
    assert!(
        !outside.exists() && !dir.path().join("x").exists(),
        "wrote outside --out"
    );
    let mut folders: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    folders.sort();
    assert_eq!(folders, ["description=.._.._.._x", "description=y"]);
    // --json with --sweep is refused, not ignored.
    refused_keeping(
        &study_args(
            "builtin:czyba2015-tables",
            &dir.path().join("s2").display().to_string(),
            &["--sweep", "program.dwell_s=1,2", "--json", "summary.json"],
        ),
        &["--json", "--sweep"],
        &[],
    );
}

#[test]
fn simulate_and_report_never_write_over_what_they_read() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).display().to_string();
    common::simulate_quick_tables(&p("run"));
    // A replay of run/recording.csv written into run/.
    let scenario = p("replay.toml");
    std::fs::write(
        &scenario,
        "name = \"replay\"\n[program]\nkind = \"replay\"\nfile = \"run/recording.csv\"\n",
    )
    .unwrap();
    let recording = p("run/recording.csv");
    refused_keeping(
        &["simulate", "--scenario", &scenario, "--out", &p("run")],
        &["recording.csv", "input"],
        &[Path::new(&recording), Path::new(&p("run/scenario.toml"))],
    );
    // A report input named like one of the report's figures.
    let r = common::magstand(&["report", "--recording", &recording, "--out", &p("first")]);
    assert!(r.ok, "{}", r.stderr);
    let figure = std::fs::read_dir(p("first"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .find(|n| n.ends_with(".svg"))
        .expect("a report writes figures");
    std::fs::create_dir(p("report")).unwrap();
    let as_figure = p(&format!("report/{figure}"));
    std::fs::copy(&recording, &as_figure).unwrap();
    refused_keeping(
        &["report", "--recording", &as_figure, "--out", &p("report")],
        &[&figure, "input"],
        &[Path::new(&as_figure)],
    );
    assert!(
        !Path::new(&p("report/index.html")).exists(),
        "nothing may be written"
    );
}

#[test]
fn special_files_are_refused_and_modes_kept() {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).display().to_string();
    common::simulate_quick_tables(&p("run"));
    let recording = p("run/recording.csv");
    let model = p("model.json");
    let r = common::magstand(&["fit", "--recording", &recording, "--model-out", &model]);
    assert!(r.ok, "{}", r.stderr);
    let fifo = p("fifo");
    let c = std::ffi::CString::new(fifo.as_str()).unwrap();
    // SAFETY: mkfifo on a path in a fresh temporary folder.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    for target in [fifo.as_str(), "/dev/null", "/dev/stdout"] {
        refused_keeping(
            &[
                "compensate",
                "--model",
                &model,
                "--recording",
                &recording,
                "--out",
                target,
            ],
            &[target, "regular files"],
            &[Path::new(&recording), Path::new(&model)],
        );
    }
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo(),
        "the FIFO was replaced"
    );
    // A 0600 output stays 0600 when replaced.
    std::fs::set_permissions(&model, std::fs::Permissions::from_mode(0o600)).unwrap();
    let r = common::magstand(&["fit", "--recording", &recording, "--model-out", &model]);
    assert!(r.ok, "{}", r.stderr);
    let mode = std::fs::metadata(&model).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "mode {mode:o}");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_wrong_type_in_set_names_the_override() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run").display().to_string();
    refused_keeping(
        &[
            "simulate",
            "--scenario",
            "builtin:czyba2015-stair",
            "--set",
            "program.dwell_s=abc",
            "--out",
            &out,
        ],
        &["program.dwell_s=abc", "expected f64"],
        &[],
    );
    assert!(!Path::new(&out).exists());
}

/// SIGTERM reaches magstand's handler (exit 130 rather than death by signal), which removes
/// the temporaries being written; `interrupted_write.rs` in magstand-core checks the removal.
#[test]
fn sigterm_ends_the_run_through_the_cleanup_handler() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_magstand"))
        .args([
            "montecarlo",
            "--scenario",
            "builtin:czyba2015-stair",
            "--runs",
            "500",
        ])
        .args(["--out", out.to_str().unwrap(), "--methods", "px4"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    // SAFETY: sends SIGTERM to the child this test started.
    assert_eq!(
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) },
        0
    );
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
