//! Exports against known answers: a model that is a line gives that line back with PX4's and
//! ArduPilot's units and signs; the C header, compiled by the system compiler, evaluates the
//! same disturbance and sd as the Rust model.
use magstand_core::Vec3;
use magstand_core::rbf::paper_tables;
use magstand_ident::noise_model::SdModel;
use magstand_ident::{InputKind, InputSpec, LocalLinearNet, Model, Structure};
use magstand_logs::export::{ardupilot_params, c_header, linear_approximation, px4_params};

fn throttle_input() -> InputSpec {
    InputSpec {
        kind: InputKind::Throttle,
        lo: 0.0,
        hi: 1.0,
        motors: 4,
        off_raw: 0.0,
    }
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

#[test]
fn a_linear_model_exports_its_own_slope_with_the_autopilots_units_and_signs() {
    let k = [4.0, 10.0, -16.0]; // µT per unit throttle
    let model = Model::new(
        "line",
        throttle_input(),
        Vec3::new(20.0, 0.0, 45.0),
        Structure::Polynomial {
            coefficients: std::array::from_fn(|a| vec![0.0, k[a]]),
        },
        None,
    );
    let line = linear_approximation(&model).unwrap();
    for a in 0..3 {
        assert!((line.slope[a] - k[a]).abs() < 1e-12, "{:?}", line.slope);
        assert!(line.rms_left_ut[a] < 1e-12);
    }
    assert!(
        line.worst_heading_deg < 1e-9 && line.uncompensated_heading_deg > 10.0,
        "{line:?}"
    );
    let ap = ardupilot_params(&line, 1);
    assert_eq!(value(&ap, "COMPASS_MOTCT"), 1.0);
    // ArduPilot: field + COMPASS_MOT x throttle, in mG: -k x 10.
    assert_eq!(value(&ap, "COMPASS_MOT_Z"), 160.0);
    assert_eq!(value(&ardupilot_params(&line, 2), "COMPASS_MOT2_X"), -40.0);
    let px4 = px4_params(&line, 0);
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
    let line = linear_approximation(&amps).unwrap();
    assert!((line.slope[0] - 0.25).abs() < 1e-12);
    assert_eq!(value(&px4_params(&line, 1), "CAL_MAG_COMP_TYP"), 2.0);
    assert!((value(&px4_params(&line, 1), "CAL_MAG1_XCOMP") + 2.5).abs() < 1e-9);
    assert_eq!(value(&ardupilot_params(&line, 1), "COMPASS_MOTCT"), 2.0);
    assert!((value(&ardupilot_params(&line, 1), "COMPASS_MOT_X") + 2.5).abs() < 1e-9);
}

fn paper_model() -> Model {
    let t = paper_tables();
    let net = LocalLinearNet {
        partition: t[0].partition().clone(),
        coefficients: std::array::from_fn(|a| {
            (0..3)
                .map(|i| vec![100.0 * t[a].slopes()[i], 100.0 * t[a].intercepts()[i]])
                .collect()
        }),
    };
    let sd = SdModel {
        knots: (0..11).map(|k| k as f64 / 10.0).collect(),
        sd_ut: std::array::from_fn(|a| {
            (0..11)
                .map(|k| 0.2 + 0.1 * a as f64 + 0.13 * k as f64)
                .collect()
        }),
    };
    Model::new(
        "global",
        throttle_input(),
        Vec3::new(20.0, 1.0, 45.0),
        Structure::LocalLinear(net),
        Some(sd),
    )
}

#[test]
fn a_convex_model_loses_heading_accuracy_in_the_linear_form() {
    let line = linear_approximation(&paper_model()).unwrap();
    assert!(line.rms_left_ut.iter().any(|r| *r > 0.3), "{line:?}");
    assert!(
        line.worst_heading_deg > 0.5 && line.worst_heading_deg < line.uncompensated_heading_deg,
        "{line:?}"
    );
}

#[test]
fn the_c_header_evaluates_the_same_model_as_rust() {
    let cc = ["cc", "gcc", "clang"].into_iter().find(|c| {
        std::process::Command::new(c)
            .arg("--version")
            .output()
            .is_ok()
    });
    let Some(cc) = cc else {
        assert!(std::env::var("CI").is_err(), "CI=true but no C compiler");
        eprintln!("no C compiler: skipping");
        return;
    };
    let model = paper_model();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("magstand_model.h"),
        c_header(&model).unwrap(),
    )
    .unwrap();
    let raws: Vec<f64> = (0..=20).map(|i| -0.05 + i as f64 * 0.0575).collect();
    let main = format!(
        "#include <stdio.h>\n#include \"magstand_model.h\"\nint main(void) {{\n  const double r[] = {{{}}};\n  for (unsigned i = 0; i < sizeof r / sizeof r[0]; i++) {{\n    double d[3], s[3];\n    magstand_dist(r[i], d);\n    magstand_sd(r[i], s);\n    printf(\"%.17g %.17g %.17g %.17g %.17g %.17g\\n\", d[0], d[1], d[2], s[0], s[1], s[2]);\n  }}\n  return 0;\n}}\n",
        raws.iter()
            .map(|r| format!("{r:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    std::fs::write(dir.path().join("main.c"), main).unwrap();
    let exe = dir.path().join("eval");
    let built = std::process::Command::new(cc)
        .args(["-std=c99", "-Wall", "-Werror", "-O2", "-o"])
        .arg(&exe)
        .arg(dir.path().join("main.c"))
        .arg("-lm")
        .output()
        .unwrap();
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let out = std::process::Command::new(&exe).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let mut s = model.scratch();
    for (line, raw) in text.lines().zip(&raws) {
        let v: Vec<f64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        let d = model.dist_at_input(*raw, &mut s);
        let sd = model.sd.as_ref().unwrap().sd(*raw);
        for a in 0..3 {
            assert!(
                (v[a] - d[a]).abs() < 1e-9,
                "dist at {raw} axis {a}: C {} vs Rust {}",
                v[a],
                d[a]
            );
            assert!(
                (v[3 + a] - sd[a]).abs() < 1e-12,
                "sd at {raw} axis {a}: C {} vs Rust {}",
                v[3 + a],
                sd[a]
            );
        }
    }
    assert_eq!(text.lines().count(), raws.len());
}
