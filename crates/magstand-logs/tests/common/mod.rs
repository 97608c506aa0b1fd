//! What the integration tests of magstand-logs share.
// Each test binary uses part of this module.
#![allow(dead_code)]
use std::path::{Path, PathBuf};
use std::process::Command;

use magstand_core::Vec3;
use magstand_core::rbf::paper_tables;
use magstand_ident::noise_model::SdModel;
use magstand_ident::{InputKind, InputSpec, LocalLinearNet, Model, Structure};

/// The path of a public log in the repository's tests/data/real-logs (provenance in its
/// README).
pub fn real_log(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/real-logs")
        .join(name)
}

/// The overall throttle of four motors, 0..1, off at 0.
pub fn throttle_input() -> InputSpec {
    InputSpec {
        kind: InputKind::Throttle,
        lo: 0.0,
        hi: 1.0,
        motors: 4,
        off_raw: 0.0,
    }
}

/// The paper's Tables I-III as a throttle model (µT), with its motors-off field and the noise
/// model `sd`.
pub fn paper_model(sd: Option<SdModel>) -> Model {
    let t = paper_tables();
    let net = LocalLinearNet {
        partition: t[0].partition().clone(),
        coefficients: std::array::from_fn(|a| {
            (0..3)
                .map(|i| vec![100.0 * t[a].slopes()[i], 100.0 * t[a].intercepts()[i]])
                .collect()
        }),
    };
    Model::new(
        "global",
        throttle_input(),
        Vec3::new(20.0, 1.0, 45.0),
        Structure::LocalLinear(net),
        sd,
    )
}

/// Runs `cmd`, asserting that it succeeds, and returns what it printed.
pub fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The system's C compiler; `None` (a skipped test) only outside CI.
pub fn c_compiler() -> Option<&'static str> {
    let cc = ["cc", "gcc", "clang"]
        .into_iter()
        .find(|c| Command::new(c).arg("--version").output().is_ok());
    if cc.is_none() {
        assert!(std::env::var("CI").is_err(), "CI=true but no C compiler");
        eprintln!("no C compiler: skipping");
    }
    cc
}

/// Compiles `main_c` (C99, every warning an error) in `dir` beside the headers written there,
/// runs it and returns what it printed.
pub fn run_c(cc: &str, dir: &Path, main_c: &str) -> String {
    std::fs::write(dir.join("main.c"), main_c).unwrap();
    let exe = dir.join("eval");
    run_ok(
        Command::new(cc)
            .args(["-std=c99", "-Wall", "-Werror", "-O2", "-o"])
            .arg(&exe)
            .arg(dir.join("main.c"))
            .arg("-lm"),
    );
    run_ok(&mut Command::new(&exe))
}

/// Builds the exported module `module` (file `{name}.rs`) as part of a `no_std` library with
/// every warning an error, then runs `main_rs` (which declares `mod {name};`) on the host and
/// returns what it printed.
pub fn run_no_std_rust(dir: &Path, name: &str, module: &str, main_rs: &str) -> String {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    std::fs::write(dir.join(format!("{name}.rs")), module).unwrap();
    std::fs::write(
        dir.join("lib.rs"),
        format!("#![no_std]\n#![deny(warnings, missing_docs)]\n//! Firmware.\npub mod {name};\n"),
    )
    .unwrap();
    run_ok(
        Command::new(&rustc)
            .args([
                "--edition",
                "2021",
                "--crate-type",
                "rlib",
                "--crate-name",
                "fw",
                "-O",
            ])
            .arg("--out-dir")
            .arg(dir)
            .arg(dir.join("lib.rs")),
    );
    std::fs::write(dir.join("main.rs"), main_rs).unwrap();
    let exe = dir.join("eval");
    run_ok(
        Command::new(&rustc)
            .args(["--edition", "2021", "-O", "-o"])
            .arg(&exe)
            .arg(dir.join("main.rs")),
    );
    run_ok(&mut Command::new(&exe))
}
