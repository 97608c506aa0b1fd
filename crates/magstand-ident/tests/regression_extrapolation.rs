//! Regression: the automatic throttle model fitted on hover data (throttle up to 0.59) bent
//! back beyond it, and on later rows of the same flight did worse than no compensation
//! (11.98 mG against 11.29 for none and 8.17 for a straight line). A model now records the
//! input range it was identified on and continues linearly from its edge beyond it; inside
//! the range it is unchanged. The data here come from an analytic disturbance, not from
//! magstand's simulator.
use magstand_core::{Recording, Vec3};
use magstand_ident::{FitConfig, Model, Structure};

/// A quadratic disturbance in throttle (current grows about as throttle squared) with a
/// deterministic ripple; `top` is the highest throttle of the run.
fn run(top: f64) -> Recording {
    let mut rec = Recording {
        thr: vec![vec![]],
        overall_only: true,
        ..Default::default()
    };
    for k in 0..6000 {
        let level = (k / 200) as f64 / 29.0;
        let u = if k < 400 { 0.0 } else { top * level };
        let ripple = 0.3 * ((k as f64) * 1.7).sin() + 0.2 * ((k as f64) * 0.37).cos();
        rec.t_s.push(k as f64 * 0.01);
        rec.thr[0].push(u);
        rec.mag_ut
            .push(Vec3::new(20.0, 1.0, 45.0) + truth(u) + Vec3::repeat(ripple));
    }
    rec
}

fn truth(u: f64) -> Vec3 {
    Vec3::new(-9.0, 6.0, 14.0) * (u * u) + Vec3::new(-2.0, 1.0, 3.0) * u
}

fn rms_error(model: &Model, from: f64, to: f64) -> f64 {
    let mut s = model.scratch();
    let n = 100;
    let sum: f64 = (0..=n)
        .map(|i| {
            let u = from + (to - from) * i as f64 / n as f64;
            (model.dist_at_input(u, &mut s) - truth(u)).norm_squared()
        })
        .sum();
    (sum / (n + 1) as f64).sqrt()
}

#[test]
fn beyond_the_identified_range_the_model_continues_linearly_and_beats_no_compensation() {
    let hover = run(0.59);
    for cfg in [FitConfig::automatic(), FitConfig::paper()] {
        let model = cfg.check().unwrap().fit_recording(&hover, "hover").unwrap();
        let range = model
            .identified
            .clone()
            .expect("the identified range is recorded");
        assert!(
            range.lo == 0.0 && (range.hi - 0.59).abs() < 1e-9,
            "{range:?}"
        );
        // Straight beyond the edge: equal steps give equal changes.
        let mut s = model.scratch();
        let d = |u: f64, s: &mut magstand_ident::Scratch| model.dist_at_input(u, s);
        let (a, b, c) = (d(0.7, &mut s), d(0.8, &mut s), d(0.9, &mut s));
        assert!(
            ((c - b) - (b - a)).norm() < 1e-9,
            "{} not linear beyond the edge: {a:?} {b:?} {c:?}",
            model.method
        );
        // Continuous at the edge.
        let (inside, outside) = (d(0.59 - 1e-9, &mut s), d(0.59 + 1e-9, &mut s));
        assert!((inside - outside).norm() < 1e-6, "{inside:?} {outside:?}");
        // Beyond the range it still removes most of the disturbance: better than nothing.
        let none = {
            let n = 100;
            let sum: f64 = (0..=n)
                .map(|i| truth(0.59 + 0.31 * i as f64 / n as f64).norm_squared())
                .sum();
            (sum / (n + 1) as f64).sqrt()
        };
        let beyond = rms_error(&model, 0.59, 0.9);
        assert!(
            beyond < 0.5 * none,
            "{}: {beyond} µT beyond the range vs {none} µT uncompensated",
            model.method
        );
    }
}

#[test]
fn inside_the_identified_range_nothing_changes() {
    let hover = run(0.59);
    let model = FitConfig::automatic()
        .check()
        .unwrap()
        .fit_recording(&hover, "hover")
        .unwrap();
    let mut unguarded = model.clone();
    unguarded.identified = None;
    let (mut s1, mut s2) = (model.scratch(), unguarded.scratch());
    for i in 0..=59 {
        let u = i as f64 / 100.0;
        assert_eq!(
            model.dist_at_input(u, &mut s1),
            unguarded.dist_at_input(u, &mut s2),
            "u = {u}"
        );
    }
}

#[test]
fn a_polynomial_continues_along_its_tangent() {
    let hover = run(0.59);
    let mut model = FitConfig::automatic()
        .check()
        .unwrap()
        .fit_recording(&hover, "hover")
        .unwrap();
    // u^2 + u per axis, identified on 0..0.5: beyond, value 0.75 plus slope 2 per unit.
    model.structure = Structure::Polynomial {
        coefficients: [
            vec![0.0, 1.0, 1.0],
            vec![0.0, 1.0, 1.0],
            vec![0.0, 1.0, 1.0],
        ],
    };
    model.identified.as_mut().unwrap().hi = 0.5;
    let mut s = model.scratch();
    let got = model.dist_at_input(0.8, &mut s);
    assert!(
        (got - Vec3::repeat(0.75 + 2.0 * 0.3)).norm() < 1e-12,
        "{got:?}"
    );
}

#[test]
fn a_model_file_with_a_broken_identified_range_is_refused() {
    let hover = run(0.59);
    let mut model = FitConfig::automatic()
        .check()
        .unwrap()
        .fit_recording(&hover, "hover")
        .unwrap();
    model.identified.as_mut().unwrap().quantiles.truncate(3);
    let text = serde_json::to_string(&model).unwrap();
    let e = Model::from_json(&text, "m.json").unwrap_err().to_string();
    assert!(e.contains("m.json") && e.contains("identified"), "{e}");
}
