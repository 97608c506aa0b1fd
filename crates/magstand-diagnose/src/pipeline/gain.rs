//! Stage 2, the statistics of a held-out gain: held-out RMSE, per-block improvements, the
//! three tests of a candidate's gain (t, signed rank, gain against noise with the residuals'
//! autocovariance) and the white-noise test of standardized residuals.
use magstand_core::Vec3;

use crate::fit::Weights;
use crate::stats::{LjungBox, ljung_box, normal_sf, one_sided_t, signed_rank};
use magstand_core::held_out::Split;

/// Lags of the whiteness test.
const LAGS: usize = 20;

/// Held-out RMSE per axis, µT.
pub(crate) fn holdout_rmse(resid: &[Vec3], holdout: &[bool]) -> [f64; 3] {
    let mut s = [0.0; 3];
    let mut n = 0.0f64;
    for (e, _) in resid.iter().zip(holdout).filter(|(_, h)| **h) {
        for a in 0..3 {
            s[a] += e[a] * e[a];
        }
        n += 1.0;
    }
    s.map(|v| (v / n.max(1.0)).sqrt())
}

/// Per held-out block, the mean drop of the weighted squared residual from `before` to `after`.
pub(crate) fn block_improvements(
    before: &[Vec3],
    after: &[Vec3],
    w: &Weights,
    split: &Split,
) -> Vec<f64> {
    block_improvements_on(before, after, w, split, &[0, 1, 2])
}

/// [`block_improvements`] over the axes `axes` only.
pub(crate) fn block_improvements_on(
    before: &[Vec3],
    after: &[Vec3],
    w: &Weights,
    split: &Split,
    axes: &[usize],
) -> Vec<f64> {
    let mut out: Vec<(usize, f64, f64)> = Vec::new();
    for r in (0..before.len()).filter(|&r| split.holdout[r]) {
        let d: f64 = axes
            .iter()
            .map(|&a| w.0[r][a] * (before[r][a].powi(2) - after[r][a].powi(2)))
            .sum();
        match out.last_mut() {
            Some((b, s, n)) if *b == split.block[r] => {
                *s += d;
                *n += 1.0;
            }
            _ => out.push((split.block[r], d, 1.0)),
        }
    }
    out.into_iter().map(|(_, s, n)| s / n).collect()
}

/// The mean of per-block improvements ([`block_improvements`]): the gain a candidate reports.
pub(crate) fn mean_gain(blocks: &[f64]) -> f64 {
    blocks.iter().sum::<f64>() / blocks.len().max(1) as f64
}

/// The one-sided p-value of a held-out gain from `before` to `after`, given its per-block
/// improvements `blocks`: three views of the same gain, Bonferroni-combined. The t-test sees
/// gains spread over all blocks, the signed-rank test gains confined to the blocks with steps,
/// and the gain against its noise given the residuals' own autocovariance gains concentrated
/// in a few short transients.
pub(crate) fn gain_p_value(
    blocks: &[f64],
    before: &[Vec3],
    after: &[Vec3],
    w: &Weights,
    split: &Split,
) -> Option<f64> {
    let p = [
        one_sided_t(blocks),
        signed_rank(blocks),
        noise_referenced(before, after, w, split),
    ];
    let k = p.iter().flatten().count() as f64;
    p.iter()
        .flatten()
        .cloned()
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))))
        .map(|m| (m * k).min(1.0))
}

/// One-sided p-value of the held-out gain `S = sum(z_before^2 - z_after^2) + D` (D: the
/// squared change of the prediction in noise units), which has mean zero when the candidate
/// only fits noise; its variance uses the autocovariance of the before-residuals up to one
/// block's length, so structure that is not white does not pass for a gain.
fn noise_referenced(before: &[Vec3], after: &[Vec3], w: &Weights, split: &Split) -> Option<f64> {
    noise_referenced_by(before, after, w, split, true)
}

/// [`noise_referenced`], its lagged products summed block by block where `by_block` and the
/// held-out rows' blocks never decrease ([`block_runs`]), else by a scan over every pair of
/// rows that keeps the pairs within one block: the same pairs in the same order either way.
fn noise_referenced_by(
    before: &[Vec3],
    after: &[Vec3],
    w: &Weights,
    split: &Split,
    by_block: bool,
) -> Option<f64> {
    let rows: Vec<usize> = (0..before.len()).filter(|&r| split.holdout[r]).collect();
    let n = rows.len();
    if n < 10 {
        return None;
    }
    let lags = (n / split.holdout_blocks().max(1)).clamp(1, 400);
    let runs = by_block.then(|| block_runs(&rows, split)).flatten();
    let mut s = 0.0;
    let mut var = 0.0;
    for a in 0..3 {
        let z: Vec<f64> = rows
            .iter()
            .map(|&r| before[r][a] * w.0[r][a].sqrt())
            .collect();
        let d: Vec<f64> = rows
            .iter()
            .map(|&r| (before[r][a] - after[r][a]) * w.0[r][a].sqrt())
            .collect();
        s += z.iter().zip(&d).map(|(z, d)| 2.0 * z * d).sum::<f64>();
        for k in 0..=lags.min(n - 1) {
            let (mut gamma, mut c, mut pairs) = (0.0, 0.0, 0usize);
            let mut pair = |i: usize| {
                gamma += z[i] * z[i + k];
                c += d[i] * d[i + k];
                pairs += 1;
            };
            match &runs {
                // Each block's pairs in turn: the same pairs in the same order as the scan
                // below, without the rows of other blocks (most of them, at a lag near a
                // block's length).
                Some(runs) => {
                    for run in runs {
                        (run.start..run.end.saturating_sub(k)).for_each(&mut pair);
                    }
                }
                None => (0..n - k)
                    .filter(|&i| split.block[rows[i]] == split.block[rows[i + k]])
                    .for_each(&mut pair),
            }
            if pairs == 0 {
                continue;
            }
            // Bartlett weights keep the estimate positive.
            let weight = if k == 0 {
                1.0
            } else {
                2.0 * (1.0 - k as f64 / (lags + 1) as f64)
            };
            var += 4.0 * weight * (gamma / pairs as f64) * c;
        }
    }
    if !(var > 0.0) {
        return None;
    }
    Some(normal_sf(s / var.sqrt()))
}

