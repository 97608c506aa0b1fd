//! The checked-in logs that magstand wrote from a simulated stair
//! (`tests/data/magstand-written`, remade by its `make.sh`): imported from the files and
//! fitted, they give back the simulator's ground truth disturbance, which is checked in beside
//! them. Unlike the in-memory round trip, these files stay fixed when the writers or the
//! simulator change, so an import that drifts from what was once written fails here.
use std::path::PathBuf;

use magstand_core::Vec3;
use magstand_ident::{Estimation, Family, FitConfig};
use magstand_logs::import::{ImportOptions, import_file};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/magstand-written")
        .join(name)
}

/// `(t_s, true disturbance)` rows of the checked-in truth.
fn truth() -> Vec<(f64, Vec3)> {
    let mut r = csv::Reader::from_path(data("stair-truth.csv")).unwrap();
    r.records()
        .map(|row| {
            let row = row.unwrap();
            let v: Vec<f64> = row.iter().map(|c| c.parse().unwrap()).collect();
            (v[0], Vec3::new(v[1], v[2], v[3]))
        })
        .collect()
}

fn recovers_the_truth(file: &str) {
    let (rec, report) = import_file(&data(file), &ImportOptions::default()).unwrap();
    let truth = truth();
    assert_eq!(
        rec.len(),
        truth.len(),
        "{file}: rows\n{}",
        report.summary(&rec)
    );
    for (r, (t, _)) in truth.iter().enumerate() {
        assert!(
            (rec.t_s[r] - t).abs() < 1e-5,
            "{file} row {r}: t {} vs {t}",
            rec.t_s[r]
        );
    }
    // RMS per axis of a fitted model's prediction minus the truth.
    let rmse_against_truth = |cfg: FitConfig| {
        let model = cfg.check().unwrap().fit_recording(&rec, file).unwrap();
        let dist = model.dist_column(&rec);
        let err = truth
            .iter()
            .zip(&dist)
            .map(|((_, d), p)| (p - d).component_mul(&(p - d)))
            .sum::<Vec3>();
        (err / truth.len() as f64).map(f64::sqrt)
    };
    let rms = (truth.iter().map(|(_, d)| d.component_mul(d)).sum::<Vec3>() / truth.len() as f64)
        .map(f64::sqrt);
    let model = rmse_against_truth(FitConfig::evenly_spaced(5, Estimation::Global));
    let px4 = rmse_against_truth(FitConfig::baseline(Family::Px4));
    for a in 0..3 {
        assert!(
            model[a] < 0.1 * rms[a] && model[a] < 0.5 * px4[a],
            "{file} axis {a}: model vs truth {:.3} uT RMS, PX4's line {:.3}, against a disturbance of {:.3} uT RMS",
            model[a],
            px4[a],
            rms[a]
        );
    }
}

#[test]
fn the_checked_in_ulog_gives_back_the_ground_truth() {
    recovers_the_truth("stair.ulg");
}

#[test]
fn the_checked_in_dataflash_log_gives_back_the_ground_truth() {
    recovers_the_truth("stair.bin");
}
