//! Regression: a Copter 3.4 log (no `FRAME_CLASS`, no `SERVOn_FUNCTION`, 14 RCOU channels)
//! would not import without `--motors 4`, although the log shows its motor count twice: the
//! firmware writes "Frame: QUAD" at boot, and the channels that drive motors move together in
//! the motor PWM range while the others sit still or move on their own. The import now reads
//! the count from the frame message, or else from the outputs, and says which it used.
use std::path::Path;

use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::DataflashBuilder;

/// A Copter 3.4-style log: `motors` motor channels on C1.., a gimbal on the next channel
/// moving on its own, the rest of 14 channels fixed; `frame` the boot message, if any.
fn copter34(motors: usize, frame: Option<&str>, spinning: bool) -> Vec<u8> {
    let mut b = DataflashBuilder::new();
    let labels: Vec<String> = (1..=14).map(|c| format!("C{c}")).collect();
    b.format(0x81, "MAG", "Qhhh", "TimeUS,MagX,MagY,MagZ")
        .format(
            0x82,
            "RCOU",
            &format!("Q{}", "H".repeat(14)),
            &format!("TimeUS,{}", labels.join(",")),
        )
        .format(0x83, "CURR", "Qfff", "TimeUS,Volt,Curr,CurrTot");
    b.text(0, "APM:Copter V3.4.6 (a0a3e4d2)");
    if let Some(f) = frame {
        b.text(0, &format!("Frame: {f}"));
    }
    for (name, v) in [("FRAME", 1.0), ("RC3_MIN", 1000.0), ("RC3_MAX", 2000.0)] {
        b.param(0, name, v);
    }
    for k in 0..400 {
        let t = 0.1 * k as f64;
        let us = t * 1e6;
        let collective = if spinning {
            1450.0 + 150.0 * (0.3 * t).sin()
        } else {
            1000.0
        };
        let mut row = vec![us];
        for m in 0..14 {
            row.push(if m < motors {
                // Differential thrust on top of the collective, different per motor.
                collective + 40.0 * (1.7 * t + m as f64).sin()
            } else if m == motors {
                1500.0 + 300.0 * (0.05 * t + 2.0).cos()
            } else if m < 8 {
                1500.0
            } else {
                0.0
            });
        }
        b.row(0x81, &[us, 200.0, -40.0, 410.0])
            .row(0x82, &row)
            .row(0x83, &[us, 15.8, 3.0 + collective / 100.0, 0.0]);
    }
    b.into_bytes()
}

fn count(bytes: &[u8]) -> (usize, String) {
    let (rec, report) = import_bytes(bytes, Path::new("copter34.bin"), &ImportOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    (rec.motor_count(), report.notes.join("\n"))
}

#[test]
fn the_frame_message_gives_the_motor_count() {
    let (n, notes) = count(&copter34(4, Some("QUAD"), true));
    assert!(n == 4 && notes.contains("\"Frame: QUAD\""), "{n}: {notes}");
    let (n, notes) = count(&copter34(6, Some("HEXA/X"), true));
    assert!(n == 6 && notes.contains("HEXA/X"), "{n}: {notes}");
}

#[test]
fn without_a_frame_message_the_outputs_show_the_motor_count() {
    for motors in [4, 6, 8] {
        let (n, notes) = count(&copter34(motors, None, true));
        assert!(
            n == motors && notes.contains("move together"),
            "{motors} motors read as {n}: {notes}"
        );
    }
}

#[test]
fn outputs_that_never_spin_are_an_error_asking_for_the_count() {
    let e = import_bytes(
        &copter34(4, None, false),
        Path::new("disarmed.bin"),
        &ImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("disarmed.bin") && e.contains("motor count") && e.contains("`motors`"),
        "{e}"
    );
}
