//! Regression: ArduPilot's `ESC` instances were read as the motors' numbers (instance 0 for
//! motor 1), but an ESC instance is the servo output channel its ESC drives, counted from 0
//! (`AP_ESC_Telem` holds one per servo channel, and `AP_BLHeli` reports each through its
//! channel's index). On a vehicle whose motors are not on outputs 1 to N (here outputs 3 to 6,
//! `SERVO3_FUNCTION` = 33 ..), the import wrote the currents of other outputs' ESCs as the
//! motors'. Each motor's current now comes from its own channel's ESC.
use std::path::Path;

use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::DataflashBuilder;

#[test]
fn each_motor_takes_the_esc_of_its_own_output_channel() {
    const MAG: u8 = 0x82;
    const RCOU: u8 = 0x83;
    const ESC: u8 = 0x84;
    let mut b = DataflashBuilder::new();
    b.format(MAG, "MAG", "QBfff", "TimeUS,I,MagX,MagY,MagZ")
        .format(RCOU, "RCOU", "QHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6")
        .format(ESC, "ESC", "QBf", "TimeUS,Instance,Curr");
    for (name, value) in [
        ("MOT_PWM_MIN", 1000.0),
        ("MOT_PWM_MAX", 2000.0),
        ("COMPASS_EXTERNAL", 0.0),
        ("SERVO1_FUNCTION", 0.0),
        ("SERVO2_FUNCTION", 0.0),
        ("SERVO3_FUNCTION", 33.0),
        ("SERVO4_FUNCTION", 34.0),
        ("SERVO5_FUNCTION", 35.0),
        ("SERVO6_FUNCTION", 36.0),
    ] {
        b.param(0, name, value);
    }
    for r in 0..200 {
        let us = 1e6 + r as f64 * 2e4;
        let pwm = 1100.0 + (r % 50) as f64 * 10.0;
        b.row(MAG, &[us, 0.0, 200.0 + r as f64, -50.0, 400.0]);
        // Outputs 1 and 2 drive no motor (a gimbal at its centre).
        b.row(
            RCOU,
            &[us, 1500.0, 1500.0, pwm, pwm + 1.0, pwm + 2.0, pwm + 3.0],
        );
        // ESC instance i reads i + 1 amperes: the motors' ESCs are 2 to 5.
        for i in 0..6 {
            b.row(ESC, &[us, i as f64, i as f64 + 1.0]);
        }
    }
    let (rec, report) = import_bytes(
        &b.into_bytes(),
        Path::new("outputs-3-to-6.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert_eq!(rec.motor_count(), 4, "{:?}", report.notes);
    for (motor, amperes) in [(1, 3.0), (2, 4.0), (3, 5.0), (4, 6.0)] {
        let column = rec
            .extra_column(&format!("esc_{motor}_a"))
            .unwrap_or_else(|| panic!("no esc_{motor}_a: {:?}", report.notes));
        assert!(
            column.iter().all(|a| a.parse::<f64>() == Ok(amperes)),
            "motor {motor} (output {}): {:?} A, expected {amperes} A",
            motor + 2,
            &column[..3]
        );
    }
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains("ESC instances [2, 3, 4, 5]")),
        "{:?}",
        report.notes
    );
}
