//! Recordings magstand did not make: the independent stand generator (`tests/standgen`, no
//! magstand crate inside) writes the documented recording format from its own laws, and
//! magstand reads it and identifies its disturbance. The full diagnosis suite on these
//! recordings, with its confusion matrices, is
//! `cargo run --release -p magstand-tests --bin independent-suite` (results/diagnosis-independent.md).
use magstand_ident::{Dataset, Fit, FitConfig, InputKind};
use magstand_tests::independent::{Case, ROWS, recording, rmse_ut};

fn control(log_bat_v: bool) -> Case {
    Case {
        label: "control",
        effects: vec![],
        log_bat_v,
        log_temp: false,
    }
}

#[test]
fn the_generator_depends_on_no_magstand_crate() {
    let manifest =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/standgen/Cargo.toml"))
            .unwrap();
    let deps = manifest
        .split("[dependencies]")
        .nth(1)
        .expect("a [dependencies] table")
        .split("\n[")
        .next()
        .unwrap();
    assert!(
        deps.lines()
            .all(|l| l.trim().is_empty() || l.trim().starts_with('#')),
        "the independent generator must stay independent:\n{deps}"
    );
}

#[test]
fn its_recordings_read_as_documented() {
    let (rec, truth) = recording(&control(true), 3);
    assert_eq!(rec.len(), ROWS);
    assert_eq!(rec.motor_count(), 4);
    assert!(rec.bat_v.is_some() && rec.bat_a.is_some() && rec.temp_c.is_none());
    assert_eq!(truth.len(), ROWS);
    // Motors off: no current, so no disturbance, in the generator's own truth.
    let off: Vec<usize> = (0..rec.len())
        .filter(|&r| rec.thr.iter().all(|m| m[r] == 0.0))
        .collect();
    assert!(off.len() > ROWS / 20, "{} motors-off rows", off.len());
    assert!(off.iter().all(|&r| truth[r] == [0.0; 3]));
}

/// Identified on one recording, judged against the generator's truth on another (another
/// seed: other commands, other noise): the default fit follows a disturbance whose law it was
/// not written for to within 2 % of the disturbance's own size on every axis.
#[test]
fn the_default_fit_recovers_a_foreign_disturbance() {
    let (ident, _) = recording(&control(false), 11);
    let (valid, truth) = recording(&control(false), 12);
    let data = Dataset::from_recording(&ident, InputKind::Throttle, "ident").unwrap();
    let model = FitConfig::automatic().check().unwrap().fit(&data).unwrap();
    let err = rmse_ut(&model.dist_column(&valid), &truth);
    let size: [f64; 3] = std::array::from_fn(|a| {
        (truth.iter().map(|t| t[a] * t[a]).sum::<f64>() / truth.len() as f64).sqrt()
    });
    for a in 0..3 {
        assert!(
            err[a] < 0.02 * size[a],
            "axis {a}: RMSE {:.4} µT against a disturbance of RMS {:.3} µT (all axes: {err:?} vs {size:?})",
            err[a],
            size[a]
        );
    }
}
