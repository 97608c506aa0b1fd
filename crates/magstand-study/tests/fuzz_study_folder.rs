//! Property test of a study folder (`runs.csv` and `study.json`, read back by `montecarlo
//! merge` and `report`): a valid shard with one cell or number replaced by a hostile value is
//! either refused naming the file, or its summary holds only finite numbers; the folder is
//! never changed by reading it.
//!
//! This is the class of defect where a shard with a repeated (run, method) row merged into a
//! wrong summary.
use std::path::Path;

use magstand_core::file_fuzzing::{hostile_f64, hostile_json_value, mutate_json_number};
use magstand_sim::Scenario;
use magstand_study::{Silent, StudyConfig, StudyResult, Summary, merge, run_study};
use proptest::prelude::*;

const SCENARIO: &str = r#"
    name = "quick stair"
    [program]
    kind = "stair"
    off_s = 1.0
    steps = 4
    dwell_s = 1.0
    [stand]
    enabled = false
"#;

/// The texts of `runs.csv` and `study.json` of a whole 3-run study of two methods.
fn study_files() -> (String, String) {
    let scenario = Scenario::from_toml_str(SCENARIO, "inline")
        .unwrap()
        .check("inline", None)
        .unwrap();
    let mut config = StudyConfig::new(3, 7);
    config.methods = vec!["px4".into(), "global".into()];
    let study = config.check(&scenario).unwrap();
    let result = run_study(&study, Some(1), &Silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    result.write(dir.path()).unwrap();
    let read = |n: &str| std::fs::read_to_string(dir.path().join(n)).unwrap();
    (read("runs.csv"), read("study.json"))
}

/// Reads a folder holding `runs` and `info`; on success, checks the summary and that reading
/// left the files as they were.
fn check_folder(runs: &str, info: &str, what: &str) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("runs.csv"), runs).unwrap();
    std::fs::write(dir.path().join("study.json"), info).unwrap();
    match StudyResult::read(dir.path()) {
        Err(e) => {
            let e = e.to_string();
            prop_assert!(
                e.contains("runs.csv") || e.contains("study.json"),
                "{what}: the error names no file: {e}"
            );
        }
        Ok(result) => {
            let merged = merge(vec![result]);
            if let Ok(m) = merged {
                let json = Summary::new(m.info.clone(), &m.outcomes).to_json();
                let v: serde_json::Value = serde_json::from_str(&json).unwrap();
                let mut leaked = Vec::new();
                non_finite_nulls(&v, "", &mut leaked);
                prop_assert!(
                    leaked.is_empty(),
                    "{what}: null (a non-finite number) at {leaked:?}"
                );
            }
        }
    }
    for (name, text) in [("runs.csv", runs), ("study.json", info)] {
        prop_assert_eq!(
            std::fs::read_to_string(Path::new(dir.path()).join(name)).unwrap(),
            text,
            "{} changed",
            name
        );
    }
    Ok(())
}

/// serde_json writes a non-finite number as null. The summary's optional fields (a first
/// failure, an empty throttle bin, a ratio to a bound that does not exist) are null by
/// design; a null anywhere else is a NaN or inf that leaked.
fn non_finite_nulls(v: &serde_json::Value, key: &str, out: &mut Vec<String>) {
    const OPTIONAL: [&str; 4] = ["first_failure", "crlb_ratio", "mse_crlb_ratio", "bins"];
    match v {
        serde_json::Value::Null if !OPTIONAL.contains(&key) => out.push(key.to_string()),
        serde_json::Value::Array(a) => a.iter().for_each(|x| non_finite_nulls(x, key, out)),
        serde_json::Value::Object(o) => o.iter().for_each(|(k, x)| non_finite_nulls(x, k, out)),
        _ => {}
    }
}

fn base() -> &'static (String, String) {
    static BASE: std::sync::OnceLock<(String, String)> = std::sync::OnceLock::new();
    BASE.get_or_init(study_files)
}

proptest! {
    #![proptest_config(magstand_core::file_fuzzing::config(128))]

    #[test]
    fn a_crafted_runs_csv_is_refused_or_summarised_finite(
        row in 1usize..7,
        column in 0usize..40,
        value in prop_oneof![
            hostile_f64().prop_map(|x| format!("{x:e}")),
            Just("NaN".to_string()),
            Just("".to_string()),
            Just("px4".to_string()),
            Just("0".to_string()),
        ],
    ) {
        let (runs, info) = base();
        let mut lines: Vec<Vec<String>> = runs
            .lines()
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect();
        let r = row % lines.len().max(2);
        let c = column % lines[r].len();
        lines[r][c] = value.clone();
        let text: String = lines.iter().map(|l| l.join(",") + "\n").collect();
        check_folder(&text, info, &format!("{value} in runs.csv row {r} column {c}"))?;
    }

    #[test]
    fn a_crafted_study_json_is_refused_or_summarised_finite(
        pick in 0usize..1000,
        value in hostile_json_value(),
    ) {
        let (runs, info) = base();
        let crafted = mutate_json_number(info, pick, value.clone());
        check_folder(runs, &crafted, &format!("{value} at number {pick} of study.json"))?;
    }
}

/// Regression, found by the property test above: a figure of 1.8e308 in runs.csv was read,
/// and the summary's standard deviation overflowed into a null in SUMMARY.json. Figures are
/// now bounded where they are read, with the row and column named.
#[test]
fn an_absurd_figure_is_refused_by_row_and_column() {
    let (runs, info) = base();
    let mut lines: Vec<String> = runs.lines().map(str::to_string).collect();
    let mut cells: Vec<String> = lines[1].split(',').map(str::to_string).collect();
    assert!(cells[3].is_empty(), "the first run succeeded: {}", lines[1]);
    cells[4] = "1.7976931348623157e308".into();
    lines[1] = cells.join(",");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("runs.csv"), lines.join("\n") + "\n").unwrap();
    std::fs::write(dir.path().join("study.json"), info).unwrap();
    let e = StudyResult::read(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("runs.csv") && e.contains("row 2") && e.contains("1e12"),
        "{e}"
    );
}
