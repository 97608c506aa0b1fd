//! Regression: `import` takes a PX4 magnetometer's readings to the body frame through the log's
//! calibration (`R · S · (raw − offset)`: the rotation `CAL_MAGn_ROT`, or `SENS_BOARD_ROT` for
//! an internal sensor, and the scale matrix), so `fit` finds the disturbance's slopes in the
//! body frame. But PX4 adds its power compensation to the raw reading, before that
//! calibration, and `export --to px4` wrote minus the body-frame slopes as `CAL_MAGn_*COMP`.
//! On a board mounted turned by 180 degrees the x and y coefficients had the wrong sign (the
//! compensation doubled the error it was meant to remove), and any scale other than 1 made
//! every coefficient off by it. `import` now writes the transform in `mag_to_body`, `fit`
//! keeps it in the model file, and `export --to px4` maps the slopes back through it; a model
//! of a PX4 sensor without it is refused.
//!
//! The same held for ArduPilot firmware without per-motor compensation (log171, Copter 3.3),
//! which adds its compensation before the compass's soft-iron matrix: `COMPASS_MOT2_*` from
//! log171 were off by that matrix (its diagonal 0.95, 1.05, 1.01). Its import now writes the
//! matrix as the frame, and takes the compensation the vehicle applied out through it.
mod common;
use common::magstand;

use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::{Recording, Vec3};
use magstand_logs::log_writer::{LogWriteOptions, Px4MagCalibration, write_ulog};

/// The value of parameter `name` in a QGroundControl parameter file.
fn param(text: &str, name: &str) -> f64 {
    text.lines()
        .find_map(|l| {
            let f: Vec<&str> = l.split('\t').collect();
            (f.len() == 5 && f[2] == name).then(|| f[3].parse::<f64>().unwrap())
        })
        .unwrap_or_else(|| panic!("no {name} in:\n{text}"))
}

/// The frame `import` wrote in recording `rec`, and the JSON export of the model that
/// `fit --earth fit` makes of the recording (written to `model`).
fn frame_and_export(rec: &str, model: &str) -> (SensorToBody, serde_json::Value) {
    let recording = magstand_core::recording_csv::read(rec).unwrap();
    let frame = SensorToBody::of_recording(&recording, rec.as_ref())
        .unwrap()
        .unwrap_or_else(|| panic!("{rec}: the import wrote no mag_to_body"));
    common::fit_flight(rec, model);
    let r = magstand(&["export", "--model", model, "--to", "json"]);
    assert!(r.ok, "{}", r.stderr);
    (frame, serde_json::from_str(&r.stdout).unwrap())
}

/// The numbers of `keys` in the JSON object `block` as a vector.
fn vector(block: &serde_json::Value, keys: [&str; 3]) -> Vec3 {
    Vec3::from_fn(|a, _| {
        block[keys[a]]
            .as_f64()
            .unwrap_or_else(|| panic!("no number {} in {block}", keys[a]))
    })
}

/// A stand recording whose magnetometer, in its own frame, is disturbed by `raw_g_per_thr`
/// gauss per unit throttle, read in the body frame through `frame`: a stair of 8 steps at
/// 50 Hz, with a small deterministic noise.
fn stand(frame: &SensorToBody, raw_g_per_thr: Vec3) -> Recording {
    let n = 3000;
    let t_s: Vec<f64> = (0..n).map(|r| r as f64 * 0.02).collect();
    let thr: Vec<f64> = t_s
        .iter()
        .map(|&t| {
            if t < 4.0 {
                0.0
            } else {
                (((t - 4.0) / 7.0).floor() + 1.0).min(8.0) * 0.1
            }
        })
        .collect();
    let earth_body = Vec3::new(21.0, -4.0, 43.0);
    let mag_ut = thr
        .iter()
        .enumerate()
        .map(|(r, &u)| {
            let noise = 0.05 * ((r as f64 * 0.37).sin() + (r as f64 * 1.91).cos());
            earth_body + frame.matrix() * (raw_g_per_thr * 100.0 * u) + Vec3::repeat(noise)
        })
        .collect();
    Recording {
        t_s,
        thr: vec![thr; 4],
        mag_ut,
        ..Recording::default()
    }
}

