//! The five public logs of tests/data/real-logs (provenance in its README): each imports with
//! the documented choices, or fails with a message that names what is wrong.

use magstand_logs::import::{ImportOptions, SegmentKind, import_file};

mod common;
use common::real_log as log;

fn max(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::MIN, f64::max)
}

#[test]
fn ardupilot_quad_with_three_compasses() {
    let (rec, report) =
        import_file(&log("ardupilot-log171-quad.bin"), &ImportOptions::default()).unwrap();
    let text = report.summary(&rec);
    assert_eq!(rec.motor_count(), 4, "{text}");
    assert!(report.damage.is_none(), "{text}");
    // COMPASS_EXTERNAL = 1, COMPASS_EXTERN2 = 0: the default is MAG2, the internal one.
    assert!(report.notes[0].contains("instance 1 (internal)"), "{text}");
    assert!(
        report.notes.iter().any(|n| n.contains("RC3_MIN/MAX")),
        "{text}"
    );
    // Copter 3.3 (no per-motor compensation) adds its compensation before compass 2's
    // soft-iron matrix, which is the frame its parameters are written in.
    assert!(
        report.notes[1].contains("before compass 2's soft-iron matrix"),
        "{text}"
    );
    assert!((2300..=2400).contains(&rec.len()), "{text}");
    // 4S pack: 13..17 V; flight current 12..30 A.
    let v = rec.bat_v.as_ref().unwrap();
    assert!(v.iter().all(|v| (13.0..17.5).contains(v)), "{text}");
    assert!(
        (12.0..35.0).contains(&max(rec.bat_a.as_ref().unwrap())),
        "{text}"
    );
    let ground = report
        .segments
        .iter()
        .find(|s| s.kind == SegmentKind::Ground)
        .expect("the spin-up on the ground");
    assert!(ground.span_s.0 > 70.0 && ground.span_s.1 < 90.0, "{text}");
    assert!(
        report
            .segments
            .iter()
            .any(|s| s.kind == SegmentKind::Flight),
        "{text}"
    );
    let p = report.position.unwrap();
    assert!(
        (p.lat_deg + 35.36).abs() < 0.05 && (p.lon_deg - 149.17).abs() < 0.05,
        "{p:?}"
    );
    assert!(rec.attitude.is_some());
    // The external compass on request.
    let opts = ImportOptions {
        mag: Some(0),
        ..ImportOptions::default()
    };
    let (ext, report) = import_file(&log("ardupilot-log171-quad.bin"), &opts).unwrap();
    assert!(
        report.notes[0].contains("instance 0 (external)"),
        "{:?}",
        report.notes
    );
    assert_ne!(ext.mag_ut[100], rec.mag_ut[100]);
}

