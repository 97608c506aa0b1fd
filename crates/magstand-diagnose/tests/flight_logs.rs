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
/// follows its own current law 0.12 s behind the commands, and the magnetometer's samples on
/// time against the attitude. The current is logged.
fn flight() -> Recording {
    flight_with(|_, _| Vec3::zeros())
}

/// [`flight`] with `extra(t_s, current_a)` added to the readings, for the logged current
/// before each row.
fn flight_with(mut extra: impl FnMut(&[f64], &[f64]) -> Vec3) -> Recording {
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
    let current_a: Vec<f64> = (0..n)
        .map(|k| 2.0 + 30.0 * thr[k.saturating_sub(lag)].powf(1.5))
        .collect();
    let mag_ut = (0..n)
        .map(|k| {
            attitude[k].inverse() * earth
                + offset
                + gain_ut_per_a * current_a[k]
                + extra(&t_s[..=k], &current_a[..=k])
                + Vec3::from_fn(|_, _| 0.1 * noise.draw())
        })
        .collect();
    Recording {
        bat_a: Some(current_a),
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
    // The samples are on time against the attitude; the disturbance lags the commands.
    let (age, delay) = (value("flight.mag_delay_s"), value("flight.command_delay_s"));
    assert!(
        age < 0.03 && (delay - DELAY_S).abs() < 0.03,
        "samples {age} s behind the attitude (true 0), {delay} s behind the commands (true {DELAY_S})"
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

#[test]
fn a_field_lagging_the_logged_current_of_a_flight_is_named() {
    // Eddy currents: the field of 0.4 µT/A follows the measured current through a 0.6 s lag,
    // slower than any spin-up, so its departure from the current is physics of its own.
    let gain = Vec3::new(0.4, -0.3, 0.5);
    let (tau_s, mut state, mut last) = (0.6, None::<f64>, 0.0);
    let rec = flight_with(|t, a| {
        let k = t.len() - 1;
        let s = state.get_or_insert(a[0]);
        if k > 0 {
            *s += (a[k - 1] - *s) * (1.0 - (-(t[k] - last) / tau_s).exp());
        }
        last = t[k];
        gain * (*s - a[k])
    });
    let d = diagnose(
        &rec,
        "eddy.csv",
        &unstated_nominal().unwrap(),
        &DiagnoseConfig::default().check().unwrap(),
    )
    .unwrap();
    assert_eq!(d.verdict, ["current_lag"], "{}", d.summary());
    let tau = d.effects[0]
        .params
        .iter()
        .find(|p| p.name == "spinup_tau_s")
        .map(|p| p.value);
    assert!(
        tau.is_some_and(|v| (v - tau_s).abs() < 0.15),
        "lag {tau:?} s (true {tau_s}): {:?}",
        d.effects[0].params
    );
    // Its model follows the measured current, so a recording without one is refused by name.
    let model = d.model.as_ref().expect("a diagnosis writes its model");
    assert!(model.follow_recorded_current);
    let mut without = rec.clone();
    without.bat_a = None;
    let err = model
        .dist_column(&without, "no-current.csv")
        .expect_err("a model on the measured current compensated a recording without it")
        .to_string();
    assert!(
        err.contains("no-current.csv") && err.contains("bat_a"),
        "{err}"
    );
}
