//! Regression: ArduPilot marks each `MAG` sample of a compass it does not trust (`Health` 0:
//! a stale reading, or one failing its consistency checks), and the import read those samples
//! as the field. They are now left out, with a note that counts them.
use std::path::Path;

use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::DataflashBuilder;

#[test]
fn samples_marked_unhealthy_are_left_out() {
    const MAG: u8 = 0x82;
    const RCOU: u8 = 0x83;
    let mut b = DataflashBuilder::new();
    b.format(MAG, "MAG", "QBfffB", "TimeUS,I,MagX,MagY,MagZ,Health")
        .format(RCOU, "RCOU", "QHHHH", "TimeUS,C1,C2,C3,C4");
    for (name, value) in [
        ("MOT_PWM_MIN", 1000.0),
        ("MOT_PWM_MAX", 2000.0),
        ("COMPASS_EXTERNAL", 0.0),
    ] {
        b.param(0, name, value);
    }
    b.param(0, "SERVO1_FUNCTION", 33.0)
        .param(0, "SERVO2_FUNCTION", 34.0)
        .param(0, "SERVO3_FUNCTION", 35.0)
        .param(0, "SERVO4_FUNCTION", 36.0);
    for r in 0..100 {
        let us = 1e6 + r as f64 * 2e4;
        let pwm = 1100.0 + (r % 20) as f64 * 20.0;
        // Every tenth sample is stale: the firmware repeats a reading far from the others.
        let (field, health) = if r % 10 == 5 {
            (9999.0, 0.0)
        } else {
            (200.0, 1.0)
        };
        b.row(MAG, &[us, 0.0, field, -50.0, 400.0, health]);
        b.row(RCOU, &[us, pwm, pwm, pwm, pwm]);
    }
    let (rec, report) = import_bytes(
        &b.into_bytes(),
        Path::new("stale.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert_eq!(rec.len(), 90, "{:?}", report.notes);
    assert!(
        rec.mag_ut.iter().all(|m| (m.x - 20.0).abs() < 1e-9),
        "an unhealthy sample was read"
    );
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains("10 of 100 samples") && n.contains("unhealthy")),
        "{:?}",
        report.notes
    );
}
