//! The tests behind every decision: a paired test of held-out improvement over blocks, the
//! Ljung-Box test of white residuals, and chi-square tests of windowed residual means.
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal, StudentsT};

/// One-sided p-value that the mean of `x` is above zero (Student t over independent units).
/// `None` with fewer than three units.
pub(crate) fn one_sided_t(x: &[f64]) -> Option<f64> {
    let n = x.len();
    if n < 3 {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    if var <= 0.0 {
        return Some(if mean > 0.0 { 0.0 } else { 1.0 });
    }
    Some(t_sf(mean / (var / n as f64).sqrt(), (n - 1) as f64))
}

/// Batches of consecutive rows in [`BatchMeans`].
const VARIANCE_BATCHES: usize = 16;

/// Fewest rows per batch in [`BatchMeans`]; fewer rows than two such batches give no
/// estimate.
const MIN_BATCH_ROWS: usize = 32;

/// The long-run variance of series of standardized residuals in time order (one per axis), by
/// batch means: the variance of the means of [`VARIANCE_BATCHES`] batches of consecutive rows
/// (fewer where the rows are few), times the rows per batch. Independent residuals of unit
/// variance give about 1; a misfit that runs over many rows gives about the number of rows it
/// spans, and the variance of an estimate from those rows is that many times what independent
/// rows would give (exactly so for a mean, and as an upper bound for a regressor that varies
/// as slowly as the misfit). The rows are pushed one at a time, so a fit keeps no copy of its
/// residuals for it.
pub(crate) struct BatchMeans {
    rows: usize,
    batches: usize,
    /// Rows pushed so far, the batch they fill and where it ends.
    seen: usize,
    batch: usize,
    batch_end: usize,
    /// Sum of each batch per axis, and of every row per axis (in row order).
    sums: Vec<Vec<f64>>,
    total: Vec<f64>,
}

impl BatchMeans {
    /// Batches for `rows` rows of `axes` residuals each.
    pub(crate) fn new(rows: usize, axes: usize) -> Self {
        let batches = (rows / MIN_BATCH_ROWS).min(VARIANCE_BATCHES);
        BatchMeans {
            rows,
            batches,
            seen: 0,
            batch: 0,
            batch_end: rows / batches.max(1),
            sums: vec![vec![0.0; axes]; batches],
            total: vec![0.0; axes],
        }
    }

    /// Adds the next row's residuals (one per axis); rows beyond those announced are ignored.
    pub(crate) fn push(&mut self, z: &[f64]) {
        if self.batches < 2 || self.seen >= self.rows {
            return;
        }
        while self.seen >= self.batch_end {
            self.batch += 1;
            self.batch_end = (self.batch + 1) * self.rows / self.batches;
        }
        for ((s, t), v) in self.sums[self.batch].iter_mut().zip(&mut self.total).zip(z) {
            *s += v;
            *t += v;
        }
        self.seen += 1;
    }

    /// The long-run variance of axis `a`, or `None` with too few rows.
    pub(crate) fn long_run_variance(&self, a: usize) -> Option<f64> {
        if self.batches < 2 || self.seen < self.rows {
            return None;
        }
        let mean = self.total[a] / self.rows as f64;
        let spread = (0..self.batches)
            .map(|b| {
                let len = (b + 1) * self.rows / self.batches - b * self.rows / self.batches;
                (self.sums[b][a] / len as f64 - mean).powi(2)
            })
            .sum::<f64>()
            / (self.batches - 1) as f64;
        Some(spread * (self.rows as f64 / self.batches as f64))
    }

    /// What an uncertainty taken from independent rows is multiplied by for these rows: the
    /// root of their long-run variance averaged over the axes, at least 1 (an uncertainty is
    /// never made smaller than the independent rows' one).
    pub(crate) fn sd_factor(&self) -> f64 {
        let per_axis: Vec<f64> = (0..self.total.len())
            .filter_map(|a| self.long_run_variance(a))
            .collect();
        if per_axis.is_empty() {
            return 1.0;
        }
        (per_axis.iter().sum::<f64>() / per_axis.len() as f64)
            .max(1.0)
            .sqrt()
    }
}

/// [`BatchMeans::sd_factor`] of one series.
pub(crate) fn serial_sd_factor(z: &[f64]) -> f64 {
    let mut b = BatchMeans::new(z.len(), 1);
    z.iter().for_each(|v| b.push(&[*v]));
    b.sd_factor()
}

/// Upper tail of Student's t with `dof` degrees of freedom.
pub(crate) fn t_sf(t: f64, dof: f64) -> f64 {
    StudentsT::new(0.0, 1.0, dof.max(1.0)).map_or(1.0, |d| d.sf(t))
}

/// Upper tail of the standard normal.
pub(crate) fn normal_sf(z: f64) -> f64 {
    Normal::new(0.0, 1.0).map_or(1.0, |d| d.sf(z))
}

/// One-sided p-value that the values of `x` lean above zero: the Wilcoxon signed-rank test
/// (normal approximation with tie correction; zeros dropped). Unlike the t-test it keeps its
/// power when the improvement sits in a few blocks (those with command steps) and the others
/// hold only noise. `None` with fewer than five non-zero values.
pub(crate) fn signed_rank(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x
        .iter()
        .copied()
        .filter(|v| *v != 0.0 && v.is_finite())
        .collect();
    let n = v.len();
    if n < 5 {
        return None;
    }
    v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let (mut w_plus, mut tie_term) = (0.0, 0.0);
    let mut i = 0;
    while i < n {
        let mut j = i;
        while j + 1 < n && v[j + 1].abs() == v[i].abs() {
            j += 1;
        }
        let rank = (i + j) as f64 / 2.0 + 1.0;
        let t = (j - i + 1) as f64;
        tie_term += t * t * t - t;
        w_plus += v[i..=j].iter().filter(|x| **x > 0.0).count() as f64 * rank;
        i = j + 1;
    }
    let nf = n as f64;
    let mean = nf * (nf + 1.0) / 4.0;
    let var = nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0;
    let z = (w_plus - mean - 0.5) / var.sqrt();
    Some(normal_sf(z))
}

/// Upper-tail p-value of a chi-square statistic with `dof` degrees of freedom.
pub(crate) fn chi2_sf(stat: f64, dof: f64) -> f64 {
    ChiSquared::new(dof.max(1e-9)).map_or(1.0, |d| d.sf(stat))
}

/// Quantile of the chi-square distribution.
pub(crate) fn chi2_quantile(p: f64, dof: f64) -> f64 {
    ChiSquared::new(dof.max(1e-9)).map_or(f64::INFINITY, |d| d.inverse_cdf(p))
}

/// What [`ljung_box`] finds in a residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LjungBox {
    /// The statistic Q.
    pub(crate) q: f64,
    /// Its upper-tail p-value (chi-square with `lags` degrees of freedom).
    pub(crate) p: f64,
    /// Root mean square of the autocorrelations over the lags: for structure that varies
    /// slowly against the lags, about the share of the residual's variance it carries (white
    /// noise gives about `1/sqrt(n)`). The p-value says whether there is structure; this says
    /// how much.
    pub(crate) rms_autocorrelation: f64,
}

