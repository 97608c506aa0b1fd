//! Regression: an augmented model read back from its file differed from the one written in
//! the last bit of a coefficient (1.7170400262418501 came back as 1.71704002624185), because
//! serde_json's default float parser is fast but not correctly rounded. A model file must
//! reproduce the model exactly, or `compensate` from the file and from memory disagree. The
//! workspace now enables serde_json's `float_roundtrip`.
use magstand_diagnose::augmented_model::{
    AugmentedModel, AugmentedTerm, FORMAT, MotorCurrentLaw, NoiseLaw, VERSION,
};

#[test]
fn coefficients_survive_the_file_bit_for_bit() {
    // The value that broke, and others whose shortest decimal form needs 17 digits.
    let hard = [
        1.7170400262418501,
        0.1 + 0.2,
        1.0 / 3.0,
        2.0_f64.sqrt(),
        -5.125437975815636e-7,
    ];
    let model = AugmentedModel {
        format: FORMAT.into(),
        version: VERSION,
        recording: "seen.csv".into(),
        nominal_scenario: String::new(),
        stated_keys: Some(vec!["motors.dead_zone".into()]),
        command_lead: 0.26585140122570994,
        block_s: 0.5,
        holdout_every: 3,
        effects: vec![AugmentedTerm {
            name: "current_lag".into(),
            variant: None,
            theta: vec![0.28740422209046457],
        }],
        columns: (0..hard.len()).map(|i| format!("c{i}")).collect(),
        coefficients: hard.iter().map(|&c| [c, -c, c * 1e3]).collect(),
        noise: Some(NoiseLaw {
            variance_ut2: [
                [hard[0], hard[1], hard[2]],
                [hard[3], hard[4], 0.0],
                [0.0; 3],
            ],
            floor_ut2: [hard[1], hard[2], hard[3]],
            full_load_a: 47.123456789012345,
        }),
        method: Some("physics".into()),
        choice: None,
        magnetometer: None,
        magnetometer_to_body: None,
        follow_recorded_voltage: true,
        follow_recorded_current: true,
        motor_groups: Some(vec![vec![0, 2], vec![1], vec![3]]),
        motor_current_law: Some(MotorCurrentLaw {
            columns: vec!["driven".into(), "speed^1".into()],
            a_per_unit: vec![hard[0], hard[4]],
        }),
        current_law: Some(MotorCurrentLaw {
            columns: vec!["speed^1".into()],
            a_per_unit: vec![hard[2]],
        }),
        calibration_warnings: vec!["no [supply] is stated: \u{00b5}T \"quoted\"".into()],
    };
    let path = std::env::temp_dir().join(format!("magstand-bit-exact-{}.json", std::process::id()));
    model.save(&path).unwrap();
    let back = AugmentedModel::load(&path);
    std::fs::remove_file(&path).ok();
    let back = back.unwrap();
    for (a, b) in model.coefficients.iter().zip(&back.coefficients) {
        for k in 0..3 {
            assert_eq!(
                a[k].to_bits(),
                b[k].to_bits(),
                "wrote {:e}, read {:e}",
                a[k],
                b[k]
            );
        }
    }
    assert_eq!(model, back);
}
