//! How good a compensation is: eq. 9 deviations, eq. 20 error in percent of the field norm,
//! apparent heading error, ArduPilot-style interference, and errors against ground truth.
use serde::Serialize;

use crate::dataset::{motors_off_reference, motors_off_rows};
use crate::model::Model;
use magstand_core::{Recording, Vec3};

/// Percentile `q` (0..1) of `sorted` values by linear interpolation between order statistics:
/// the one definition of a percentile in magstand's figures (a study's summaries, an export's
/// heading error). `sorted` must not be empty.
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Magnetic heading in degrees (0..360) of a body-frame field, tilt-compensated with the
/// accelerometer's specific force when given (eq. 2-3 roll and pitch), level otherwise.
pub fn heading_deg(mag: Vec3, acc: Option<Vec3>) -> f64 {
    let (bx, by) = match acc {
        Some(f) if f.norm() > 1.0 => {
            // At rest the accelerometer reads -g along body z: roll and pitch from its direction.
            let roll = (-f.y).atan2(-f.z);
            let pitch = (f.x).atan2((f.y * f.y + f.z * f.z).sqrt());
            let (sr, cr, sp, cp) = (roll.sin(), roll.cos(), pitch.sin(), pitch.cos());
            (
                mag.x * cp + mag.y * sr * sp + mag.z * cr * sp,
                mag.y * cr - mag.z * sr,
            )
        }
        _ => (mag.x, mag.y),
    };
    (-by).atan2(bx).to_degrees().rem_euclid(360.0)
}

/// Difference of two headings wrapped to -180..180 degrees.
pub fn heading_difference_deg(a: f64, b: f64) -> f64 {
    (a - b + 180.0).rem_euclid(360.0) - 180.0
}

/// Figures at one throttle level.
#[derive(Debug, Clone, Serialize)]
pub struct LevelRow {
    /// Overall throttle (level or bin centre).
    pub throttle: f64,
    /// Samples.
    pub samples: usize,
    /// Mean deviation from the motors-off reading (eq. 9), µT.
    pub dmag_ut: [f64; 3],
    /// Mean predicted disturbance, µT.
    pub model_ut: [f64; 3],
    /// Mean eq. 20 error after compensation, % of the field norm.
    pub e20_pct: [f64; 3],
    /// Apparent heading error of the level's mean field before compensation, degrees.
    pub heading_before_deg: f64,
    /// Apparent heading error of the level's mean field after compensation, degrees.
    pub heading_after_deg: f64,
}

/// A model judged on a recording.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// Per throttle level (stair levels, or 0.05-wide bins for continuous throttle).
    pub levels: Vec<LevelRow>,
    /// RMSE of the predicted against the true disturbance, per axis, µT (simulations only).
    pub truth_rmse_ut: Option<[f64; 3]>,
    /// RMSE of the uncompensated disturbance (the error with no compensation), µT.
    pub truth_rms_dist_ut: Option<[f64; 3]>,
    /// RMS of eq. 20 over rows with the motors running, % of the field norm, per axis.
    pub e20_rms_pct: [f64; 3],
    /// Worst mean apparent heading error over levels before compensation, degrees.
    pub heading_before_max_deg: f64,
    /// Worst mean apparent heading error over levels after compensation, degrees.
    pub heading_after_max_deg: f64,
    /// ArduPilot-style interference: the largest mean field change over levels in % of the
    /// motors-off field norm, before compensation.
    pub interference_before_pct: f64,
    /// The same after compensation.
    pub interference_after_pct: f64,
}

