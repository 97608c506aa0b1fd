//! The diagnosis as a model: fitted on one recording of a stand whose motors spin up more
//! slowly than the nominal physics assumes (a concealed current lag), the augmented model
//! predicts the disturbance of another recording of the same stand (a different seed and
//! command sequence, never seen by the diagnosis) much better than the calibrated nominal
//! physics alone, judged against the simulator's ground truth. It survives its file, and a
//! recording it cannot serve is refused by name.
use magstand_core::Vec3;
use magstand_diagnose::{AugmentedModel, DiagnoseConfig, diagnose};
use magstand_sim::{Scenario, ValidScenario, simulate};

const STAND: &str = r#"
    name = "steps"
    [program]
    kind = "random_steps"
    off_s = 2.0
    count = 40
    dwell_min_s = 1.0
    dwell_max_s = 2.0
    [supply]
    kind = "bench"
    voltage_v = 12.0
    [magnetometer]
    odr_hz = 50.0
"#;

fn scenario(overrides: &[&str], seed: u64) -> ValidScenario {
    let mut o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    o.push(format!("seed={seed}"));
    Scenario::from_toml_with_overrides(STAND, "stand", &o)
        .unwrap()
        .check("stand", None)
        .unwrap()
}

fn rmse_against_truth(pred: &[Vec3], truth: &[Vec3]) -> f64 {
    let s: f64 = pred
        .iter()
        .zip(truth)
        .map(|(p, t)| (p - t).norm_squared())
        .sum();
    (s / pred.len() as f64).sqrt()
}

#[test]
fn the_augmented_model_predicts_a_new_recording_of_the_same_stand() {
    let nominal = scenario(&[], 1);
    let real = |seed| scenario(&["motors.spinup_tau_s=0.3"], seed);
    let seen = simulate(&real(1), 1);
    let d = diagnose(
        &seen,
        "seen.csv",
        &nominal,
        &DiagnoseConfig::default().check().unwrap(),
    )
    .unwrap();
    assert_eq!(d.verdict, ["current_lag"]);
    let model = d.model.clone().unwrap();
    let baseline = d.baseline_model.clone().unwrap();

    // Through its file.
    let path = std::env::temp_dir().join(format!("magstand-augmented-{}.json", std::process::id()));
    model.save(&path).unwrap();
    let loaded = AugmentedModel::load(&path);
    std::fs::remove_file(&path).ok();
    let model = loaded.unwrap();
    assert_eq!(Some(&model), d.model.as_ref());

    // A recording the diagnosis never saw: another seed, other commands.
    let new = simulate(&real(2), 2);
    let truth = &new.truth.as_ref().unwrap().dist_ut;
    let predicted = model.dist_column(&new, "new.csv").unwrap();
    let after = rmse_against_truth(&predicted, truth);
    let before = rmse_against_truth(&baseline.dist_column(&new, "new.csv").unwrap(), truth);
    let size = rmse_against_truth(&vec![Vec3::zeros(); truth.len()], truth);
    assert!(
        after < 0.5 * before && after < 0.1 * size,
        "augmented {after:.3} uT, nominal {before:.3} uT, disturbance {size:.3} uT RMS"
    );
    // Compensation removes exactly that prediction.
    let comp = model.compensate(&new, "new.csv").unwrap();
    for r in [0, new.len() / 2, new.len() - 1] {
        let removed = new.mag_ut[r] - comp.mag_ut[r];
        assert!((removed - predicted[r]).norm() < 1e-12, "row {r}");
    }
    assert!(comp.extra.iter().any(|(n, _)| n == "dist_z_ut"));

    // A model of a quad cannot serve a hexa's recording.
    let mut six = new.clone();
    six.thr.push(six.thr[0].clone());
    six.thr.push(six.thr[0].clone());
    let err = model.dist_column(&six, "hexa.csv").unwrap_err().to_string();
    assert!(err.contains("hexa.csv") && err.contains("6 motor"), "{err}");
}
