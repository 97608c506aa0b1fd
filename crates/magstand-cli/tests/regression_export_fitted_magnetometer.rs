//! Regression: `import --mag 1` of an ArduPilot log reads its second compass (MAG2, the
//! internal one the motors disturb), but nothing carried that to `export`: `fit` then
//! `export --to ardupilot` wrote `COMPASS_MOT_*`, the first compass's parameters (on log171 an
//! external one), and `--to px4` wrote `CAL_MAG0_*COMP`, silently. A compensation loaded into
//! another sensor's parameters corrects that sensor by a field it does not see. `import` now
//! writes the magnetometer's parameter set in the recording's `mag_slot` column, `fit` keeps
//! it in the model file, and `export` writes that set's parameters: `--instance` may only
//! repeat it, the other firmware's numbering needs `--instance`, and a recording of another
//! sensor is refused (by `compensate` too).
mod common;
use common::magstand;

#[test]
fn an_export_writes_the_parameters_of_the_magnetometer_the_model_was_fitted_on() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let log = common::test_data("real-logs", "ardupilot-log171-quad.bin");
    for (mag, slot) in [("1", "ardupilot:2"), ("2", "ardupilot:3")] {
        let r = magstand(&[
            "import",
            "--dataflash",
            &log,
            "--out",
            &p(&format!("mag{mag}.csv")),
            "--mag",
            mag,
        ]);
        assert!(r.ok, "{}", r.stderr);
        // The import's summary is on stderr.
        assert!(
            r.stderr.contains(&format!("`mag_slot` = {slot}")),
            "--mag {mag}: {}",
            r.stderr
        );
    }
    let (rec, other) = (p("mag1.csv"), p("mag2.csv"));
    let model = p("m.json");
    common::fit_flight(&rec, &model);
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(
        text.contains("\"magnetometer\": \"ardupilot:2\""),
        "the model file does not name its magnetometer"
    );
    let export = |extra: &[&str]| {
        let mut args = vec!["export", "--model", model.as_str()];
        args.extend(extra);
        magstand(&args)
    };
    // A throttle line from a flight log is said to be in the motor outputs' space, which the
    // autopilot's thrust curve maps to its own throttle; the current is not.
    let warned = |r: &common::Run| r.stderr.contains("thrust demand");
    let r = export(&["--to", "ardupilot"]);
    assert!(r.ok && warned(&r), "{}", r.stderr);
    let r = export(&[
        "--to",
        "ardupilot",
        "--input",
        "current",
        "--recording",
        &rec,
    ]);
    assert!(r.ok && !warned(&r), "{}", r.stderr);
    // Without --instance, and with the same one: compass 2's parameters only.
    for extra in [
        &["--to", "ardupilot"][..],
        &["--to", "ardupilot", "--instance", "2"],
    ] {
        let r = export(extra);
        assert!(r.ok, "{extra:?}: {}", r.stderr);
        let names: Vec<&str> = r
            .stdout
            .lines()
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| l.split(',').next())
            .collect();
        assert_eq!(
            names,
            [
                "COMPASS_MOTCT",
                "COMPASS_MOT2_X",
                "COMPASS_MOT2_Y",
                "COMPASS_MOT2_Z"
            ],
            "{extra:?}: {}",
            r.stdout
        );
    }
    // Another compass, the other firmware without its numbering, per-motor (first compass
    // only), and a recording of another sensor: refused, nothing written.
    let out = p("refused.params");
    for (extra, says) in [
        (
            &["--to", "ardupilot", "--instance", "1"][..],
            "fitted on the magnetometer of ArduPilot's compass 2",
        ),
        (&["--to", "px4"][..], "Give --instance"),
        (
            &["--to", "ardupilot-per-motor", "--recording", &rec][..],
            "first compass only",
        ),
        (
            &["--to", "ardupilot", "--recording", &other][..],
            "\"ardupilot:3\" is not the magnetometer the model was fitted on",
        ),
    ] {
        let mut args = extra.to_vec();
        args.extend(["--out", out.as_str()]);
        let r = export(&args);
        assert!(
            !r.ok && r.stderr.contains(says),
            "{extra:?}: exit ok = {}, stderr: {}",
            r.ok,
            r.stderr
        );
        assert!(
            !std::path::Path::new(&out).exists(),
            "{extra:?} wrote {out}"
        );
    }
    // The JSON document for other tools names the sensor its lines belong to.
    let r = export(&["--to", "json"]);
    assert!(
        r.ok && r.stdout.contains("\"magnetometer\": \"ardupilot:2\""),
        "{}",
        r.stderr
    );
    // Compensating another sensor's recording with the model is refused too.
    let r = magstand(&[
        "compensate",
        "--model",
        &model,
        "--recording",
        &other,
        "--out",
        &out,
    ]);
    assert!(
        !r.ok && r.stderr.contains("mag_slot") && r.stderr.contains("another sensor"),
        "{}",
        r.stderr
    );
    assert!(
        !std::path::Path::new(&out).exists(),
        "compensate wrote {out}"
    );
    // A diagnosis's model file keeps the sensor too.
    let physics = p("physics.json");
    let r = magstand(&["diagnose", "--recording", &rec, "--model-out", &physics]);
    assert!(r.ok, "{}", r.stderr);
    let text = std::fs::read_to_string(&physics).unwrap();
    assert!(
        text.contains("\"magnetometer\": \"ardupilot:2\""),
        "the diagnosis's model file does not name its magnetometer"
    );
    let r = magstand(&[
        "compensate",
        "--model",
        &physics,
        "--recording",
        &other,
        "--out",
        &out,
    ]);
    assert!(!r.ok && r.stderr.contains("another sensor"), "{}", r.stderr);
    // Told which PX4 slot that sensor is, the PX4 parameters are that slot's.
    let r = export(&["--to", "px4", "--instance", "1"]);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stdout.contains("CAL_MAG1_XCOMP") && !r.stdout.contains("CAL_MAG0"),
        "{}",
        r.stdout
    );
}

/// A PX4 log's magnetometer is matched to its calibration slot by device id
/// (`CAL_MAGn_ID`): on the FMU-v6C log the first internal sensor is `sensor_mag[1]`, slot 1.
#[test]
fn a_px4_import_names_the_calibration_slot_of_its_sensor() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("v6c.csv");
    let log = common::test_data("real-logs", "px4-fmuv6c-quad-local.ulg");
    let r = magstand(&["import", "--ulog", &log, "--out", rec.to_str().unwrap()]);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stderr.contains("sensor_mag[1]") && r.stderr.contains("`mag_slot` = px4:1"),
        "{}",
        r.stderr
    );
    let text = std::fs::read_to_string(&rec).unwrap();
    let header = text.lines().next().unwrap_or_default();
    let column = header.split(',').position(|c| c == "mag_slot");
    let column = column.unwrap_or_else(|| panic!("no mag_slot column in {header}"));
    assert!(
        text.lines()
            .skip(1)
            .all(|l| l.split(',').nth(column) == Some("px4:1")),
        "a row without px4:1"
    );
}
