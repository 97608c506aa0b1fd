//! Regression: the import's summary printed a position west of Greenwich as a negative east
//! longitude (`41.90101 N -87.70563 E` for the FMU-V6XRT log flown near Chicago), which reads
//! as a typo and, copied by hand into a scenario's `earth` section, invites a sign slip. Each
//! coordinate is now its size with its hemisphere's letter.

use magstand_logs::import::{ImportOptions, import_file};

mod common;
use common::real_log as log;

#[test]
fn a_western_longitude_is_printed_with_its_hemisphere() {
    let (rec, report) = import_file(
        &log("px4-fmuv6xrt-quad-msgid-bitflip.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    let line = text
        .lines()
        .find(|l| l.starts_with("position:"))
        .unwrap_or_else(|| panic!("no position line in\n{text}"));
    let p = report
        .position
        .as_ref()
        .expect("the log has a GPS position");
    assert!(p.lon_deg < 0.0 && p.lat_deg > 0.0, "{p:?}");
    let expected = format!("position: {:.5} N {:.5} W,", p.lat_deg, -p.lon_deg);
    assert!(
        line.starts_with(&expected),
        "{line:?}, expected {expected:?}"
    );
    assert!(!line.contains('-'), "{line:?}");
}

#[test]
fn an_eastern_longitude_keeps_its_letter() {
    let (rec, report) = import_file(
        &log("px4-cubeorange-octo-x8-fsyr-log123.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    let line = text.lines().find(|l| l.starts_with("position:"));
    assert!(
        line.is_some_and(|l| l.starts_with("position: 22.88519 N 113.84668 E,")),
        "{text}"
    );
}
