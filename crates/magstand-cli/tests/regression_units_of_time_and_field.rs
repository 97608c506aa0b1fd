//! Regression: `fit` of a recording whose rows lie further apart than a held-out block (the
//! bad input `time-in-microseconds.csv`, a stair with `t_s` times 1e6, a row every 20,000 s)
//! held out no row at all. The split numbered its 1 s blocks by time, so every row's block was
//! a multiple of 20,000, and every fifth block, the held-out one, held none. `fit` then chose
//! its model on "0 held-out rows in 0 time blocks", printed an error of 0.0000 µT for every
//! family, and exited 0. Blocks are now numbered in the order they hold rows. And nothing said
//! that times in microseconds, or a field in gauss, are not what the columns' names state:
//! `fit`, `diagnose` and `compensate` now warn where the rows are more than 2 s apart or the
//! field's magnitude is beyond a factor 5 of the Earth's.
mod common;

#[test]
fn a_clock_in_microseconds_still_holds_rows_out_and_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    let recording = common::test_data("bad-inputs", "time-in-microseconds.csv");
    let r = common::fit(&recording, model.to_str().unwrap());
    assert!(r.ok, "{}", r.stderr);
    // 1,050 rows, one a block: every fifth held out.
    assert!(
        r.stdout
            .contains("judged on 210 held-out rows in 210 time blocks"),
        "{}",
        r.stdout
    );
    assert!(
        r.stderr.contains("rows are 20000.0000 s apart") && r.stderr.contains("microseconds"),
        "{}",
        r.stderr
    );
}

#[test]
fn a_field_in_gauss_is_warned_about_and_one_in_microtesla_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let source = common::test_data("bad-inputs", "small-stair.csv");
    let text = std::fs::read_to_string(&source).unwrap();
    // The same stair with its field in gauss (µT / 100) under the same column names.
    let mut gauss = String::new();
    for (k, line) in text.lines().enumerate() {
        if k == 0 {
            gauss.push_str(line);
        } else {
            let cells: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(c, v)| match c {
                    5..=7 => format!("{:.6}", v.parse::<f64>().unwrap() / 100.0),
                    _ => v.to_string(),
                })
                .collect();
            gauss.push_str(&cells.join(","));
        }
        gauss.push('\n');
    }
    let in_gauss = dir.path().join("gauss.csv");
    std::fs::write(&in_gauss, gauss).unwrap();
    let fit = |recording: &str| common::fit(recording, dir.path().join("m.json").to_str().unwrap());
    let r = fit(in_gauss.to_str().unwrap());
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stderr.contains("median magnitude is 0.") && r.stderr.contains("1 gauss = 100 µT"),
        "{}",
        r.stderr
    );
    let r = fit(&source);
    assert!(r.ok, "{}", r.stderr);
    assert!(!r.stderr.contains("warning"), "{}", r.stderr);
    // A model in microtesla applied to the field in gauss: the same warning.
    let r = common::magstand(&[
        "compensate",
        "--model",
        dir.path().join("m.json").to_str().unwrap(),
        "--recording",
        in_gauss.to_str().unwrap(),
        "--out",
        dir.path().join("c.csv").to_str().unwrap(),
    ]);
    assert!(
        r.ok && r.stderr.contains("1 gauss = 100 µT"),
        "{}",
        r.stderr
    );

    let r = common::magstand(&[
        "diagnose",
        "--recording",
        in_gauss.to_str().unwrap(),
        "--json",
        dir.path().join("d.json").to_str().unwrap(),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let d: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("d.json")).unwrap()).unwrap();
    let first = d["warnings"][0].as_str().unwrap_or_default();
    assert!(first.contains("1 gauss = 100 µT"), "{d:#}");
}
