//! `magstand fit --method physics` printed the held-out RMSE of the model before its
//! calibration when the calibration (here the dead zone, 0.05 on a stand whose nominal says
//! 0.37) was all it accepted: the figure of the last named effect stood for the model's,
//! and with no named effect the bare baseline's did. It printed z 0.805 µT for a model whose
//! held-out error is 0.645 µT, on a stand whose noise is 0.585 µT RMS. The figure is now the
//! calibrated model's, with every accepted term.
mod common;
use common::{magstand, simulate_bench_stair};

#[test]
fn the_printed_held_out_error_is_the_calibrated_models() {
    let dir = tempfile::tempdir().unwrap();
    let p = |s: &str| dir.path().join(s).to_str().unwrap().to_string();
    simulate_bench_stair(&p("a"), Some("1"), &["motors.dead_zone=0.05"]);
    let recording = p("a/recording.csv");
    let r = magstand(&[
        "fit",
        "--recording",
        &recording,
        "--model-out",
        &p("m.json"),
        "--method",
        "physics",
    ]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stdout.contains("motors.dead_zone"), "{}", r.stdout);
    let line = r
        .stdout
        .lines()
        .find(|l| l.contains("held-out RMSE"))
        .unwrap_or_else(|| panic!("no held-out RMSE printed:\n{}", r.stdout));
    let printed: Vec<f64> = line
        .split("RMSE")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .filter_map(|w| w.parse::<f64>().ok())
        .collect();
    assert_eq!(printed.len(), 3, "{line}");
    // The simulator's own noise, RMS over the rows: a calibrated model of its own stand
    // leaves about that.
    let rec = magstand_core::recording_csv::read(&recording).unwrap();
    let sd = &rec
        .truth
        .as_ref()
        .expect("a simulated recording's truth")
        .sd_ut;
    for a in 0..3 {
        let noise = (sd.iter().map(|v| v[a] * v[a]).sum::<f64>() / sd.len() as f64).sqrt();
        assert!(
            printed[a] < 1.2 * noise,
            "axis {a}: printed held-out RMSE {} µT against noise {noise:.3} µT ({line})",
            printed[a]
        );
    }
}
