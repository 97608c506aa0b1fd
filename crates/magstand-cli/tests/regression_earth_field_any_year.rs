//! Regression: `fit --earth wmm` covered 2020 to 2029 only, so the 2015 log171 could not be
//! fitted against a reference field, and the error said "cannot export" although nothing was
//! being exported. IGRF-13 now covers 1900 to 2020; a year outside both models is an error
//! that names the year and the years covered.
mod common;

#[test]
fn a_2015_log_is_fitted_against_igrf() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    let log = common::test_data("real-logs", "ardupilot-log171-quad.bin");
    let log = log.as_str();
    let r = common::magstand(&["import", "--dataflash", log, "--out", rec.to_str().unwrap()]);
    assert!(r.ok, "{}", r.stderr);
    let model = dir.path().join("m.json");
    let fit = |year: &str| {
        common::magstand(&[
            "fit",
            "--recording",
            rec.to_str().unwrap(),
            "--model-out",
            model.to_str().unwrap(),
            "--earth",
            "wmm",
            "--lat",
            "-35.362",
            "--lon",
            "149.166",
            "--year",
            year,
        ])
    };
    let r = fit("2015.87");
    assert!(r.ok, "{}", r.stderr);
    // Canberra, late 2015: about 58 µT, inclination about -66 degrees (IGRF).
    assert!(
        r.stdout.contains("Earth field (IGRF-13)") && r.stdout.contains("inclination -66."),
        "{}",
        r.stdout
    );
    std::fs::remove_file(&model).unwrap();
    let r = fit("1850");
    assert!(
        !r.ok
            && r.stderr.contains("1850")
            && r.stderr.contains("1900")
            && !r.stderr.contains("export"),
        "{}",
        r.stderr
    );
    assert!(!model.exists());
}
