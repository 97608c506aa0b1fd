//! Flight logs: a recording with attitude whose vehicle flew is diagnosed on a baseline that
//! takes out the Earth field turned by the logged attitude, the sensor offset and the
//! magnetometer delay; a flight without attitude is refused.
//!
//! Regression: the diagnosis ignored the logged attitude, so the Earth field turning with
//! every heading change of a real flight was named as motor physics (3 to 5 names on every
//! ArduPilot log, `time_offset` and `thermal_drift` among them).
use magstand_core::{Quat, Recording, Vec3};
use magstand_diagnose::{DiagnoseConfig, diagnose, unstated_nominal};
mod common;
use common::Normal;

const HZ: f64 = 50.0;
const DELAY_S: f64 = 0.12;
const EARTH_NED_UT: [f64; 3] = [21.0, 1.5, -48.0];

/// Five minutes of flight written by this test's own laws: slow turns through every heading
/// with rolling and pitching, the throttle stepping in the hover range, a disturbance that
/// follows its own current law, and the magnetometer 0.12 s behind the commands.
fn flight() -> Recording {
    let n = (300.0 * HZ) as usize;
    let mut steps = Normal(0x5eed_f1e5);
    let mut level = 0.5;
    let thr: Vec<f64> = (0..n)
        .map(|k| {
            if k % (3 * HZ as usize) == 0 {
                level = (0.55 + 0.12 * steps.draw()).clamp(0.3, 0.8);
            }
            level
        })
        .collect();
    let t_s: Vec<f64> = (0..n).map(|k| k as f64 / HZ).collect();
    let attitude: Vec<Quat> = t_s
        .iter()
        .map(|&t| {
            let yaw = std::f64::consts::TAU * t / 60.0;
            let roll = 15f64.to_radians() * (std::f64::consts::TAU * t / 7.0).sin();
            let pitch = 10f64.to_radians() * (std::f64::consts::TAU * t / 11.0).sin();
            Quat::from_euler_angles(roll, pitch, yaw)
        })
        .collect();
    let earth = Vec3::from(EARTH_NED_UT);
    let offset = Vec3::new(-4.0, 7.5, 2.0);
    let gain_ut_per_a = Vec3::new(0.05, -0.03, 0.08);
    let lag = (DELAY_S * HZ).round() as usize;
    let mut noise = Normal(0x0dd_ba11);
    let mag_ut = (0..n)
        .map(|k| {
            let u = thr[k.saturating_sub(lag)];
            let current_a = 2.0 + 30.0 * u.powf(1.5);
            attitude[k].inverse() * earth
                + offset
                + gain_ut_per_a * current_a
                + Vec3::from_fn(|_, _| 0.1 * noise.draw())
        })
        .collect();
    Recording {
        t_s,
        thr: vec![thr.clone(); 4],
        overall_only: false,
        mag_ut,
        attitude: Some(attitude),
        extra: vec![("segment".into(), vec!["flight".into(); n])],
        ..Recording::default()
    }
}

#[test]
fn a_flight_is_diagnosed_on_the_attitude_aware_baseline() {
    let d = diagnose(
        &flight(),
        "flight.csv",
        &unstated_nominal().unwrap(),
        &DiagnoseConfig::default().check().unwrap(),
    )
    .unwrap();
    let value = |name: &str| {
        d.baseline
            .calibration
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.value)
            .unwrap_or_else(|| panic!("no {name} in {:?}", d.baseline.calibration))
    };
    let delay = value("flight.mag_delay_s");
    assert!(
        (delay - DELAY_S).abs() < 0.03,
        "delay {delay} s (true {DELAY_S})"
    );
    for (k, axis) in ["n", "e", "d"].iter().enumerate() {
        let e = value(&format!("flight.earth_{axis}_ut"));
        assert!(
            (e - EARTH_NED_UT[k]).abs() < 1.0,
            "Earth {axis}: {e} µT (true {})",
            EARTH_NED_UT[k]
        );
    }
    assert!(
        d.verdict.is_empty(),
        "a flight with nothing but the Earth field, the offset, the delay and the motors was named {:?}\n{}",
        d.verdict,
        d.summary()
    );
}

#[test]
fn a_flight_without_attitude_is_refused() {
    let mut rec = flight();
    rec.attitude = None;
    let e = diagnose(
        &rec,
        "flight.csv",
        &unstated_nominal().unwrap(),
        &DiagnoseConfig::default().check().unwrap(),
    )
    .expect_err("a flight without attitude was diagnosed");
    let m = e.to_string();
    assert!(
        m.contains("flight.csv") && m.contains("att_qw") && m.contains("flight"),
        "{m}"
    );
}
