//! The diagnosis as a model: fitted on one recording of a stand whose motors spin up more
//! slowly than the nominal physics assumes (a concealed current lag), the augmented model
//! predicts the disturbance of another recording of the same stand (a different seed and
//! command sequence, never seen by the diagnosis) much better than the calibrated nominal
//! physics alone, judged against the simulator's ground truth. It survives its file, and a
//! recording it cannot serve is refused by name.
use magstand_core::Vec3;
mod common;
use common::diagnose_default;
use magstand_diagnose::AugmentedModel;
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
    [motors]
    spinup_tau_s = 0.06
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
    let d = diagnose_default(&seen, "seen.csv", &nominal);
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

    // The noise sd it writes is the noise that is left: the compensated reading minus the true
    // field, divided by it, has unit variance per axis (eq. 8's variance growing with the
    // load, fitted on the other recording), and it follows the simulator's true sd.
    let sd = model.sd_column(&new, "new.csv").unwrap().unwrap();
    let field = &new.truth.as_ref().unwrap().field_ut;
    let true_sd = &new.truth.as_ref().unwrap().sd_ut;
    for a in 0..3 {
        let z2: f64 = (0..new.len())
            .map(|r| ((comp.mag_ut[r][a] - field[r][a]) / sd[r][a]).powi(2))
            .sum::<f64>()
            / new.len() as f64;
        let ratio: f64 = (0..new.len())
            .map(|r| sd[r][a] / true_sd[r][a])
            .sum::<f64>()
            / new.len() as f64;
        assert!(
            (0.8..1.25).contains(&z2) && (0.8..1.25).contains(&ratio),
            "axis {a}: mean squared standardized residual {z2:.3}, predicted over true sd {ratio:.3}"
        );
    }
    let written: Vec<f64> = comp
        .extra
        .iter()
        .find(|(n, _)| n == "sd_x_ut")
        .map(|(_, v)| v.iter().map(|c| c.parse().unwrap()).collect())
        .unwrap();
    let mid = new.len() / 2;
    assert!(
        (written[mid] - sd[mid].x).abs() < 1e-6,
        "{} against {}",
        written[mid],
        sd[mid].x
    );

    // A model of a quad cannot serve a hexa's recording.
    let mut six = new.clone();
    six.thr.push(six.thr[0].clone());
    six.thr.push(six.thr[0].clone());
    let err = model.dist_column(&six, "hexa.csv").unwrap_err().to_string();
    assert!(err.contains("hexa.csv") && err.contains("6 motor"), "{err}");

    // A form of an effect this magstand does not know (a file written by another version, or
    // edited) is refused by name, as an unknown effect is.
    let mut unknown_form = model.clone();
    unknown_form.effects[0].variant = Some("no_such_form".into());
    let err = unknown_form
        .dist_column(&new, "new.csv")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no_such_form") && err.contains("current_lag"),
        "{err}"
    );
}
