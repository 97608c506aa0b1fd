//! Regression: a real PX4 1.14 octocopter log whose battery_status.current_a is 0.0 in every
//! sample (the current channel was not measured; the voltage is valid) was imported with a
//! `bat_a` column of zeros, and `fit --inputs current` would have fitted a disturbance against
//! a constant. A supply channel that reads zero throughout is now left out with a note, so a
//! current fit says the current is missing and the throttle is the input left.

use magstand_logs::import::{ImportOptions, import_file};

mod common;
use common::real_log as log;

#[test]
fn a_current_of_zero_throughout_is_not_measured() {
    let (rec, report) = import_file(
        &log("px4-cubeorange-octo-x8-fsyr-log61-no-current.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    assert!(rec.bat_a.is_none(), "{text}");
    assert!(text.contains("current is 0 throughout"), "{text}");
    // The voltage is real (6S, 22-24 V) and stays.
    let v = rec.bat_v.as_ref().expect("bat_v");
    assert!(v.iter().all(|v| (21.0..25.5).contains(v)), "{text}");
    assert_eq!(rec.motor_count(), 8, "{text}");
}

#[test]
fn the_same_vehicle_with_its_current_measured_keeps_it() {
    let (rec, report) = import_file(
        &log("px4-cubeorange-octo-x8-fsyr-log123.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    let a = rec.bat_a.as_ref().expect("bat_a");
    // 0.5 to 70 A over the flight.
    let top = a.iter().copied().fold(0.0, f64::max);
    assert!((40.0..80.0).contains(&top), "top {top} A\n{text}");
    assert!(!text.contains("0 throughout"), "{text}");
}