#[test]
fn px4_logs_pick_the_internal_compass_and_the_motor_outputs() {
    let (rec, report) = import_file(
        &log("px4-fmuv5-hexa-sample-small.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert_eq!(rec.motor_count(), 6, "{}", report.summary(&rec));
    assert!(
        (40.0..100.0).contains(&max(rec.bat_a.as_ref().unwrap())),
        "{}",
        report.summary(&rec)
    );

    let (rec, report) =
        import_file(&log("px4-fmuv6c-quad-local.ulg"), &ImportOptions::default()).unwrap();
    assert_eq!(rec.motor_count(), 4);
    assert!(
        report.notes[0].contains("sensor_mag[1]"),
        "{:?}",
        report.notes
    );
    // Its internal sensor is disabled (CAL_MAG1_PRIO = 0): the vehicle flies on sensor_mag[0],
    // and a compensation for the internal one would change nothing. The import says so.
    assert!(
        report.notes.iter().any(|n| n.contains("CAL_MAG1_PRIO = 0")
            && n.contains("disabled")
            && n.contains("instance(s) 0")),
        "{:?}",
        report.notes
    );
    assert!(
        report
            .segments
            .iter()
            .any(|s| s.kind == SegmentKind::Flight)
    );
    // The field is calibrated and in the body frame: roughly the Earth's 25..65 µT.
    let n = rec.mag_ut[0].norm();
    assert!((15.0..80.0).contains(&n), "{n}");

    let (rec, report) = import_file(
        &log("px4-fmuv3-uavcan-esc-status.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert!(
        report.notes[0].contains("vehicle_magnetometer"),
        "{:?}",
        report.notes
    );
    assert!(
        report.notes[1].contains("UAVCAN raw 0..8191"),
        "{:?}",
        report.notes
    );
    assert!(
        !report.gaps_s.is_empty(),
        "its 3 Hz stream has gaps of over a second"
    );
    assert!(max(&rec.thr[0]) > 0.3);
    // Its per-ESC currents (esc_status, 3.2 Hz, about 5-9 A each in the first messages).
    let esc: Vec<Vec<f64>> = (1..=4)
        .map(|i| {
            let name = format!("esc_{i}_a");
            let (_, cells) = rec
                .extra
                .iter()
                .find(|(n, _)| *n == name)
                .unwrap_or_else(|| panic!("no {name} in {:?}", report.notes));
            cells.iter().map(|c| c.parse().unwrap()).collect()
        })
        .collect();
    for (i, e) in esc.iter().enumerate() {
        assert_eq!(e.len(), rec.len());
        assert!(
            e.iter().all(|a| (0.0..100.0).contains(a)) && max(e) > 3.0,
            "ESC {i}: {:?}",
            &e[..10]
        );
    }
    assert!(
        report.notes.iter().any(|n| n.contains("esc_status")),
        "{:?}",
        report.notes
    );
}

#[test]
fn bad_requests_and_the_corrupt_log_are_clear_errors() {
    let e = import_file(
        &log("px4-corrupt-actuator-armed-wrong-size.ulg"),
        &ImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("px4-corrupt") && e.contains("damaged") && e.contains("wrong size"),
        "{e}"
    );
    let opts = ImportOptions {
        mag: Some(5),
        ..ImportOptions::default()
    };
    let e = import_file(&log("px4-fmuv6c-quad-local.ulg"), &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`mag` = 5") && e.contains("0, 1"), "{e}");
    let opts = ImportOptions {
        pwm_range: Some((2000.0, 1000.0)),
        ..ImportOptions::default()
    };
    let e = import_file(&log("ardupilot-log171-quad.bin"), &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`pwm_range`"), "{e}");
    let e = import_file(&log("README.md"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("README.md") && e.contains("neither"), "{e}");
}

/// Regression: `outputs`, which names a PX4 `actuator_outputs` instance, was ignored without a
/// word on a DataFlash log, whose motors are its RCOU channels; it is refused by name.
#[test]
fn a_px4_outputs_instance_is_refused_for_a_dataflash_log() {
    let opts = ImportOptions {
        outputs: Some(0),
        ..ImportOptions::default()
    };
    let e = import_file(&log("ardupilot-log171-quad.bin"), &opts)
        .expect_err("a PX4 option on a DataFlash log")
        .to_string();
    assert!(
        e.contains("ardupilot-log171-quad.bin")
            && e.contains("`outputs` = 0")
            && e.contains("RCOU"),
        "{e}"
    );
}

/// log171's third compass is not used for heading (`COMPASS_USE3` = 0): a compensation for it
/// would change nothing the vehicle flies on, and the import says so; its second (the default)
/// is used, and nothing is said.
#[test]
fn a_compass_the_firmware_does_not_use_is_said() {
    let note = |mag: u8| {
        let opts = ImportOptions {
            mag: Some(mag),
            ..ImportOptions::default()
        };
        let (_, report) = import_file(&log("ardupilot-log171-quad.bin"), &opts).unwrap();
        report
            .notes
            .into_iter()
            .find(|n| n.contains("not used for heading"))
    };
    let third = note(2).expect("compass 3 is not used");
    assert!(third.contains("COMPASS_USE3 = 0"), "{third}");
    assert_eq!(note(1), None);
}

/// The doubts `fit`, `diagnose`, `compensate` and `report` warn of (units, unread columns, a
/// supply that drops out) are about glitches: every real log that imports reads without one.
/// (A supply that sags in flight, a current at idle and a fast turn are a vehicle's own.)
#[test]
fn imported_real_logs_raise_no_doubt() {
    let dir = log("");
    let mut read = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let is_log = matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("ulg" | "bin")
        );
        if !is_log {
            continue;
        }
        let Ok((rec, _)) = import_file(&path, &ImportOptions::default()) else {
            continue;
        };
        read += 1;
        let doubts = rec.doubts();
        assert!(doubts.is_empty(), "{}: {doubts:?}", path.display());
    }
    assert!(
        read >= 7,
        "only {read} real logs imported from {}",
        dir.display()
    );
}