/// The stretches of `rows` (increasing) that lie in one block each, where the rows' blocks
/// never decrease (a block's rows are then one stretch, and two rows share a block only
/// within one); None where they do.
fn block_runs(rows: &[usize], split: &Split) -> Option<Vec<std::ops::Range<usize>>> {
    let block = |i: usize| split.block[rows[i]];
    if (1..rows.len()).any(|i| block(i) < block(i - 1)) {
        return None;
    }
    let mut runs = Vec::new();
    let mut start = 0;
    for i in 1..=rows.len() {
        if i == rows.len() || block(i) != block(start) {
            runs.push(start..i);
            start = i;
        }
    }
    Some(runs)
}

/// Standardized residuals (divided by the noise sd).
pub(crate) fn standardized(resid: &[Vec3], w: &Weights) -> Vec<Vec3> {
    resid
        .iter()
        .zip(&w.0)
        .map(|(e, w)| Vec3::new(e.x * w[0].sqrt(), e.y * w[1].sqrt(), e.z * w[2].sqrt()))
        .collect()
}

/// Ljung-Box p-value per axis of the held-out standardized residuals.
pub(crate) fn whiteness(z: &[Vec3], split: &Split) -> [f64; 3] {
    residual_structure(z, split).map(|t| t.p)
}

/// The Ljung-Box test per axis of the held-out standardized residuals, pairs formed within a
/// held-out block only.
pub(crate) fn residual_structure(z: &[Vec3], split: &Split) -> [LjungBox; 3] {
    let rows: Vec<usize> = (0..z.len()).filter(|&r| split.holdout[r]).collect();
    let seg: Vec<usize> = rows.iter().map(|&r| split.block[r]).collect();
    std::array::from_fn(|a| {
        let za: Vec<f64> = rows.iter().map(|&r| z[r][a]).collect();
        ljung_box(&za, &seg, LAGS)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The noise-referenced test sums its lagged products block by block where the held-out
    /// rows' blocks never decrease: the same bits as the scan over every pair of rows that
    /// keeps the pairs within one block (how it summed them before), and the scan itself
    /// where blocks do decrease.
    #[test]
    fn block_by_block_sums_equal_the_scan_over_all_pairs() {
        let n = 3000;
        let t_s: Vec<f64> = (0..n).map(|r| r as f64 * 0.02).collect();
        let split = Split::new(&t_s, 1.0, 3);
        let wobble = |r: usize, a: usize| ((r * 7 + a * 13) % 17) as f64 / 17.0 - 0.5;
        let before: Vec<Vec3> = (0..n)
            .map(|r| Vec3::new(wobble(r, 0), wobble(r, 1), wobble(r, 2)) + Vec3::repeat(0.1))
            .collect();
        let after: Vec<Vec3> = before.iter().map(|v| v * 0.8).collect();
        let w = Weights(vec![[1.0, 2.0, 0.5]; n]);
        let held_out: Vec<usize> = (0..n).filter(|&r| split.holdout[r]).collect();
        assert!(block_runs(&held_out, &split).is_some_and(|runs| runs.len() > 10));
        let by_block = noise_referenced(&before, &after, &w, &split);
        let scanned = noise_referenced_by(&before, &after, &w, &split, false);
        assert!(by_block.is_some_and(|p| p < 1e-3), "{by_block:?}");
        assert_eq!(by_block.map(f64::to_bits), scanned.map(f64::to_bits));
        // Blocks numbered out of order: no runs, the scan's path.
        let mut shuffled = split.clone();
        for b in shuffled.block.iter_mut() {
            *b = (*b * 7) % 11;
        }
        assert!(block_runs(&held_out, &shuffled).is_none());
        let p = noise_referenced(&before, &after, &w, &shuffled);
        let scanned = noise_referenced_by(&before, &after, &w, &shuffled, false);
        assert_eq!(p.map(f64::to_bits), scanned.map(f64::to_bits), "{p:?}");
    }
}
