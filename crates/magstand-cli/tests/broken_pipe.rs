//! Regression: `magstand fit ... | head -1` panicked with "failed printing to stdout: Broken
//! pipe" (exit 101, a backtrace on stderr) once the reader had gone, because Rust ignores
//! SIGPIPE and `println!` panics on the write error. The binary now restores the default
//! disposition and ends quietly, as `cat` does, after writing its output files.
#![cfg(unix)]
mod common;
use common::{magstand, simulate_quick_tables};
use std::process::{Command, Stdio};

#[test]
fn a_closed_stdout_ends_the_run_without_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    simulate_quick_tables(&p("sim"));

    let mut child = Command::new(env!("CARGO_BIN_EXE_magstand"))
        .args([
            "fit",
            "--recording",
            &p("sim/recording.csv"),
            "--model-out",
            &p("m.json"),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The reader goes away before the fit has printed anything.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !stderr.contains("panicked") && out.status.code() != Some(101),
        "status {:?}, stderr: {stderr}",
        out.status
    );
    // The model was written whole before the summary was printed.
    let r = magstand(&["export", "--model", &p("m.json"), "--to", "px4"]);
    assert!(r.ok, "{}", r.stderr);
}
