//! Automatic choice of the number, centres and widths of the local models (LOLIMOT, Nelles).
//!
//! Start with one local model over the input range. Repeatedly split the interval of the local
//! model with the largest weighted local error into two halves, refit, and score the result on
//! validation time blocks that the fit did not see. Stop when the validation error has not
//! improved by at least 1 % in three splits, or at the model limit; keep the best partition.
//! Each RBF sits at its interval's centre with a standard deviation of 0.35 of the interval's
//! width (the paper's width 4 at a spacing of 0.5 is the same ratio).
use magstand_core::Vec3;
use magstand_core::rbf::RbfPartition;

use crate::IdentError;
use crate::dataset::Dataset;
use crate::local_linear::{Estimation, LocalLinearNet, fit};

/// Standard deviation of each RBF as a fraction of its interval's width.
pub const SIGMA_FRACTION: f64 = 0.35;

/// The partition for a set of intervals.
pub fn partition_of(intervals: &[(f64, f64)]) -> RbfPartition {
    let centers = intervals.iter().map(|(a, b)| 0.5 * (a + b)).collect();
    let widths = intervals
        .iter()
        .map(|(a, b)| 1.0 / (SIGMA_FRACTION * (b - a) * std::f64::consts::SQRT_2))
        .collect();
    RbfPartition::new(centers, widths).expect("intervals of positive width give a valid partition")
}

/// Squared residual of a row, summed over axes with per-axis weights.
fn weighted_sq(net: &LocalLinearNet, data: &Dataset, k: usize, w: Vec3, phi: &mut [f64]) -> f64 {
    let r = data.y[k] - net.eval(data.u[k], data.regressors(k), phi);
    (r.component_mul(&r)).dot(&w)
}

/// Chooses a partition. `fit_row` selects the rows to fit on, `score_row` the rows to score on
/// (disjoint from `fit_row`); `weight` gives per-axis row weights.
pub fn choose(
    data: &Dataset,
    estimation: Estimation,
    max_models: usize,
    fit_row: &dyn Fn(usize) -> bool,
    score_row: &dyn Fn(usize) -> bool,
    weight: &dyn Fn(usize) -> Vec3,
) -> Result<RbfPartition, IdentError> {
    let (lo, hi) = (0..data.len())
        .filter(|&k| fit_row(k))
        .map(|k| data.u[k])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), u| {
            (a.min(u), b.max(u))
        });
    let mut intervals = vec![(lo, hi)];
    let mut best: Option<(f64, RbfPartition)> = None;
    let mut since_improvement = 0;
    let min_rows = 4 * data.spec.regressor_count();
    loop {
        let partition = partition_of(&intervals);
        let mut phi = vec![0.0; partition.len()];
        let net = match fit(data, &partition, estimation, fit_row, weight) {
            Ok(n) => n,
            // A split that leaves a local model without enough data ends the search.
            Err(e) if best.is_some() => {
                let _ = e;
                break;
            }
            Err(e) => return Err(e),
        };
        let (mut s, mut n) = (0.0, 0usize);
        for k in (0..data.len()).filter(|&k| score_row(k)) {
            s += weighted_sq(&net, data, k, weight(k), &mut phi);
            n += 1;
        }
        let score = if n > 0 { s / n as f64 } else { f64::INFINITY };
        match &best {
            Some((b, _)) if score >= 0.99 * b => since_improvement += 1,
            _ => since_improvement = 0,
        }
        if best.as_ref().is_none_or(|(b, _)| score < *b) {
            best = Some((score, partition.clone()));
        }
        if since_improvement >= 3 || intervals.len() >= max_models {
            break;
        }
        // Local losses on the fitting rows: each row's error shared by the models' weights.
        let mut loss = vec![0.0; intervals.len()];
        let mut count = vec![0usize; intervals.len()];
        for k in (0..data.len()).filter(|&k| fit_row(k)) {
            let e = weighted_sq(&net, data, k, weight(k), &mut phi);
            partition.weights_into(data.u[k], &mut phi);
            for (i, w) in phi.iter().enumerate() {
                loss[i] += w * e;
            }
            if let Some(i) = intervals
                .iter()
                .position(|&(a, b)| data.u[k] >= a && data.u[k] <= b)
            {
                count[i] += 1;
            }
        }
        // Split the worst interval that still has data on both sides of its middle.
        let mut order: Vec<usize> = (0..intervals.len()).collect();
        order.sort_by(|&a, &b| loss[b].total_cmp(&loss[a]));
        let splittable = order.into_iter().find(|&i| {
            count[i] >= 2 * min_rows && {
                let (a, b) = intervals[i];
                let mid = 0.5 * (a + b);
                let left = (0..data.len()).any(|k| fit_row(k) && data.u[k] >= a && data.u[k] < mid);
                let right =
                    (0..data.len()).any(|k| fit_row(k) && data.u[k] > mid && data.u[k] <= b);
                left && right
            }
        });
        let Some(i) = splittable else { break };
        let (a, b) = intervals[i];
        let mid = 0.5 * (a + b);
        intervals.splice(i..=i, [(a, mid), (mid, b)]);
    }
    Ok(best
        .expect("the first fit either succeeds or returns its error")
        .1)
}
