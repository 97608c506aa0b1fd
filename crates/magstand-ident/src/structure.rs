//! Automatic choice of the number, centres and widths of the local models (LOLIMOT, Nelles).
//!
//! Start with one local model over the input range. Repeatedly split the interval of the local
//! model with the largest local *systematic* error into two halves, refit, and score the result
//! on validation time blocks that the fit did not see. Stop when the validation score has not
//! improved by at least 1 % in three splits, or at the model limit; keep the best partition.
//!
//! Both the local error and the score are measured on residuals averaged within narrow bins of
//! the input (`n_b |mean r_b|^2`, weighted per axis): with throttle-dependent noise many times
//! the model's bias, plain squared residuals would split where the data are most numerous or
//! noisiest instead of where the model is wrong.
//! Each RBF sits at its interval's centre with a standard deviation of 0.35 of the interval's
//! width (the paper's width 4 at a spacing of 0.5 is the same ratio).
use magstand_core::Vec3;
use magstand_core::rbf::RbfPartition;

use crate::IdentError;
use crate::dataset::Dataset;
use crate::local_linear::Estimation;
use crate::row_groups::Groups;

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

/// Most rows the structure is chosen on: a longer recording chooses on rows evenly spread over
/// it (every k-th), 1,000 per input bin, and fits the chosen structure's coefficients on
/// every row. (The choice scans the data once per candidate split, about 20 times per fit.)
pub const MAX_CHOICE_ROWS: usize = 50_000;

/// Number of input bins over which residuals are averaged.
pub const BINS: usize = 50;

/// Systematic error energy of a bin: `n |mean r|^2`, weighted per axis.
fn bin_energy((sum, n): (Vec3, usize), w: Vec3) -> f64 {
    if n == 0 {
        return 0.0;
    }
    let mean = sum / n as f64;
    n as f64 * mean.component_mul(&mean).dot(&w)
}

/// Chooses a partition. `fit_row` selects the rows to fit on, `score_row` the rows to score on
/// (disjoint from `fit_row`); `weight` gives per-axis row weights and `weight_at` the same
/// weights as a function of the normalized input.
pub fn choose(
    data: &Dataset,
    estimation: Estimation,
    max_models: usize,
    fit_row: &dyn Fn(usize) -> bool,
    score_row: &dyn Fn(usize) -> bool,
    weight: &dyn Fn(usize) -> Vec3,
    weight_at: &dyn Fn(f64) -> Vec3,
) -> Result<RbfPartition, IdentError> {
    let fit_groups = Groups::of(data, fit_row, weight);
    let score_groups = Groups::of(data, score_row, &|_| Vec3::repeat(1.0));
    let (lo, hi) = fit_groups
        .u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
            (a.min(u), b.max(u))
        });
    let mut intervals = vec![(lo, hi)];
    let mut best: Option<(f64, RbfPartition)> = None;
    let mut since_improvement = 0;
    let min_rows = 4 * data.spec.regressor_count();
    loop {
        let partition = partition_of(&intervals);
        let mut phi = vec![0.0; partition.len()];
        let net = match fit_groups.fit(&partition, estimation) {
            Ok(n) => n,
            // A split that leaves a local model without enough data ends the search.
            Err(e) if best.is_some() => {
                let _ = e;
                break;
            }
            Err(e) => return Err(e),
        };
        let bin_u = |b: usize| lo + (hi - lo) * (b as f64 + 0.5) / BINS as f64;
        let bin_weight = |b: usize| weight_at(bin_u(b));
        let scored = score_groups.binned_residuals(&net, BINS, lo, hi);
        let score: f64 = scored
            .iter()
            .enumerate()
            .map(|(b, &x)| bin_energy(x, bin_weight(b)))
            .sum();
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
        // Local losses on the fitting rows: each bin's systematic error shared by the models'
        // weights at the bin.
        let fitted = fit_groups.binned_residuals(&net, BINS, lo, hi);
        let mut loss = vec![0.0; intervals.len()];
        for (b, &x) in fitted.iter().enumerate() {
            let e = bin_energy(x, bin_weight(b));
            partition.weights_into(bin_u(b), &mut phi);
            for (i, w) in phi.iter().enumerate() {
                loss[i] += w * e;
            }
        }
        // Split the worst interval whose halves each keep a determined local line: enough
        // rows, at two or more distinct inputs (a stair gives one input per level, and a line
        // through a single level has no slope).
        let determined = |a: f64, b: f64, closed_right: bool| {
            let mut n = 0;
            let mut first = None;
            let mut distinct = false;
            for (&u, &rows) in fit_groups.u.iter().zip(&fit_groups.n) {
                if u >= a && (u < b || (closed_right && u <= b)) {
                    n += rows;
                    match first {
                        None => first = Some(u),
                        Some(f) if (u - f).abs() > 1e-9 => distinct = true,
                        _ => {}
                    }
                }
            }
            n >= min_rows && distinct
        };
        let mut order: Vec<usize> = (0..intervals.len()).collect();
        order.sort_by(|&a, &b| loss[b].total_cmp(&loss[a]));
        let splittable = order.into_iter().find(|&i| {
            let (a, b) = intervals[i];
            let mid = 0.5 * (a + b);
            determined(a, mid, false) && determined(mid, b, true)
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
