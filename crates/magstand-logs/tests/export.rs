//! Exports against known answers: a model that is a line gives that line back with PX4's and
//! ArduPilot's units and signs; the C header, compiled by the system compiler, evaluates the
//! same disturbance and sd as the Rust model.
use magstand_core::{Recording, Vec3};
use magstand_ident::noise_model::SdModel;
use magstand_ident::{InputKind, InputSpec, LocalLinearNet, Model, Structure};
mod common;
use common::{c_compiler, run_c, run_no_std_rust, throttle_input};
use magstand_logs::export::json::export_json;
use magstand_logs::export::per_motor::{per_motor_fit, per_motor_params};
use magstand_logs::export::{
    LineInput, LinearFit, Span, ardupilot_params, c_header, linear_approximation, px4_params,
    rust_module,
};

fn line_of(model: &Model) -> Result<LinearFit, magstand_logs::LogsError> {
    linear_approximation(model, LineInput::of(model), Span::ModelRange)
}

fn value(text: &str, name: &str) -> f64 {
    text.lines()
        .find_map(|l| {
            let cells: Vec<&str> = l.split([',', '\t']).collect();
            let i = cells.iter().position(|c| *c == name)?;
            cells.get(i + 1)?.parse().ok()
        })
        .unwrap_or_else(|| panic!("{name} not in\n{text}"))
}

/// A model of the overall throttle that is exactly the line `k x throttle` µT.
fn throttle_line_model(k: [f64; 3]) -> Model {
    Model::new(
        "line",
        throttle_input(),
        Vec3::new(20.0, 0.0, 45.0),
        Structure::Polynomial {
            coefficients: std::array::from_fn(|a| vec![0.0, k[a]]),
        },
        None,
    )
}

#[test]
fn a_linear_model_exports_its_own_slope_with_the_autopilots_units_and_signs() {
    let k = [4.0, 10.0, -16.0]; // µT per unit throttle
    let model = throttle_line_model(k);
    let line = line_of(&model).unwrap();
    for a in 0..3 {
        assert!((line.slope[a] - k[a]).abs() < 1e-12, "{:?}", line.slope);
        assert!(line.rms_left_ut[a] < 1e-12);
    }
    assert!(
        line.worst_heading_deg < 1e-9 && line.uncompensated_heading_deg > 10.0,
        "{line:?}"
    );
    let ap = ardupilot_params(&line, 1, None).unwrap();
    assert_eq!(value(&ap, "COMPASS_MOTCT"), 1.0);
    // ArduPilot: field + COMPASS_MOT x throttle, in mG: -k x 10.
    assert_eq!(value(&ap, "COMPASS_MOT_Z"), 160.0);
    assert_eq!(
        value(&ardupilot_params(&line, 2, None).unwrap(), "COMPASS_MOT2_X"),
        -40.0
    );
    let px4 = px4_params(&line, 0, None).unwrap();
    assert_eq!(value(&px4, "CAL_MAG_COMP_TYP"), 1.0);
    // PX4: mag + coefficient x throttle, in gauss: -k x 0.01.
    assert!((value(&px4, "CAL_MAG0_YCOMP") + 0.1).abs() < 1e-9, "{px4}");

    // Current input: per kA for PX4, per A for ArduPilot.
    let mut amps = model.clone();
    amps.input = InputSpec {
        kind: InputKind::Current,
        hi: 60.0,
        ..throttle_input()
    };
    if let Structure::Polynomial { coefficients } = &mut amps.structure {
        // 0.25 µT/A: the normalized input is A / 60.
        *coefficients = std::array::from_fn(|_| vec![0.0, 0.25 * 60.0]);
    }
    let line = line_of(&amps).unwrap();
    assert!((line.slope[0] - 0.25).abs() < 1e-12);
    assert_eq!(
        value(&px4_params(&line, 1, None).unwrap(), "CAL_MAG_COMP_TYP"),
        2.0
    );
    assert!((value(&px4_params(&line, 1, None).unwrap(), "CAL_MAG1_XCOMP") + 2.5).abs() < 1e-9);
    assert_eq!(
        value(&ardupilot_params(&line, 1, None).unwrap(), "COMPASS_MOTCT"),
        2.0
    );
    assert!(
        (value(&ardupilot_params(&line, 1, None).unwrap(), "COMPASS_MOT_X") + 2.5).abs() < 1e-9
    );
}

