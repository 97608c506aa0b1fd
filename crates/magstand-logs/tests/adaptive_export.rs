//! The recursive estimation exported as firmware code (`magstand export --to c-adaptive` and
//! `--to rust-adaptive`) runs the same recursion as `magstand compensate --adapt`: compiled
//! and fed the same samples, it predicts the same disturbance, sample after sample, as
//! [`magstand_ident::adaptive::Adaptive`].
use magstand_core::Vec3;
use magstand_ident::adaptive::{AdaptConfig, Adaptive, ValidAdaptConfig};
use magstand_ident::{Model, Structure};
use magstand_logs::export::{c_adaptive, rust_adaptive};
mod common;
use common::{c_compiler, run_c, run_no_std_rust};

fn paper_model() -> Model {
    common::paper_model(None)
}

/// Samples of a stair whose disturbance is 1.2 times the model's (a drifted gain), with a
/// deterministic wobble for noise, and motors-off rows between the levels.
fn samples(model: &Model) -> Vec<(f64, [f64; 3])> {
    let mut s = model.scratch();
    (0..900)
        .map(|k| {
            let raw = if k % 150 < 20 {
                0.0
            } else {
                ((k / 150) as f64 + 1.0) / 6.5
            };
            let d = 1.2 * model.dist_at_input(raw, &mut s);
            let wobble = 0.3 * (k as f64 * 0.7).sin();
            let m = Vec3::from(model.reference_ut) + d + Vec3::repeat(wobble);
            (raw, [m.x, m.y, m.z])
        })
        .collect()
}

fn expected(model: &Model, cfg: &ValidAdaptConfig, input: &[(f64, [f64; 3])]) -> Vec<Vec3> {
    let mut state = Adaptive::new(model, cfg).unwrap();
    let reference = Vec3::from(model.reference_ut);
    input
        .iter()
        .map(|(raw, m)| state.step(*raw, Vec3::from(*m) - reference))
        .collect()
}

fn assert_same(text: &str, want: &[Vec3], what: &str) {
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), want.len(), "{what}: {} lines", lines.len());
    for (k, (line, w)) in lines.iter().zip(want).enumerate() {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        for a in 0..3 {
            assert!(
                (v[a] - w[a]).abs() <= 1e-9 * (1.0 + w[a].abs()),
                "{what}: sample {k} axis {a}: {} vs Rust {}",
                v[a],
                w[a]
            );
        }
    }
    // The recursion did adapt: the last prediction moved towards the drifted disturbance.
    assert!(want.first() != want.last());
}

fn sample_table(input: &[(f64, [f64; 3])], open: &str, close: &str) -> String {
    input
        .iter()
        .map(|(r, m)| format!("{open}{r:e}, {:e}, {:e}, {:e}{close}", m[0], m[1], m[2]))
        .collect::<Vec<_>>()
        .join(", ")
}

#[test]
fn the_c_recursion_predicts_what_the_rust_one_does() {
    let Some(cc) = c_compiler() else {
        return;
    };
    let model = paper_model();
    let cfg = AdaptConfig { forgetting: 0.98 }.check().unwrap();
    let input = samples(&model);
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("magstand_adapt.h"),
        c_adaptive(&model, &cfg).unwrap(),
    )
    .unwrap();
    let main = format!(
        "#include <stdio.h>\n#include \"magstand_adapt.h\"\nint main(void) {{\n  static const double in[][4] = {{{}}};\n  magstand_adapt_state s;\n  magstand_adapt_init(&s);\n  for (unsigned i = 0; i < sizeof in / sizeof in[0]; i++) {{\n    double d[3];\n    magstand_adapt_step(&s, in[i][0], &in[i][1], d);\n    printf(\"%.17g %.17g %.17g\\n\", d[0], d[1], d[2]);\n  }}\n  return 0;\n}}\n",
        sample_table(&input, "{", "}")
    );
    let text = run_c(cc, dir.path(), &main);
    assert_same(&text, &expected(&model, &cfg, &input), "C");
}

#[test]
fn the_no_std_rust_recursion_predicts_what_magstand_does() {
    let model = paper_model();
    let cfg = AdaptConfig { forgetting: 0.98 }.check().unwrap();
    let input = samples(&model);
    let dir = tempfile::tempdir().unwrap();
    let main = format!(
        "mod magstand_adapt;\nfn main() {{\n    let mut s = magstand_adapt::State::new();\n    for x in [{}] {{\n        let d = s.step(x[0], [x[1], x[2], x[3]]);\n        println!(\"{{:e}} {{:e}} {{:e}}\", d[0], d[1], d[2]);\n    }}\n}}\n",
        sample_table(&input, "[", "]")
    );
    let text = run_no_std_rust(
        dir.path(),
        "magstand_adapt",
        &rust_adaptive(&model, &cfg).unwrap(),
        &main,
    );
    assert_same(&text, &expected(&model, &cfg, &input), "Rust");
}

#[test]
fn models_the_recursion_cannot_update_are_refused_by_name() {
    let mut model = paper_model();
    model.structure = Structure::Polynomial {
        coefficients: std::array::from_fn(|_| vec![0.0, 1.0]),
    };
    let cfg = AdaptConfig::default().check().unwrap();
    let e = c_adaptive(&model, &cfg).unwrap_err().to_string();
    assert!(e.contains("polynomial"), "{e}");
}