/// RMSE per axis of a predicted disturbance (one per row) against a simulated recording's true
/// one, and the RMS of the true disturbance itself, µT; `None` without ground truth.
pub fn against_truth(rec: &Recording, dist: &[Vec3]) -> Option<([f64; 3], [f64; 3])> {
    let t = rec.truth.as_ref()?;
    let n = rec.len().max(1) as f64;
    let mut e = Vec3::zeros();
    let mut d = Vec3::zeros();
    for (p, truth) in dist.iter().zip(&t.dist_ut) {
        let err = p - truth;
        e += err.component_mul(&err);
        d += truth.component_mul(truth);
    }
    let rms = |v: Vec3| [0, 1, 2].map(|a| (v[a] / n).sqrt());
    Some((rms(e), rms(d)))
}

/// Groups rows by throttle: exact levels when there are at most 60 distinct ones, else bins.
fn level_of(rec: &Recording) -> (Vec<f64>, Vec<usize>) {
    let thr = rec.overall_throttle_column();
    let mut distinct: Vec<f64> = thr.iter().map(|t| (t * 1e4).round() / 1e4).collect();
    distinct.sort_unstable_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() <= 60 {
        let idx = thr
            .iter()
            .map(|t| distinct.partition_point(|d| *d < (t * 1e4).round() / 1e4))
            .collect();
        (distinct, idx)
    } else {
        let centres = (0..20).map(|k| 0.025 + 0.05 * k as f64).collect();
        (
            centres,
            thr.iter()
                .map(|t| ((t / 0.05).floor() as usize).min(19))
                .collect(),
        )
    }
}

impl Evaluation {
    /// Evaluates `model` on `rec`. The eq. 9 reference is the recording's own motors-off mean
    /// when it has motors-off rows (as the paper does for each series), else the model's.
    pub fn new(model: &Model, rec: &Recording) -> Self {
        Self::from_prediction(model, rec, &model.dist_column(rec))
    }

    /// The same, from the model's predicted disturbance per row (`model.dist_column(rec)`),
    /// for a caller that needs the prediction too.
    pub fn from_prediction(model: &Model, rec: &Recording, dist: &[Vec3]) -> Self {
        Self::from_prediction_at(Vec3::from(model.reference_ut), rec, dist)
    }