/// The paper's tables with a noise model growing with throttle.
fn paper_model() -> Model {
    let sd = SdModel {
        knots: (0..11).map(|k| k as f64 / 10.0).collect(),
        sd_ut: std::array::from_fn(|a| {
            (0..11)
                .map(|k| 0.2 + 0.1 * a as f64 + 0.13 * k as f64)
                .collect()
        }),
    };
    common::paper_model(Some(sd))
}

#[test]
fn a_convex_model_loses_heading_accuracy_in_the_linear_form() {
    let line = line_of(&paper_model()).unwrap();
    assert!(line.rms_left_ut.iter().any(|r| *r > 0.3), "{line:?}");
    assert!(
        line.worst_heading_deg > 0.5 && line.worst_heading_deg < line.uncompensated_heading_deg,
        "{line:?}"
    );
    assert!(
        line.p95_heading_deg <= line.worst_heading_deg
            && line.p95_heading_deg < line.uncompensated_p95_heading_deg
            && line.uncompensated_p95_heading_deg <= line.uncompensated_heading_deg,
        "{line:?}"
    );
}

/// Raw inputs the firmware tests evaluate at: below, across and above the model's range.
fn firmware_raws() -> Vec<f64> {
    (0..=20).map(|i| -0.05 + i as f64 * 0.0575).collect()
}

/// Checks lines of `dx dy dz sdx sdy sdz` printed by compiled firmware code at `raws` against
/// the Rust model.
fn assert_matches_model(text: &str, raws: &[f64], model: &Model, what: &str) {
    let mut s = model.scratch();
    assert_eq!(text.lines().count(), raws.len(), "{what} printed:\n{text}");
    for (line, raw) in text.lines().zip(raws) {
        let v: Vec<f64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        let d = model.dist_at_input(*raw, &mut s);
        let sd = model.sd.as_ref().unwrap().sd(*raw);
        for a in 0..3 {
            assert!(
                (v[a] - d[a]).abs() < 1e-9,
                "{what}: dist at {raw} axis {a}: {} vs Rust {}",
                v[a],
                d[a]
            );
            assert!(
                (v[3 + a] - sd[a]).abs() < 1e-12,
                "{what}: sd at {raw} axis {a}: {} vs Rust {}",
                v[3 + a],
                sd[a]
            );
        }
    }
}

