//! Regression: a recording whose supply voltage was logged as `vbat` and whose board
//! temperature as `Temp_C` was fitted and diagnosed as if neither had been logged, without a
//! word: unknown columns are carried through as extra, so the diagnosis calibrated the
//! battery's sag and took the heating from the power, while the user believed both measured.
//! `fit`, `diagnose`, `compensate` and `report` now warn of an extra column that looks meant
//! to be read where the column it looks like is absent.
mod common;

/// The bad input `small-stair.csv` with two more columns under `header`, each row's `cells`.
fn stair_with(dir: &std::path::Path, header: &str, cells: &str) -> String {
    let source = common::test_data("bad-inputs", "small-stair.csv");
    let mut text = String::new();
    for (k, line) in std::fs::read_to_string(source).unwrap().lines().enumerate() {
        let added = if k == 0 { header } else { cells };
        text.push_str(&format!("{line},{added}\n"));
    }
    let path = dir.join("stair.csv");
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn a_voltage_and_temperature_under_other_names_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let recording = stair_with(dir.path(), "vbat,Temp_C", "16.2,25.0");
    let model = dir.path().join("m.json");
    let r = common::fit(&recording, model.to_str().unwrap());
    assert!(r.ok, "{}", r.stderr);
    for expected in [
        "column `vbat` is not read: magstand reads the supply voltage in volts as `bat_v`",
        "column `Temp_C` is not read: column names are lower case, as `temp_c`",
    ] {
        assert!(r.stderr.contains(expected), "{expected:?} in {}", r.stderr);
    }
    let r = common::magstand(&[
        "compensate",
        "--model",
        model.to_str().unwrap(),
        "--recording",
        &recording,
        "--out",
        dir.path().join("c.csv").to_str().unwrap(),
    ]);
    assert!(
        r.ok && r.stderr.contains("`vbat` is not read"),
        "{}",
        r.stderr
    );
    let r = common::magstand(&[
        "report",
        "--recording",
        &recording,
        "--model",
        model.to_str().unwrap(),
        "--out",
        dir.path().join("report").to_str().unwrap(),
    ]);
    assert!(
        r.ok && r.stderr.contains("`Temp_C` is not read"),
        "{}",
        r.stderr
    );

    let json = dir.path().join("d.json");
    let r = common::magstand(&[
        "diagnose",
        "--recording",
        &recording,
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let d: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let warnings: Vec<&str> = d["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    assert!(
        warnings[0].contains("`vbat` is not read") && warnings[1].contains("`Temp_C` is not read"),
        "{warnings:#?}"
    );
}

#[test]
fn a_read_column_beside_its_lookalike_is_not_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let recording = stair_with(dir.path(), "bat_v,vbat_raw", "16.2,16.3");
    let r = common::fit(&recording, dir.path().join("m.json").to_str().unwrap());
    assert!(r.ok && !r.stderr.contains("is not read"), "{}", r.stderr);
}