/// Ljung-Box statistic of standardized residuals `z` over `lags` lags, where pairs are only
/// formed within one segment (`segment[i] == segment[i + k]`).
pub(crate) fn ljung_box(z: &[f64], segment: &[usize], lags: usize) -> LjungBox {
    let none = LjungBox {
        q: 0.0,
        p: 1.0,
        rms_autocorrelation: 0.0,
    };
    let n = z.len();
    if n <= lags + 1 {
        return none;
    }
    let mean = z.iter().sum::<f64>() / n as f64;
    let c0: f64 = z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    if c0 <= 0.0 {
        return none;
    }
    let (mut q, mut rho2, mut counted) = (0.0, 0.0, 0usize);
    for k in 1..=lags {
        let mut s = 0.0;
        let mut pairs = 0usize;
        for i in 0..n - k {
            if segment[i] == segment[i + k] {
                s += (z[i] - mean) * (z[i + k] - mean);
                pairs += 1;
            }
        }
        if pairs == 0 {
            continue;
        }
        let rho = s / pairs as f64 / c0;
        q += rho * rho * (pairs as f64);
        rho2 += rho * rho;
        counted += 1;
    }
    // With pairs restricted to segments, `pairs` plays the role of n - k (large-sample form).
    LjungBox {
        q,
        p: chi2_sf(q, lags as f64),
        rms_autocorrelation: if counted > 0 {
            (rho2 / counted as f64).sqrt()
        } else {
            0.0
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers on -0.5..0.5 from a fixed LCG: deterministic tests.
    fn uniform_from(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    #[test]
    fn white_noise_passes_and_a_random_walk_fails_ljung_box() {
        let mut uniform = uniform_from(12345);
        let white: Vec<f64> = (0..5000).map(|_| uniform() * 12f64.sqrt()).collect();
        let seg = vec![0; white.len()];
        let p = ljung_box(&white, &seg, 10).p;
        assert!(p > 0.001, "white noise rejected, p = {p}");
        let mut acc = 0.0;
        let walk: Vec<f64> = white
            .iter()
            .map(|w| {
                acc = 0.99 * acc + w;
                acc
            })
            .collect();
        let p = ljung_box(&walk, &seg, 10).p;
        assert!(p < 1e-10, "AR(1) accepted as white, p = {p}");
    }

    #[test]
    fn ljung_box_share_measures_how_much_of_the_variance_is_structure() {
        let mut uniform = uniform_from(777);
        let n = 20_000;
        // Unit-variance white noise, and levels held for 200 rows with variance `v`: the
        // levels carry v / (1 + v) of the sum's variance.
        let noise: Vec<f64> = (0..n).map(|_| uniform() * 12f64.sqrt()).collect();
        let seg = vec![0; n];
        let white = ljung_box(&noise, &seg, 20).rms_autocorrelation;
        assert!(white < 3.0 / (n as f64).sqrt(), "white noise share {white}");
        for v in [0.05f64, 0.25, 1.0] {
            let mut level = 0.0;
            let z: Vec<f64> = noise
                .iter()
                .enumerate()
                .map(|(i, e)| {
                    if i % 200 == 0 {
                        level = uniform() * (12.0 * v).sqrt();
                    }
                    level + e
                })
                .collect();
            let share = ljung_box(&z, &seg, 20).rms_autocorrelation;
            let expected = v / (1.0 + v);
            assert!(
                (share - expected).abs() < 0.35 * expected,
                "levels of variance {v}: share {share}, expected about {expected}"
            );
        }
    }

    #[test]
    fn t_test_sees_a_positive_mean_and_not_a_zero_one() {
        let up: Vec<f64> = (0..30)
            .map(|k| 1.0 + ((k % 5) as f64 - 2.0) * 0.1)
            .collect();
        assert!(one_sided_t(&up).unwrap() < 1e-10);
        let zero: Vec<f64> = (0..30).map(|k| ((k % 5) as f64 - 2.0) * 0.1).collect();
        assert!(one_sided_t(&zero).unwrap() > 0.4);
        assert!(one_sided_t(&[1.0, 2.0]).is_none());
    }

    #[test]
    fn signed_rank_sees_improvement_in_a_few_units_and_not_in_noise() {
        // Ten units with a clear gain among thirty that hold noise of both signs.
        let mut x: Vec<f64> = (0..30)
            .map(|k| if k % 2 == 0 { 0.01 } else { -0.01 } * (k as f64 + 1.0))
            .collect();
        assert!(
            signed_rank(&x).unwrap() > 0.2,
            "noise alone: {:?}",
            signed_rank(&x)
        );
        for v in x.iter_mut().step_by(3) {
            *v = 5.0;
        }
        assert!(signed_rank(&x).unwrap() < 0.01, "{:?}", signed_rank(&x));
        assert!(signed_rank(&[1.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn the_long_run_variance_is_one_for_white_noise_and_the_run_length_for_a_slow_misfit() {
        let long_run_variance = |z: &[f64]| {
            let mut b = BatchMeans::new(z.len(), 1);
            z.iter().for_each(|v| b.push(&[*v]));
            b.long_run_variance(0)
        };
        // Deterministic white noise of unit variance: a linear congruential sequence.
        let mut state: u64 = 12345;
        let mut uniform = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let white: Vec<f64> = (0..20_000)
            .map(|_| (uniform() - 0.5) * 12f64.sqrt())
            .collect();
        let lrv = long_run_variance(&white).unwrap();
        assert!((0.3..3.0).contains(&lrv), "white noise: {lrv}");
        let factor = serial_sd_factor(&white);
        assert!(
            (1.0..1.8).contains(&factor),
            "white noise: sd factor {factor}"
        );
        // The same noise plus a misfit constant over runs of 1,250 rows (one batch each), of
        // unit size: the batch means vary by about 1, so the long-run variance is about 1,250.
        let slow: Vec<f64> = white
            .iter()
            .enumerate()
            .map(|(k, z)| z + if (k / 1250) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let lrv = long_run_variance(&slow).unwrap();
        assert!((800.0..2000.0).contains(&lrv), "slow misfit: {lrv}");
        let factor = serial_sd_factor(&slow);
        assert!((28.0..45.0).contains(&factor), "sd factor {factor}");
        assert!(long_run_variance(&white[..40]).is_none());
    }

    #[test]
    fn chi2_tail_and_quantile_agree() {
        let q = chi2_quantile(0.99, 10.0);
        assert!((chi2_sf(q, 10.0) - 0.01).abs() < 1e-9, "{q}");
    }
}
