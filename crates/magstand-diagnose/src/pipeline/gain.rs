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
    let rows: Vec<usize> = (0..before.len()).filter(|&r| split.holdout[r]).collect();
    let n = rows.len();
    if n < 10 {
        return None;
    }
    let lags = (n / split.holdout_blocks().max(1)).clamp(1, 400);
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
            for i in 0..n - k {
                if split.block[rows[i]] == split.block[rows[i + k]] {
                    gamma += z[i] * z[i + k];
                    c += d[i] * d[i + k];
                    pairs += 1;
                }
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
