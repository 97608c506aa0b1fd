//! Regression: a 10 Hz ArduPilot log holding two flights 628 s apart was reported as a
//! "1.0 Hz" log, because the rate was the mean interval over the whole span, gap included.
//! `fit` then warned that rows were 0.97 s apart, and `diagnose` replayed the gap in 0.01 s
//! substeps. The rate is now the median interval, and the gap is reported as a gap that ends a
//! segment. A magnetometer sample stamped exactly on the last motor sample before the gap was
//! dropped as well; it is kept.
use std::path::Path;

use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::DataflashBuilder;

#[test]
fn two_flights_far_apart_are_a_10_hz_log_with_one_gap() {
    let mut b = DataflashBuilder::new();
    b.format(0x81, "MAG", "QBhhh", "TimeUS,I,MagX,MagY,MagZ")
        .format(0x82, "RCOU", "QHHHH", "TimeUS,C1,C2,C3,C4")
        .format(0x83, "BAT", "QBff", "TimeUS,Inst,Volt,Curr");
    for (name, v) in [
        ("MOT_PWM_MIN", 1000.0),
        ("MOT_PWM_MAX", 2000.0),
        ("FRAME_CLASS", 1.0),
    ] {
        b.param(0, name, v);
    }
    let flight = |b: &mut DataflashBuilder, start_s: f64| {
        for k in 0..600 {
            let us = (start_s + 0.1 * k as f64) * 1e6;
            let pwm = 1300.0 + (k % 50) as f64 * 6.0;
            b.row(0x81, &[us, 0.0, 200.0, -40.0, 410.0])
                .row(0x82, &[us, pwm, pwm, pwm, pwm])
                .row(0x83, &[us, 0.0, 15.8, 12.0]);
        }
    };
    flight(&mut b, 10.0);
    flight(&mut b, 10.0 + 60.0 + 628.0);
    let (rec, report) = import_bytes(
        &b.into_bytes(),
        Path::new("two-flights.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    assert_eq!(rec.len(), 1200, "{text}");
    assert!(
        (rec.typical_interval_s() - 0.1).abs() < 1e-6,
        "{}",
        rec.typical_interval_s()
    );
    assert!(text.contains("(10.0 Hz magnetometer)"), "{text}");
    assert_eq!(report.gaps_s.len(), 1, "{text}");
    let (a, b) = report.gaps_s[0];
    assert!((b - a - 628.1).abs() < 0.01, "{text}");
    // Each flight is its own segment.
    assert_eq!(report.segments.len(), 2, "{text}");
    assert!(report.segments.iter().all(|s| s.rows == 600), "{text}");
}
