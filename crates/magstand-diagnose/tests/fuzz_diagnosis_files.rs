//! Property tests of the two files `diagnose` writes and other commands read back: the
//! augmented model (`--model-out`, read by `compensate`, `export` and `report`) and the
//! diagnosis (`--json`, read by `report`). A valid file with one number replaced by a hostile
//! value is either refused at load, or everything derived from it is finite: the predicted
//! disturbance and noise sd at every row of a recording, and the diagnosis summary.
//!
//! This is the class of defect where `holdout_every: 0` divided by zero, a short `theta`
//! indexed out of bounds and a negative lag predicted 1e300 and inf.
use std::path::Path;

use magstand_core::file_fuzzing::{hostile_json_value, mutate_json_number};
use magstand_core::{Recording, recording_csv};
use magstand_diagnose::{AugmentedModel, DEFAULT_NOMINAL, DiagnoseConfig, Diagnosis, diagnose};
use magstand_sim::Scenario;
use proptest::prelude::*;

fn bad_input(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/bad-inputs")
        .join(name)
}

fn small_lag() -> Recording {
    recording_csv::read(bad_input("small-lag.csv")).unwrap()
}

fn diagnosis_text(rec: &Recording) -> String {
    let nominal = Scenario::from_toml_str(DEFAULT_NOMINAL, "nominal")
        .unwrap()
        .check("nominal", None)
        .unwrap();
    let config = DiagnoseConfig::default().check().unwrap();
    let d = diagnose(rec, "small-lag.csv", &nominal, &config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("diagnosis.json");
    d.save(&path).unwrap();
    std::fs::read_to_string(path).unwrap()
}

fn finite(what: &str, values: &[magstand_core::Vec3]) {
    if let Some((row, v)) = values
        .iter()
        .enumerate()
        .find(|(_, v)| !v.iter().all(|x| x.is_finite()))
    {
        panic!("{what} at row {row} is {v:?}");
    }
}

proptest! {
    #![proptest_config(magstand_core::file_fuzzing::config(128))]

    #[test]
    fn a_crafted_augmented_model_is_refused_or_predicts_finite_values(
        pick in 0usize..10_000,
        value in hostile_json_value(),
    ) {
        thread_local! {
            static BASE: (Recording, String) = (
                small_lag(),
                std::fs::read_to_string(bad_input("augmented-lag.json")).unwrap(),
            );
        }
        BASE.with(|(rec, text)| {
            let crafted = mutate_json_number(text, pick, value.clone());
            let Ok(model) = AugmentedModel::from_json(&crafted, Path::new("crafted.json")) else {
                return;
            };
            if let Ok(dist) = model.dist_column(rec, "small-lag.csv") {
                finite(&format!("the disturbance with {value} at number {pick}"), &dist);
            }
            if let Ok(Some(sd)) = model.sd_column(rec, "small-lag.csv") {
                finite(&format!("the noise sd with {value} at number {pick}"), &sd);
            }
        });
    }

    #[test]
    fn a_crafted_diagnosis_is_refused_or_reads_finite(
        pick in 0usize..10_000,
        value in hostile_json_value(),
    ) {
        thread_local! {
            static BASE: String = diagnosis_text(&small_lag());
        }
        BASE.with(|text| {
            let crafted = mutate_json_number(text, pick, value.clone());
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("crafted.json");
            std::fs::write(&path, &crafted).unwrap();
            let Ok(d) = Diagnosis::load(&path) else { return };
            let summary = d.summary();
            let bad = magstand_core::file_fuzzing::non_finite_word(&summary);
            assert!(bad.is_none(), "{value} at number {pick}: {summary}");
            assert_eq!(std::fs::read_to_string(&path).unwrap(), crafted, "the input changed");
        });
    }
}

/// Regression, found by the property test above: a noise law with `full_load_a` of 2.2e-308
/// loaded, and every predicted sd came out infinite. The law's numbers are now bounded where
/// they are read (and written) so that the sd stays finite for every current a recording can
/// hold.
#[test]
fn a_noise_law_with_a_vanishing_full_load_is_refused() {
    let text = std::fs::read_to_string(bad_input("augmented-lag.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v["noise"].is_object(), "the base model has a noise law");
    v["noise"]["full_load_a"] = serde_json::json!(2.2250738585072014e-308);
    let e = AugmentedModel::from_json(&v.to_string(), Path::new("tiny-load.json"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("tiny-load.json") && e.contains("full_load_a"),
        "{e}"
    );
}
