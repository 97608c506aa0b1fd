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

/// `rec` written as a ULog with `opts` and imported again: the field must come back as it was
/// (the calibration taken out), with the transform the import wrote in `mag_to_body`, and the
/// import's notes.
fn calibrated_round_trip(
    rec: &Recording,
    opts: &LogWriteOptions,
    label: &str,
) -> (magstand_core::magnetometer_frame::SensorToBody, Vec<String>) {
    let (back, report) = import_bytes(
        &ulog_bytes(rec, opts),
        Path::new("calibrated.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    compare(rec, &back, 1e-6, label);
    let frame =
        magstand_core::magnetometer_frame::SensorToBody::of_recording(&back, Path::new("c.csv"))
            .unwrap()
            .unwrap_or_else(|| panic!("{label}: no mag_to_body"));
    (frame, report.notes)
}

/// A PX4 calibration that turns and scales the sensor (a board mounted turned by 135 degrees,
/// an external sensor upside down and turned by 90, one pitched up by 90, a board at PX4's
/// one odd angle) is taken back out by the import, and the
/// transform it applied is written in `mag_to_body`, where `export` finds the frame PX4 adds
/// its compensation in.
#[test]
fn a_turned_and_scaled_px4_calibration_is_taken_out_and_its_transform_kept() {
    use magstand_core::magnetometer_frame::SensorToBody;
    use magstand_logs::log_writer::Px4MagCalibration;
    let rec = run();
    // (CAL_MAG0_ROT, SENS_BOARD_ROT, the roll, pitch and yaw PX4's table gives the code used,
    // the board's trim in degrees: an internal sensor turns with it, an external one does not).
    for (rotation, board_rotation, [roll, pitch, yaw], board_trim_deg) in [
        (-1, 3, [0.0f64, 0.0, 135.0], [0.0; 3]),
        (10, 0, [180.0, 0.0, 90.0], [2.0, -1.5, 0.5]),
        (24, 0, [0.0, 90.0, 0.0], [0.0; 3]),
        (-1, 38, [90.0, 68.0, 293.0], [0.0; 3]),
        (-1, 0, [0.0, 0.0, 0.0], [-3.4, 2.5, 1.0]),
    ] {
        let cal = Px4MagCalibration {
            rotation,
            board_rotation,
            board_trim_deg,
            offset_g: [0.12, -0.05, 0.3],
            scale: [1.08, 0.94, 1.02],
            off_diagonal: [0.015, -0.02, 0.01],
        };
        let opts = LogWriteOptions {
            landed: false,
            px4_calibration: Some(cal),
            ..LogWriteOptions::default()
        };
        let label = format!("CAL_MAG0_ROT {rotation}, SENS_BOARD_ROT {board_rotation}");
        let (frame, notes) = calibrated_round_trip(&rec, &opts, &label);
        // The expected transform, worked out here from the angles: about x by the roll, then
        // about y by the pitch, then about z by the yaw; the trim the same way, after it.
        let f = |v: f64| v as f32 as f64;
        let scale = magstand_core::Mat3::new(
            f(1.08),
            f(0.015),
            f(-0.02),
            f(0.015),
            f(0.94),
            f(0.01),
            f(-0.02),
            f(0.01),
            f(1.02),
        );
        let rotation_matrix = |[roll, pitch, yaw]: [f64; 3]| {
            let (cr, sr) = (roll.to_radians().cos(), roll.to_radians().sin());
            let (cp, sp) = (pitch.to_radians().cos(), pitch.to_radians().sin());
            let (cy, sy) = (yaw.to_radians().cos(), yaw.to_radians().sin());
            let rx = magstand_core::Mat3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
            let ry = magstand_core::Mat3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
            let rz = magstand_core::Mat3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0);
            rz * ry * rx
        };
        let trim = match rotation {
            -1 => rotation_matrix(board_trim_deg.map(f)),
            _ => magstand_core::Mat3::identity(),
        };
        let expected = trim * rotation_matrix([roll, pitch, yaw]) * scale;
        let d = (frame.matrix() - expected).abs().max();
        assert!(
            d < 1e-12,
            "{label}: mag_to_body {frame}, expected {expected}"
        );
        assert!(
            notes.iter().any(|n| n.contains("mag_to_body")),
            "{label}: {notes:?}"
        );
    }
    // Without a calibration's turn or scale, nothing is written: the sensor reads the body.
    let (back, _) = import_bytes(
        &ulog_bytes(&rec, &LogWriteOptions::default()),
        Path::new("plain.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let frame = SensorToBody::of_recording(&back, Path::new("plain.csv")).unwrap();
    assert!(frame.is_none_or(|f| f.is_identity()), "{frame:?}");
}

/// Before PX4 1.12 the driver applied the calibration's offsets and scale to `sensor_mag`
/// itself (only the rotation came after, and the power compensation before it). A 1.11 log
/// is imported with the rotation alone, which is then the frame the compensation lives in;
/// a 1.14 log with the whole calibration.
#[test]
fn a_px4_log_before_1_12_is_calibrated_by_its_driver() {
    use magstand_logs::log_writer::Px4MagCalibration;
    let rec = run();
    let cal = Px4MagCalibration {
        rotation: 4,
        board_rotation: 0,
        board_trim_deg: [0.0; 3],
        offset_g: [0.12, -0.05, 0.3],
        scale: [1.08, 0.94, 1.02],
        off_diagonal: [0.0; 3],
    };
    // Yaw 180: x and y turned over.
    let turned = magstand_core::Mat3::from_diagonal(&magstand_core::Vec3::new(-1.0, -1.0, 1.0));
    let f = |v: f64| v as f32 as f64;
    let scaled = turned
        * magstand_core::Mat3::from_diagonal(&magstand_core::Vec3::new(f(1.08), f(0.94), f(1.02)));
    for (release, expected) in [(0x010B_00FFu32, turned), (0x010E_00FF, scaled)] {
        let opts = LogWriteOptions {
            landed: false,
            px4_calibration: Some(cal),
            px4_release: Some(release),
            ..LogWriteOptions::default()
        };
        let label = format!("ver_sw_release {release:#010x}");
        let (frame, notes) = calibrated_round_trip(&rec, &opts, &label);
        let d = (frame.matrix() - expected).abs().max();
        assert!(
            d < 1e-12,
            "{label}: mag_to_body {frame}, expected {expected}"
        );
        let driver = notes.iter().any(|n| n.contains("applied by the driver"));
        assert_eq!(driver, release < 0x010C_0000, "{label}: {notes:?}");
    }
}

/// ArduPilot logs `ATT` as the vehicle body's attitude, the estimators' Euler angles less the
/// trim `AHRS_TRIM_*`, while `MAG` is in the autopilot board's frame. The import adds the trim
/// back, so that the attitude is the board's again: without it, the attitude would be off by
/// the trim (here 2 degrees of roll), which turns the Earth field by as much.
#[test]
fn an_ardupilot_trim_is_added_back_to_the_logged_attitude() {
    let rec = run();
    let trim = [0.035, -0.02, 0.01];
    let opts = LogWriteOptions {
        landed: false,
        ardupilot_trim_rad: trim,
        ..LogWriteOptions::default()
    };
    let (back, report) = import_bytes(
        &dataflash_bytes(&rec, &opts),
        Path::new("trimmed.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    compare(&rec, &back, 5e-4 + 1e-9, "DataFlash with AHRS_TRIM");
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains("AHRS_TRIM_X") && n.contains("+2.01, -1.15, +0.57 deg")),
        "{:?}",
        report.notes
    );
    // The same log without its trim parameters comes back turned by the trim.
    let untrimmed = LogWriteOptions {
        ardupilot_trim_rad: [0.0; 3],
        ..opts
    };
    let logged_as_trimmed = {
        let mut r = rec.clone();
        let q = r.attitude.as_mut().unwrap();
        for a in q.iter_mut() {
            let (roll, pitch, yaw) = a.euler_angles();
            *a = magstand_core::Quat::from_euler_angles(
                roll - trim[0],
                pitch - trim[1],
                yaw - trim[2],
            );
        }
        r
    };
    let (back, _) = import_bytes(
        &dataflash_bytes(&logged_as_trimmed, &untrimmed),
        Path::new("untrimmed.bin"),
        &ImportOptions::default(),
    )
    .unwrap();
    let q = |r: &Recording, k: usize| r.attitude.as_ref().unwrap()[k];
    let off = q(&back, 5).angle_to(&q(&rec, 5));
    assert!(
        (0.03..0.05).contains(&off),
        "without the trim the attitude is {off} rad from the board's"
    );
}
