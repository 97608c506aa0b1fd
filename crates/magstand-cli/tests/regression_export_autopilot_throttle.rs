//! Regression: ArduPilot multiplies `COMPASS_MOT*` (`COMPASS_MOTCT` 1) by its throttle, the
//! collective thrust demand (`CTUN.ThO`), which its thrust curve (`MOT_THST_EXPO`, 0.8 on
//! log171) maps to the motor outputs. `export --to ardupilot` fitted the line against the mean
//! motor output instead: on log171, in flight 0.53 of the PWM range at a demand of 0.39, so
//! every exported coefficient was a quarter too small. `import` now writes the demand as
//! `autopilot_throttle` (PX4's thrust setpoint too), and a throttle line over such a recording
//! is fitted against it.
mod common;
use common::magstand;

/// Column `name` of CSV `text`, as numbers.
fn column(text: &str, name: &str) -> Vec<f64> {
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    let k = header
        .split(',')
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("no column {name} in {header}"));
    lines
        .map(|l| {
            l.split(',')
                .nth(k)
                .and_then(|v| v.parse().ok())
                .unwrap_or(f64::NAN)
        })
        .collect()
}

#[test]
fn a_throttle_line_for_ardupilot_is_fitted_against_its_own_throttle() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let log = common::test_data("real-logs", "ardupilot-log171-quad.bin");
    let (rec, model, out) = (p("r.csv"), p("m.json"), p("c.csv"));
    let r = magstand(&["import", "--dataflash", &log, "--out", &rec, "--mag", "1"]);
    assert!(r.ok && r.stderr.contains("CTUN.ThrOut"), "{}", r.stderr);
    common::fit_flight(&rec, &model);
    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &rec,
        "--out",
        &out,
    ]);
    assert!(r.ok, "{}", r.stderr);
    let r = magstand(&[
        "export",
        "--model",
        &model,
        "--to",
        "ardupilot",
        "--recording",
        &rec,
    ]);
    assert!(
        r.ok && r.stderr.contains("against the autopilot's own throttle"),
        "{}",
        r.stderr
    );
    // The known answer: minus the least-squares slope through the origin of the predicted
    // disturbance against the logged demand, in mG.
    let (written, recording) = (
        std::fs::read_to_string(&out).unwrap(),
        std::fs::read_to_string(&rec).unwrap(),
    );
    let demand = column(&recording, "autopilot_throttle");
    let outputs: Vec<f64> = (1..=4)
        .map(|m| column(&recording, &format!("thr_{m}")))
        .fold(vec![0.0; demand.len()], |acc, c| {
            acc.iter().zip(c).map(|(a, c)| a + c / 4.0).collect()
        });
    let slope = |x: &[f64], d: &[f64]| {
        x.iter().zip(d).map(|(x, d)| x * d).sum::<f64>() / x.iter().map(|x| x * x).sum::<f64>()
    };
    // Copter 3.3 adds its compensation before compass 2's soft-iron matrix (`mag_to_body`):
    // the body-frame line is written through it.
    let frame = magstand_core::magnetometer_frame::SensorToBody::of_recording(
        &magstand_core::recording_csv::read(&rec).unwrap(),
        rec.as_ref(),
    )
    .unwrap()
    .expect("log171's import writes compass 2's soft-iron matrix");
    let axes = ["x", "y", "z"];
    let body_mg = magstand_core::Vec3::from_fn(|a, _| {
        -10.0 * slope(&demand, &column(&written, &format!("dist_{}_ut", axes[a])))
    });
    let expected = frame.to_sensor(body_mg).unwrap();
    for (a, axis) in axes.iter().enumerate() {
        let dist = column(&written, &format!("dist_{axis}_ut"));
        let expected_mg = expected[a];
        let name = format!("COMPASS_MOT2_{}", axis.to_uppercase());
        let got: f64 = r
            .stdout
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{name},"))?.parse().ok())
            .unwrap_or_else(|| panic!("no {name} in {}", r.stdout));
        assert!(
            (got - expected_mg).abs() < 0.002,
            "{name} = {got}, the line against the demand gives {expected_mg:.3}"
        );
        // Against the motor outputs it would be a quarter smaller (the matrix is near 1).
        let outputs_mg = -10.0 * slope(&outputs, &dist);
        assert!(
            (got / outputs_mg - 1.0).abs() > 0.2,
            "{name}: {got} against the demand, {outputs_mg:.3} against the outputs"
        );
    }
}

/// PX4's throttle compensation multiplies the thrust setpoint: `vehicle_thrust_setpoint` from
/// 1.13, `actuator_controls_0` before. On the 1.9 UAVCAN log the motors run at 0.55 of their
/// range at a setpoint of 0.36.
#[test]
fn a_px4_import_writes_the_thrust_setpoint() {
    let dir = tempfile::tempdir().unwrap();
    for (file, source, differs) in [
        (
            "px4-fmuv3-uavcan-esc-status.ulg",
            "actuator_controls_0",
            true,
        ),
        (
            "px4-fmuv6c-quad-local.ulg",
            "vehicle_thrust_setpoint",
            false,
        ),
    ] {
        let rec = dir.path().join("r.csv");
        let log = common::test_data("real-logs", file);
        let r = magstand(&["import", "--ulog", &log, "--out", rec.to_str().unwrap()]);
        assert!(r.ok && r.stderr.contains(source), "{file}: {}", r.stderr);
        let text = std::fs::read_to_string(&rec).unwrap();
        let demand = column(&text, "autopilot_throttle");
        assert!(
            demand.iter().all(|v| (0.0..=1.0).contains(v)) && demand.iter().any(|v| *v > 0.3),
            "{file}: {demand:?}"
        );
        let motors = (1..=4)
            .map(|m| column(&text, &format!("thr_{m}")))
            .fold(vec![0.0; demand.len()], |acc, c| {
                acc.iter().zip(c).map(|(a, c)| a + c / 4.0).collect()
            });
        let widest = demand
            .iter()
            .zip(&motors)
            .map(|(d, m)| (d - m).abs())
            .fold(0.0f64, f64::max);
        assert_eq!(
            widest > 0.1,
            differs,
            "{file}: setpoint and outputs differ by up to {widest}"
        );
    }
}
