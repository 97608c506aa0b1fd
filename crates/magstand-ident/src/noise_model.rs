//! The noise standard deviation as a function of the input: the paper's "variance grows with
//! control input", fitted and kept with the model so that a Kalman filter can use it as a
//! throttle-dependent measurement noise.
//!
//! Per axis, the variance is a linear spline over evenly spaced knots of the normalized input,
//! fitted to squared residuals; the sd is its square root.
use serde::{Deserialize, Serialize};

use crate::least_squares::NormalEquations;
use magstand_core::Vec3;

/// Standard deviation per axis at knots of the normalized input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SdModel {
    /// Knots of the normalized input, increasing.
    pub knots: Vec<f64>,
    /// Standard deviation at each knot, µT: `sd_ut[axis][knot]`.
    pub sd_ut: [Vec<f64>; 3],
}

fn hat(knots: &[f64], u: f64, out: &mut [(usize, f64); 2]) -> usize {
    let n = knots.len();
    if u <= knots[0] {
        out[0] = (0, 1.0);
        return 1;
    }
    if u >= knots[n - 1] {
        out[0] = (n - 1, 1.0);
        return 1;
    }
    let k = knots.partition_point(|&c| c <= u).clamp(1, n - 1);
    let f = (u - knots[k - 1]) / (knots[k] - knots[k - 1]);
    out[0] = (k - 1, 1.0 - f);
    out[1] = (k, f);
    2
}

impl SdModel {
    /// Fits the model to residuals `r` at normalized inputs `u`, using rows where `use_row` is
    /// true: the variance is a linear spline over the knots, fitted to the squared residuals by
    /// least squares, with a light second-difference penalty so that knots without data are
    /// bridged linearly. Returns `None` when fewer than two rows are usable.
    pub fn fit(
        u: &[f64],
        r: &[Vec3],
        use_row: impl Fn(usize) -> bool + Sync,
        knots: usize,
    ) -> Option<Self> {
        let knots: Vec<f64> = (0..knots).map(|k| k as f64 / (knots - 1) as f64).collect();
        let n = knots.len();
        let mut row = vec![0.0; n];
        // Summed in fixed chunks on every core, in chunk order: the sums do not depend on the
        // thread count (and up to a chunk of rows is one pass in row order).
        let (mut ne, used) = crate::local_linear::sum_in_chunks(
            u.len().min(r.len()),
            crate::local_linear::FIT_CHUNK_ROWS,
            |range| {
                let mut ne = NormalEquations::new(n, 3);
                let mut h = [(0, 0.0); 2];
                let mut used = 0usize;
                for i in range.filter(|&i| use_row(i)) {
                    used += 1;
                    // A row touches at most two knots (ascending): only those enter the sums.
                    let m = hat(&knots, u[i], &mut h);
                    let (cols, vals) = ([h[0].0, h[1].0], [h[0].1, h[1].1]);
                    let sq = r[i].component_mul(&r[i]);
                    ne.add_sparse(&cols[..m], &vals[..m], &[sq.x, sq.y, sq.z], 1.0);
                }
                (ne, used)
            },
            |(sum, used), (part, more)| {
                sum.merge(&part);
                *used += more;
            },
        );
        if used < 2 {
            return None;
        }
        // Penalty weight: negligible against the data where there is data.
        let lambda = 1e-6 * used as f64;
        for k in 1..n - 1 {
            row[k - 1] = 1.0;
            row[k] = -2.0;
            row[k + 1] = 1.0;
            ne.add(&row, &[0.0, 0.0, 0.0], lambda);
            row[k - 1] = 0.0;
            row[k] = 0.0;
            row[k + 1] = 0.0;
        }
        let var = ne.solve().ok()?;
        let sd_ut = [0, 1, 2].map(|a| {
            let top = (0..n).map(|k| var[(k, a)]).fold(0.0, f64::max);
            // Floor: a knot of zero (or, from the spline, negative) variance would get infinite weight.
            let floor = (top * 1e-4).max(1e-12);
            (0..n).map(|k| var[(k, a)].max(floor).sqrt()).collect()
        });
        Some(SdModel { knots, sd_ut })
    }

    /// Standard deviation at normalized input `u`, per axis, µT.
    pub fn sd(&self, u: f64) -> Vec3 {
        let mut h = [(0, 0.0); 2];
        let m = hat(&self.knots, u, &mut h);
        Vec3::from_fn(|a, _| h[..m].iter().map(|&(k, w)| w * self.sd_ut[a][k]).sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_linear_sd_law() {
        // Residuals +-s(u) alternate, so the mean square at u is exactly s(u)^2 = (0.2 + u)^2.
        let n = 20_001;
        let u: Vec<f64> = (0..n).map(|k| k as f64 / (n - 1) as f64).collect();
        let r: Vec<Vec3> = u
            .iter()
            .enumerate()
            .map(|(k, &x)| Vec3::repeat((0.2 + x) * if k % 2 == 0 { 1.0 } else { -1.0 }))
            .collect();
        let m = SdModel::fit(&u, &r, |_| true, 11).unwrap();
        for x in [0.0, 0.35, 1.0] {
            let got = m.sd(x).x;
            assert!((got - (0.2 + x)).abs() < 0.005, "sd({x}) = {got}");
        }
    }

    #[test]
    fn knots_without_data_are_interpolated() {
        let u = vec![0.0; 50]
            .into_iter()
            .chain(vec![1.0; 50])
            .collect::<Vec<_>>();
        let r: Vec<Vec3> = (0..100)
            .map(|k| Vec3::repeat(if k < 50 { 1.0 } else { 3.0 }))
            .collect();
        let m = SdModel::fit(&u, &r, |_| true, 5).unwrap();
        assert!(
            (m.sd(0.5).y - (5.0f64).sqrt()).abs() < 1e-9,
            "{}",
            m.sd(0.5)
        );
    }
}
