//! Running the built `magstand` binary from the integration tests.
use std::process::Command;

/// What a run of `magstand` gave.
pub struct Run {
    /// Exit status was success.
    pub ok: bool,
    /// Standard output.
    #[allow(dead_code)] // not every test file reads it
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

/// Runs `magstand` with `args`; fails the test on a panic message, whatever the exit status.
pub fn magstand(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_magstand"))
        .args(args)
        .output()
        .expect("runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    Run {
        ok: out.status.success(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr,
    }
}
