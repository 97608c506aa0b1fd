//! A simulated run written as ULog and DataFlash and imported again gives back the recording:
//! the writers and the importers agree on topics, units, PWM mapping, attitude and segments.
use std::path::Path;

use magstand_core::Recording;
use magstand_logs::import::{ImportOptions, SegmentKind, import_bytes};
use magstand_logs::log_writer::{LogWriteOptions, dataflash_bytes, ulog_bytes};
use magstand_sim::{Scenario, simulate};

fn run() -> Recording {
    let text = r#"
        name = "short stair, turning"
        [program]
        kind = "stair"
        off_s = 1.0
        steps = 4
        dwell_s = 1.0
        [motion]
        yaw_rate_dps = 20.0
        tilt_deg = 10.0
        [logging]
        record_attitude = true
        record_temp = true
    "#;
    let s = Scenario::from_toml_str(text, "inline")
        .unwrap()
        .check("inline", None)
        .unwrap();
    simulate(&s, 3)
}

fn compare(orig: &Recording, back: &Recording, thr_tol: f64, label: &str) {
    assert_eq!(back.len(), orig.len(), "{label}: rows");
    assert_eq!(back.motor_count(), orig.motor_count(), "{label}: motors");
    for r in 0..orig.len() {
        assert!(
            (back.t_s[r] - orig.t_s[r]).abs() < 1e-6,
            "{label} row {r}: t"
        );
        for m in 0..orig.motor_count() {
            let (a, b) = (orig.thr[m][r], back.thr[m][r]);
            assert!(
                (a - b).abs() <= thr_tol,
                "{label} row {r} motor {m}: {a} vs {b}"
            );
        }
        let d = (back.mag_ut[r] - orig.mag_ut[r]).norm();
        assert!(
            d < 1e-3 * orig.mag_ut[r].norm().max(1.0),
            "{label} row {r}: mag {d}"
        );
        let qa = orig.attitude.as_ref().unwrap()[r];
        let qb = back.attitude.as_ref().unwrap()[r];
        assert!(
            qa.angle_to(&qb) < 1e-5,
            "{label} row {r}: attitude {}",
            qa.angle_to(&qb)
        );
        let (va, vb) = (
            orig.bat_a.as_ref().unwrap()[r],
            back.bat_a.as_ref().unwrap()[r],
        );
        assert!(
            (va - vb).abs() < 1e-4 * va.max(1.0),
            "{label} row {r}: current {va} vs {vb}"
        );
    }
}

#[test]
fn ulog_and_dataflash_round_trip() {
    let rec = run();
    let opts = LogWriteOptions {
        landed: false,
        ..LogWriteOptions::default()
    };
    let (back, report) = import_bytes(
        &ulog_bytes(&rec, &opts),
        Path::new("sim.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert!(report.damage.is_none(), "{report:?}");
    compare(&rec, &back, 1e-6, "ULog");
    let temp = back
        .temp_c
        .as_ref()
        .expect("sensor_mag temperature becomes temp_c");
    assert!((temp[5] - rec.temp_c.as_ref().unwrap()[5]).abs() < 1e-4);
    // Armed throughout and flying: off while the motors stand still before and after the stair.
    let kinds: Vec<SegmentKind> = report.segments.iter().map(|s| s.kind).collect();
    assert_eq!(
        kinds,
        [SegmentKind::Off, SegmentKind::Flight, SegmentKind::Off],
        "{report:?}"
    );

    // DataFlash carries PWM in whole microseconds over 1000..2000: 1e-3 of a command.
    let (back, report) = import_bytes(
        &dataflash_bytes(&rec, &opts),
        Path::new("sim.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    assert!(report.damage.is_none(), "{report:?}");
    compare(&rec, &back, 5e-4 + 1e-9, "DataFlash");
    let kinds: Vec<SegmentKind> = report.segments.iter().map(|s| s.kind).collect();
    assert_eq!(
        kinds,
        [SegmentKind::Off, SegmentKind::Flight, SegmentKind::Off],
        "{report:?}"
    );
}

#[test]
fn a_landed_stand_is_a_ground_segment_and_selection_keeps_it() {
    let rec = run();
    let bytes = ulog_bytes(&rec, &LogWriteOptions::default());
    let opts = ImportOptions {
        segment: Some(SegmentKind::Ground),
        ..ImportOptions::default()
    };
    let (back, report) = import_bytes(&bytes, Path::new("sim.ulg"), &opts).unwrap();
    let spinning = (0..rec.len())
        .filter(|&r| rec.motor_commands(r).iter().any(|c| *c > 0.02))
        .count();
    assert_eq!(back.len(), spinning, "{}", report.summary(&back));
    assert!(
        report
            .segments
            .iter()
            .all(|s| s.kind == SegmentKind::Ground)
    );
}
