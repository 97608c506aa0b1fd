//! Real flight logs as they are and with a known effect added (the fast subset of
//! `cargo run --release -p magstand-tests --bin semireal-suite`, results/diagnosis-semireal.md):
//! ArduPilot log171 is diagnosed on its flight baseline (Earth field turned by the attitude,
//! offset, delay), and a copy with the magnetometer stream 0.3 s late moves the calibrated
//! delay by that amount. (That the copies differ from the log in nothing else is the suite's
//! judgement, not yet met: see the results file.)
use magstand_tests::semireal::{Injection, diagnose_unstated, import, logs};

#[test]
fn a_late_magnetometer_on_a_real_flight_moves_the_calibrated_delay_by_its_amount() {
    let log = &logs()[0];
    assert!(log.file.contains("log171"), "{}", log.file);
    let rec = import(log).unwrap();
    let original = diagnose_unstated(&rec, log.file).unwrap();
    assert!(
        original
            .baseline
            .calibration
            .iter()
            .any(|p| p.name == "flight.mag_delay_s"),
        "no flight baseline: {:?}",
        original.baseline.calibration
    );
    assert!(!original.verdict.iter().any(|n| n == "time_offset"));
    let late = Injection::MagLate { delay_s: 0.3 };
    let copy = diagnose_unstated(&late.apply(&rec), log.file).unwrap();
    let delay = |d: &magstand_diagnose::Diagnosis| {
        d.baseline
            .calibration
            .iter()
            .find(|p| p.name == "flight.mag_delay_s")
            .map(|p| p.value)
            .unwrap()
    };
    let moved = delay(&copy) - delay(&original);
    // Half of the log's 0.1 s sample interval is the delay's resolution.
    assert!(
        (moved - 0.3).abs() <= 0.05,
        "the delay moved by {moved} s (injected 0.3 s)"
    );
    assert!(!copy.verdict.iter().any(|n| n == "time_offset"));
}