#[test]
fn a_px4_compensation_is_written_in_the_frame_px4_adds_it_in() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    // A board mounted turned by 180 degrees (SENS_BOARD_ROT 4), its internal sensor with
    // offsets and a scale matrix.
    let cal = Px4MagCalibration {
        rotation: -1,
        board_rotation: 4,
        board_trim_deg: [0.0; 3],
        offset_g: [0.08, -0.11, 0.2],
        scale: [1.1, 0.92, 1.04],
        off_diagonal: [0.02, -0.015, 0.01],
    };
    let f = |v: f64| v as f32 as f64;
    let frame = SensorToBody::new([
        [-f(1.1), -f(0.02), f(0.015)],
        [-f(0.02), -f(0.92), -f(0.01)],
        [f(-0.015), f(0.01), f(1.04)],
    ])
    .unwrap();
    let raw = Vec3::new(0.12, -0.08, 0.05);
    let rec = stand(&frame, raw);
    let opts = LogWriteOptions {
        px4_calibration: Some(cal),
        ..LogWriteOptions::default()
    };
    write_ulog(&rec, p("turned.ulg").as_ref(), &opts).unwrap();
    let r = magstand(&["import", "--ulog", &p("turned.ulg"), "--out", &p("r.csv")]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stderr.contains("mag_to_body"), "{}", r.stderr);
    let r = magstand(&[
        "fit",
        "--recording",
        &p("r.csv"),
        "--rbf",
        "3",
        "--model-out",
        &p("m.json"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    let model = std::fs::read_to_string(p("m.json")).unwrap();
    assert!(model.contains("\"magnetometer_to_body\""), "{model}");
    let r = magstand(&["export", "--model", &p("m.json"), "--to", "px4"]);
    assert!(r.ok, "{}", r.stderr);
    let exported = Vec3::new(
        param(&r.stdout, "CAL_MAG0_XCOMP"),
        param(&r.stdout, "CAL_MAG0_YCOMP"),
        param(&r.stdout, "CAL_MAG0_ZCOMP"),
    );
    // PX4 corrects with raw + C x throttle: C is minus the sensor's own disturbance, whatever
    // its calibration. The body-frame slopes, the old export, have x and y of the other sign.
    assert!(
        (exported + raw).abs().max() < 2e-3,
        "exported {exported}, expected {}",
        -raw
    );
    let body = frame.matrix() * raw;
    assert!(
        exported.x * -body.x < 0.0 && exported.y * -body.y < 0.0,
        "exported {exported} has the body frame's signs {}",
        -body
    );
    assert!(r.stdout.contains("sensor's own frame"), "{}", r.stdout);
    // The JSON document's PX4 coefficients are the same.
    let r = magstand(&["export", "--model", &p("m.json"), "--to", "json"]);
    assert!(r.ok, "{}", r.stderr);
    let doc: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    let px4 = &doc["linear"]["px4"];
    for (axis, v) in ["XCOMP", "YCOMP", "ZCOMP"].iter().zip(exported.iter()) {
        let j = px4[axis].as_f64().unwrap();
        assert!((j - v).abs() < 1e-6, "{axis}: json {j}, parameter file {v}");
    }

    // A model of a PX4 sensor that does not say how its readings were turned is refused, and
    // nothing is written.
    let stripped: serde_json::Value = {
        let mut m: serde_json::Value = serde_json::from_str(&model).unwrap();
        m.as_object_mut().unwrap().remove("magnetometer_to_body");
        assert_eq!(m["magnetometer"], "px4:0", "{model}");
        m
    };
    std::fs::write(p("old.json"), stripped.to_string()).unwrap();
    let r = magstand(&[
        "export",
        "--model",
        &p("old.json"),
        "--to",
        "px4",
        "--out",
        &p("old.params"),
    ]);
    assert!(!r.ok, "{}", r.stdout);
    assert!(
        r.stderr.contains("magnetometer_to_body") && r.stderr.contains("old.json"),
        "{}",
        r.stderr
    );
    assert!(!std::path::Path::new(&p("old.params")).exists());
    // So is its JSON document, which holds PX4's coefficients too.
    let r = magstand(&["export", "--model", &p("old.json"), "--to", "json"]);
    assert!(
        !r.ok && r.stderr.contains("magnetometer_to_body") && r.stdout.is_empty(),
        "{}",
        r.stderr
    );
    // ArduPilot adds its compensation in the body frame: its line is the body frame's.
    let r = magstand(&[
        "export",
        "--model",
        &p("m.json"),
        "--to",
        "ardupilot",
        "--instance",
        "1",
    ]);
    assert!(r.ok, "{}", r.stderr);
    let ap: Vec<f64> = ["COMPASS_MOT_X", "COMPASS_MOT_Y", "COMPASS_MOT_Z"]
        .iter()
        .map(|name| {
            r.stdout
                .lines()
                .find_map(|l| l.strip_prefix(&format!("{name},")))
                .unwrap_or_else(|| panic!("{name}: {}", r.stdout))
                .parse()
                .unwrap()
        })
        .collect();
    for (a, (got, want)) in ap.iter().zip((-body * 1000.0).iter()).enumerate() {
        assert!(
            (got - want).abs() < 2.0,
            "axis {a}: {got} mG, expected {want}"
        );
    }
}

/// On a real PX4 log (the FMU-v6C's internal sensor, `CAL_MAG1`, with its own offsets and
/// scale), the exported coefficients taken through the log's calibration give minus the
/// body-frame slopes the line was fitted with, and `mag_to_body` is the log's calibration.
#[test]
fn a_real_px4_logs_coefficients_map_back_to_its_body_frame_slopes() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let log = common::test_data("real-logs", "px4-fmuv6c-quad-local.ulg");
    let r = magstand(&["import", "--ulog", &log, "--mag", "1", "--out", &p("r.csv")]);
    assert!(r.ok, "{}", r.stderr);
    let (frame, doc) = frame_and_export(&p("r.csv"), &p("m.json"));
    let slope_ut = Vec3::from_fn(|a, _| doc["linear"]["slope_ut"][a].as_f64().unwrap());
    let px4 = vector(&doc["linear"]["px4"], ["XCOMP", "YCOMP", "ZCOMP"]);
    let rows = doc["model"]["magnetometer_to_body"].clone();
    let named: [[f64; 3]; 3] = serde_json::from_value(rows).unwrap();
    assert_eq!(named, frame.rows(), "the model's frame is the recording's");
    let back = frame.matrix() * px4;
    // Gauss per unit throttle: minus the slope in µT over 100.
    assert!(
        (back + slope_ut / 100.0).abs().max() < 1e-9,
        "M · C = {back}, slopes {slope_ut} µT"
    );
    assert!(
        !frame.is_identity(),
        "the log's calibration has a scale: {frame}"
    );
}

/// ArduPilot Copter 3.3 (log171, no per-motor compensation) adds its compensation before the
/// compass's soft-iron matrix: the import writes compass 2's matrix as `mag_to_body`, and the
/// exported `COMPASS_MOT2_*` taken through it give minus the body-frame slopes (in mG).
#[test]
fn older_ardupilots_coefficients_are_written_before_its_soft_iron_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    let log = common::test_data("real-logs", "ardupilot-log171-quad.bin");
    let r = magstand(&[
        "import",
        "--dataflash",
        &log,
        "--mag",
        "1",
        "--to-s",
        "238",
        "--out",
        &p("r.csv"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stderr.contains("soft-iron"), "{}", r.stderr);
    let (frame, doc) = frame_and_export(&p("r.csv"), &p("m.json"));

    // COMPASS_DIA2_* and COMPASS_ODI2_* as log171 holds them (single precision).
    let (dx, dy, dz) = (0.950_695_63_f32, 1.050_159_f32, 1.006_840_7_f32);
    let (ox, oy, oz) = (-0.017_186_347_f32, 0.017_151_59_f32, -0.011_333_506_f32);
    let [dx, dy, dz, ox, oy, oz] = [dx, dy, dz, ox, oy, oz].map(f64::from);
    let want = magstand_core::Mat3::new(dx, ox, oy, ox, dy, oz, oy, oz, dz);
    assert!(
        (frame.matrix() - want).abs().max() == 0.0,
        "mag_to_body {frame}, the log's compass 2 matrix {want}"
    );
    let slope_ut = Vec3::from_fn(|a, _| doc["linear"]["slope_ut"][a].as_f64().unwrap());
    let mot = vector(
        &doc["linear"]["ardupilot"],
        ["COMPASS_MOT_X", "COMPASS_MOT_Y", "COMPASS_MOT_Z"],
    );
    let back = frame.matrix() * mot;
    // mG per unit throttle: minus ten times the slope in µT.
    assert!(
        (back + slope_ut * 10.0).abs().max() < 1e-9,
        "M · C = {back}, slopes {slope_ut} µT"
    );
    // The parameter file writes the same values, rounded, for compass 2.
    let r = magstand(&["export", "--model", &p("m.json"), "--to", "ardupilot"]);
    assert!(r.ok, "{}", r.stderr);
    for (name, v) in ["COMPASS_MOT2_X", "COMPASS_MOT2_Y", "COMPASS_MOT2_Z"]
        .iter()
        .zip(mot.iter())
    {
        let written: f64 = r
            .stdout
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{name},")))
            .unwrap_or_else(|| panic!("{name}: {}", r.stdout))
            .parse()
            .unwrap();
        assert!((written - v).abs() < 6e-4, "{name}: {written} against {v}");
    }
    assert!(r.stdout.contains("soft-iron"), "{}", r.stdout);
    // That firmware has no per-motor compensation to write, on compass 1 (the only one
    // ArduPilot applies it to) either.
    let r = magstand(&[
        "import",
        "--dataflash",
        &log,
        "--mag",
        "0",
        "--to-s",
        "238",
        "--out",
        &p("first.csv"),
    ]);
    assert!(r.ok, "{}", r.stderr);
    frame_and_export(&p("first.csv"), &p("first.json"));
    let r = magstand(&[
        "export",
        "--model",
        &p("first.json"),
        "--to",
        "ardupilot-per-motor",
        "--recording",
        &p("first.csv"),
        "--out",
        &p("pmot.param"),
    ]);
    assert!(
        !r.ok && r.stderr.contains("COMPASS_PMOT_EN"),
        "{}",
        r.stderr
    );
    assert!(!std::path::Path::new(&p("pmot.param")).exists());
}