fn number_list(raws: &[f64]) -> String {
    raws.iter()
        .map(|r| format!("{r:e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

#[test]
fn the_c_header_evaluates_the_same_model_as_rust() {
    let Some(cc) = c_compiler() else {
        return;
    };
    let model = paper_model();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("magstand_model.h"),
        c_header(&model).unwrap(),
    )
    .unwrap();
    let raws = firmware_raws();
    let main = format!(
        "#include <stdio.h>\n#include \"magstand_model.h\"\nint main(void) {{\n  const double r[] = {{{}}};\n  for (unsigned i = 0; i < sizeof r / sizeof r[0]; i++) {{\n    double d[3], s[3];\n    magstand_dist(r[i], d);\n    magstand_sd(r[i], s);\n    printf(\"%.17g %.17g %.17g %.17g %.17g %.17g\\n\", d[0], d[1], d[2], s[0], s[1], s[2]);\n  }}\n  return 0;\n}}\n",
        number_list(&raws)
    );
    let text = run_c(cc, dir.path(), &main);
    assert_matches_model(&text, &raws, &model, "C header");
}

#[test]
fn the_rust_module_builds_without_std_and_evaluates_the_same_model() {
    let model = paper_model();
    let dir = tempfile::tempdir().unwrap();
    let raws = firmware_raws();
    let main = format!(
        "mod magstand_model;\nfn main() {{\n    for r in [{}] {{\n        let (d, s) = (magstand_model::dist_ut(r), magstand_model::sd_ut(r));\n        println!(\"{{:e}} {{:e}} {{:e}} {{:e}} {{:e}} {{:e}}\", d[0], d[1], d[2], s[0], s[1], s[2]);\n    }}\n}}\n",
        number_list(&raws)
    );
    // As a module of a no_std library, with every warning an error, then evaluated by a host
    // program.
    let text = run_no_std_rust(
        dir.path(),
        "magstand_model",
        &rust_module(&model).unwrap(),
        &main,
    );
    assert_matches_model(&text, &raws, &model, "Rust module");
}

/// A recording of `n` rows with four motors commanded unequally (as in a flight), a sagging
/// battery and a current proportional to the overall throttle (50 A at full throttle).
fn flight_like_recording(n: usize, volts: impl Fn(usize) -> f64) -> Recording {
    let thr: Vec<Vec<f64>> = (0..4)
        .map(|m| {
            (0..n)
                .map(|r| {
                    let t = r as f64 * 0.02;
                    let f = 0.7 + 0.23 * m as f64; // distinct per motor, so no motor is a mix of the others
                    (0.45 + 0.3 * (f * t + 1.3 * m as f64).sin() * (0.11 * t).cos()).clamp(0.0, 1.0)
                })
                .collect()
        })
        .collect();
    let mut rec = Recording {
        t_s: (0..n).map(|r| r as f64 * 0.02).collect(),
        mag_ut: vec![Vec3::new(20.0, 1.0, 45.0); n],
        bat_v: Some((0..n).map(volts).collect()),
        thr,
        ..Default::default()
    };
    rec.bat_a = Some((0..n).map(|r| 50.0 * rec.overall_throttle(r)).collect());
    rec
}

/// A per-motor model whose disturbance is exactly `sum_i k[i] p_i` µT.
fn per_motor_line_model(k: [[f64; 3]; 4]) -> Model {
    let net = LocalLinearNet {
        partition: magstand_core::rbf::RbfPartition::new(vec![0.5], vec![1.0]).unwrap(),
        coefficients: std::array::from_fn(|a| vec![vec![k[0][a], k[1][a], k[2][a], k[3][a], 0.0]]),
    };
    Model::new(
        "per-motor line",
        InputSpec {
            kind: InputKind::Motors,
            ..throttle_input()
        },
        Vec3::new(20.0, 1.0, 45.0),
        Structure::LocalLinear(net),
        None,
    )
}

#[test]
fn the_per_motor_set_recovers_each_motors_own_coefficient() {
    let k = [
        [2.0, -1.0, 6.0],
        [-3.0, 0.5, 4.0],
        [1.0, 2.5, 8.0],
        [0.0, -2.0, 5.0],
    ];
    let model = per_motor_line_model(k);
    // A constant 12 V: the form sum c_i (12 p_i)^e is exact only at e = 1, c_i = -10 k_i / 12.
    let rec = flight_like_recording(3000, |_| 12.0);
    let fit = per_motor_fit(&model, &rec, "flight.csv").unwrap();
    assert!((fit.expo - 1.0).abs() < 1e-3, "{fit:?}");
    for (i, c) in fit.compensation_mg.iter().enumerate() {
        for a in 0..3 {
            let want = -10.0 * k[i][a] / 12.0;
            assert!(
                (c[a] - want).abs() < 2e-3 * want.abs().max(1.0),
                "motor {i} axis {a}: {} vs {want}",
                c[a]
            );
        }
    }
    assert!(fit.rms_left_ut.iter().all(|r| *r < 1e-2), "{fit:?}");
    let text = per_motor_params(&fit);
    assert_eq!(value(&text, "COMPASS_PMOT_EN"), 1.0);
    assert!(
        (value(&text, "COMPASS_PMOT3_Z") + 80.0 / 12.0).abs() < 0.02,
        "{text}"
    );
}

#[test]
fn the_per_motor_set_is_refused_when_it_cannot_be_identified() {
    let model = per_motor_line_model([[1.0, 0.0, 2.0]; 4]);
    // Motors in step (a stair test): no per-motor information.
    let mut rec = flight_like_recording(500, |_| 12.0);
    let first = rec.thr[0].clone();
    for m in rec.thr.iter_mut() {
        *m = first.clone();
    }
    let err = per_motor_fit(&model, &rec, "stair.csv")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("stair.csv") && err.contains("not identifiable"),
        "{err}"
    );
    // No battery voltage.
    let mut no_v = flight_like_recording(500, |_| 12.0);
    no_v.bat_v = None;
    let err = per_motor_fit(&model, &no_v, "nov.csv")
        .unwrap_err()
        .to_string();
    assert!(err.contains("bat_v"), "{err}");
    // A model of the overall throttle has no per-motor information either.
    let err = per_motor_fit(
        &paper_model(),
        &flight_like_recording(500, |_| 12.0),
        "f.csv",
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("per-motor model"), "{err}");
}

#[test]
fn a_throttle_model_exports_a_line_per_ampere_over_a_recordings_rows() {
    let k = [4.0, 10.0, -16.0]; // µT per unit throttle
    let model = throttle_line_model(k);
    // The recording's current is 50 A x throttle, so the slope per ampere is k / 50.
    let rec = flight_like_recording(1000, |r| 12.0 - r as f64 * 1e-3);
    let span = Span::Rows {
        recording: &rec,
        origin: "f.csv",
    };
    let line = linear_approximation(&model, LineInput::Current, span).unwrap();
    for a in 0..3 {
        assert!((line.slope[a] - k[a] / 50.0).abs() < 1e-9, "{line:?}");
    }
    assert_eq!(
        value(&ardupilot_params(&line, 1, None).unwrap(), "COMPASS_MOTCT"),
        2.0
    );
    // Without a recording, a line per ampere of a throttle model is refused with the way out.
    let err = linear_approximation(&model, LineInput::Current, Span::ModelRange)
        .unwrap_err()
        .to_string();
    assert!(err.contains("`recording`"), "{err}");
    // ArduPilot's interference: |slope| x top of range over 530 mG.
    let expected = Vec3::from(k).norm() / 50.0 * line.range_max / 53.0 * 100.0;
    assert!((line.ardupilot_interference_pct() - expected).abs() < 1e-9);
}

#[test]
fn the_json_document_carries_the_table_and_the_autopilot_values() {
    let model = paper_model();
    let line = line_of(&model).unwrap();
    let text = export_json(&model, &line, None).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["format"], "magstand-export");
    assert_eq!(doc["version"], 1);
    let input = doc["table"]["input"].as_array().unwrap();
    let dist_z = doc["table"]["dist_ut"][2].as_array().unwrap();
    assert_eq!(input.len(), dist_z.len());
    let mut s = model.scratch();
    for (x, d) in input.iter().zip(dist_z).step_by(37) {
        let x = x.as_f64().unwrap();
        assert_eq!(d.as_f64().unwrap(), model.dist_at_input(x, &mut s)[2]);
    }
    let px4 = px4_params(&line, 0, None).unwrap();
    let z = doc["linear"]["px4"]["ZCOMP"].as_f64().unwrap();
    assert!(
        (z - value(&px4, "CAL_MAG0_ZCOMP")).abs() < 1e-6,
        "{z} vs\n{px4}"
    );
    assert!(doc["per_motor"].is_null());
}
