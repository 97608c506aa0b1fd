//! Regression: `magstand fit --earth wmm --lon -71.3` was refused by the argument parser
//! ("unexpected argument '-7'"), so a user west of Greenwich or south of the equator had to
//! write `--lon=-71.3`. Every subcommand now takes negative numbers as values.
mod common;

#[test]
fn negative_longitude_and_latitude_are_values_not_flags() {
    let r = common::magstand(&[
        "fit",
        "--recording",
        "no-such-recording.csv",
        "--model-out",
        "never-written.toml",
        "--earth",
        "wmm",
        "--lat",
        "-33.9",
        "--lon",
        "-71.3",
        "--year",
        "2025",
    ]);
    // The parser accepted the arguments: what fails is the missing file, named.
    assert!(
        !r.ok && r.stderr.contains("no-such-recording.csv") && !r.stderr.contains("unexpected"),
        "{}",
        r.stderr
    );
    assert!(!std::path::Path::new("never-written.toml").exists());
}