    /// As [`Evaluation::from_prediction`] for any model: `fallback_reference_ut` is the
    /// motors-off field used when `rec` has no motors-off rows of its own.
    pub fn from_prediction_at(fallback_reference_ut: Vec3, rec: &Recording, dist: &[Vec3]) -> Self {
        let n = rec.len();
        assert_eq!(
            dist.len(),
            n,
            "one predicted disturbance per row of the recording"
        );
        let off_rows = motors_off_rows(rec);
        let reference = motors_off_reference(rec, &off_rows).unwrap_or(fallback_reference_ut);
        // The stand is restrained: its tilt is the mean specific force over the motors-off rows
        // (or all rows). A per-sample accelerometer reading carries rotor vibration of several
        // m/s^2, which would swing a tilt-compensated heading by tens of degrees.
        let mean_acc = rec.imu.as_ref().map(|i| {
            let rows: Vec<usize> = if off_rows.is_empty() {
                (0..n).collect()
            } else {
                off_rows.clone()
            };
            rows.iter().map(|&r| i.acc_mps2[r]).sum::<Vec3>() / rows.len() as f64
        });
        let acc = |_: usize| mean_acc;
        let ref_heading = if off_rows.is_empty() {
            heading_deg(reference, None)
        } else {
            // Circular mean of the motors-off headings.
            let (s, c) = off_rows
                .iter()
                .map(|&r| heading_deg(rec.mag_ut[r], acc(r)).to_radians())
                .fold((0.0, 0.0), |(s, c), h| (s + h.sin(), c + h.cos()));
            s.atan2(c).to_degrees().rem_euclid(360.0)
        };
        let (centres, idx) = level_of(rec);
        let mut sums = vec![(0usize, Vec3::zeros(), Vec3::zeros(), Vec3::zeros()); centres.len()];
        let mut e20_sq = Vec3::zeros();
        let mut running = 0usize;
        for r in 0..n {
            let dmag = rec.mag_ut[r] - reference;
            let norm = rec.mag_ut[r].norm().max(1e-9);
            let e20 = (dmag - dist[r]) / norm * 100.0;
            let s = &mut sums[idx[r]];
            s.0 += 1;
            s.1 += dmag;
            s.2 += dist[r];
            s.3 += e20;
            if !rec.motors_off(r) {
                e20_sq += e20.component_mul(&e20);
                running += 1;
            }
        }
        let levels: Vec<LevelRow> = centres
            .iter()
            .zip(&sums)
            .filter(|(_, s)| s.0 > 0)
            .map(|(&throttle, s)| {
                let k = s.0 as f64;
                LevelRow {
                    throttle,
                    samples: s.0,
                    dmag_ut: (s.1 / k).into(),
                    model_ut: (s.2 / k).into(),
                    e20_pct: (s.3 / k).into(),
                    // Heading of the level's mean field: the bias a pilot sees, without the noise.
                    heading_before_deg: heading_difference_deg(
                        heading_deg(reference + s.1 / k, acc(0)),
                        ref_heading,
                    )
                    .abs(),
                    heading_after_deg: heading_difference_deg(
                        heading_deg(reference + (s.1 - s.2) / k, acc(0)),
                        ref_heading,
                    )
                    .abs(),
                }
            })
            .collect();
        let ref_norm = reference.norm().max(1e-9);
        let interference_before_pct = levels
            .iter()
            .map(|l| Vec3::from(l.dmag_ut).norm())
            .fold(0.0, f64::max)
            / ref_norm
            * 100.0;
        let interference_after_pct = levels
            .iter()
            .map(|l| (Vec3::from(l.dmag_ut) - Vec3::from(l.model_ut)).norm())
            .fold(0.0, f64::max)
            / ref_norm
            * 100.0;
        let (truth_rmse_ut, truth_rms_dist_ut) = match against_truth(rec, dist) {
            Some((e, d)) => (Some(e), Some(d)),
            None => (None, None),
        };
        Evaluation {
            e20_rms_pct: [0, 1, 2].map(|a| (e20_sq[a] / running.max(1) as f64).sqrt()),
            heading_before_max_deg: levels
                .iter()
                .map(|l| l.heading_before_deg)
                .fold(0.0, f64::max),
            heading_after_max_deg: levels
                .iter()
                .map(|l| l.heading_after_deg)
                .fold(0.0, f64::max),
            interference_before_pct,
            interference_after_pct,
            truth_rmse_ut,
            truth_rms_dist_ut,
            levels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heading_of_a_level_field() {
        // Field pointing along body x: heading 0. Along body -y (field to the left): nose is 90° east.
        assert!((heading_deg(Vec3::new(20.0, 0.0, 40.0), None) - 0.0).abs() < 1e-12);
        assert!((heading_deg(Vec3::new(0.0, -20.0, 40.0), None) - 90.0).abs() < 1e-12);
    }

    #[test]
    fn tilt_compensation_undoes_a_roll() {
        use nalgebra::UnitQuaternion;
        let ned = Vec3::new(19.5, 1.9, 46.0);
        let yaw = 30f64.to_radians();
        let q = UnitQuaternion::from_euler_angles(0.2, -0.1, yaw);
        let mag = q.inverse() * ned;
        let acc = q.inverse() * Vec3::new(0.0, 0.0, -9.81);
        let expected = (yaw.to_degrees() - 1.9f64.atan2(19.5).to_degrees()).rem_euclid(360.0);
        assert!(
            (heading_deg(mag, Some(acc)) - expected).abs() < 1e-9,
            "{} vs {expected}",
            heading_deg(mag, Some(acc))
        );
    }

    #[test]
    fn heading_difference_wraps() {
        assert_eq!(heading_difference_deg(350.0, 10.0), -20.0);
        assert_eq!(heading_difference_deg(10.0, 350.0), 20.0);
    }
}
