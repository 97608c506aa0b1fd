//! Normalized Gaussian radial basis functions over one scheduling input, and the blended
//! local linear form of Czyba, Janusz and Szafranski:
//!
//! * eq. 13: `phi_i^UN(u) = exp(-(eps_i * |c_i - u|)^2)`
//! * eq. 14: `phi_i = phi_i^UN / sum_j phi_j^UN`
//! * eq. 12 with eq. 17: `y(u) = sum_i phi_i(u) * (a_i * u + b_i)`
//!
//! The normalization is computed in log space so that an input far from every centre (where
//! each `exp` underflows to zero) still gets weights that sum to one instead of `0/0 = NaN`.
use serde::{Deserialize, Serialize};

/// Centres and widths of the normalized Gaussian RBFs that partition the input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RbfPartition {
    centers: Vec<f64>,
    widths: Vec<f64>,
}

impl RbfPartition {
    /// A partition with one width parameter `eps` per centre (the paper's ε, eq. 13).
    ///
    /// Returns `None` when there are no centres, the lengths differ, or a value is not finite
    /// or a width is not positive.
    pub fn new(centers: Vec<f64>, widths: Vec<f64>) -> Option<Self> {
        let ok = !centers.is_empty()
            && centers.len() == widths.len()
            && centers.iter().all(|c| c.is_finite())
            && widths.iter().all(|w| w.is_finite() && *w > 0.0);
        ok.then_some(Self { centers, widths })
    }

    /// A partition whose centres all share one width parameter.
    pub fn uniform_width(centers: Vec<f64>, eps: f64) -> Option<Self> {
        let widths = vec![eps; centers.len()];
        Self::new(centers, widths)
    }

    /// The paper's partition: centres 0, 0.5 and 1, width parameter 4.
    pub fn paper() -> Self {
        Self::uniform_width(vec![0.0, 0.5, 1.0], 4.0).expect("constant, valid partition")
    }

    /// Number of RBFs (local models).
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// Always false: a partition has at least one RBF.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The centres `c_i`.
    pub fn centers(&self) -> &[f64] {
        &self.centers
    }

    /// The width parameters `eps_i`.
    pub fn widths(&self) -> &[f64] {
        &self.widths
    }

    /// Writes the normalized weights `phi_i(u)` into `out` (length [`len`](Self::len)).
    pub fn weights_into(&self, u: f64, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.len(), "weights buffer length");
        let mut min_exponent = f64::INFINITY;
        for (k, (c, e)) in self.centers.iter().zip(&self.widths).enumerate() {
            let d = e * (c - u);
            out[k] = d * d;
            min_exponent = min_exponent.min(out[k]);
        }
        let mut sum = 0.0;
        for w in out.iter_mut() {
            *w = (min_exponent - *w).exp();
            sum += *w;
        }
        for w in out.iter_mut() {
            *w /= sum;
        }
    }

    /// The normalized weights at `u` as a new vector.
    pub fn weights(&self, u: f64) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.weights_into(u, &mut out);
        out
    }
}

/// A one-input local linear model network: local lines `a_i u + b_i` blended by an
/// [`RbfPartition`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalLinear1d {
    partition: RbfPartition,
    slopes: Vec<f64>,
    intercepts: Vec<f64>,
}

impl LocalLinear1d {
    /// Builds the model; `None` if the slope or intercept count differs from the partition's
    /// size or a value is not finite.
    pub fn new(partition: RbfPartition, slopes: Vec<f64>, intercepts: Vec<f64>) -> Option<Self> {
        let ok = slopes.len() == partition.len()
            && intercepts.len() == partition.len()
            && slopes.iter().chain(&intercepts).all(|v| v.is_finite());
        ok.then_some(Self {
            partition,
            slopes,
            intercepts,
        })
    }

    /// The partition.
    pub fn partition(&self) -> &RbfPartition {
        &self.partition
    }

    /// Local slopes `a_i`.
    pub fn slopes(&self) -> &[f64] {
        &self.slopes
    }

    /// Local intercepts `b_i`.
    pub fn intercepts(&self) -> &[f64] {
        &self.intercepts
    }

    /// Model output `y(u)` (eq. 12).
    pub fn eval(&self, u: f64) -> f64 {
        let mut w = [0.0; 16];
        let mut heap;
        let w: &mut [f64] = if self.partition.len() <= 16 {
            &mut w[..self.partition.len()]
        } else {
            heap = vec![0.0; self.partition.len()];
            &mut heap
        };
        self.partition.weights_into(u, w);
        w.iter()
            .zip(self.slopes.iter().zip(&self.intercepts))
            .map(|(phi, (a, b))| phi * (a * u + b))
            .sum()
    }
}

/// The paper's identified models, Tables I-III: one [`LocalLinear1d`] per axis (x, y, z), input
/// the normalized overall throttle, output in gauss as printed.
pub fn paper_tables() -> [LocalLinear1d; 3] {
    let m = |a: [f64; 3], b: [f64; 3]| {
        LocalLinear1d::new(RbfPartition::paper(), a.to_vec(), b.to_vec())
            .expect("constant tables are valid")
    };
    [
        m(
            [0.01393995, 0.04419968, 0.08254094],
            [-0.00504612, -0.01422156, -0.0414244],
        ),
        m(
            [0.0181899, 0.09792892, 0.17656376],
            [-0.00097538, -0.02581569, -0.0803944],
        ),
        m(
            [-0.03699222, -0.17482412, -0.27373477],
            [0.00264913, 0.04486959, 0.11159597],
        ),
    ]
}

/// Microtesla per gauss.
pub const UT_PER_GAUSS: f64 = 100.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one_and_peak_at_their_centre() {
        let p = RbfPartition::paper();
        for k in 0..=100 {
            let u = k as f64 / 100.0;
            let w = p.weights(u);
            let s: f64 = w.iter().sum();
            assert!((s - 1.0).abs() < 1e-12, "weights at u={u} sum to {s}");
        }
        assert!(p.weights(0.0)[0] > 0.9);
        assert!(p.weights(0.5)[1] > 0.9);
        assert!(p.weights(1.0)[2] > 0.9);
    }

    #[test]
    fn weights_match_the_closed_form() {
        // At u = 0.25 the first two RBFs are equidistant: exp(-(4*0.25)^2) = e^-1 each, and the
        // third is exp(-(4*0.75)^2) = e^-9.
        let w = RbfPartition::paper().weights(0.25);
        let (e1, e9) = ((-1.0f64).exp(), (-9.0f64).exp());
        let s = 2.0 * e1 + e9;
        assert!(
            (w[0] - e1 / s).abs() < 1e-15 && (w[1] - e1 / s).abs() < 1e-15,
            "{w:?}"
        );
        assert!((w[2] - e9 / s).abs() < 1e-15, "{w:?}");
    }

    #[test]
    fn far_inputs_do_not_give_nan() {
        let p = RbfPartition::uniform_width(vec![0.0, 1.0], 100.0).unwrap();
        let w = p.weights(50.0);
        assert!(w.iter().all(|x| x.is_finite()), "{w:?}");
        assert!((w[1] - 1.0).abs() < 1e-12, "{w:?}");
    }

    #[test]
    fn bad_partitions_are_refused() {
        assert!(RbfPartition::new(vec![], vec![]).is_none());
        assert!(RbfPartition::new(vec![0.0], vec![0.0]).is_none());
        assert!(RbfPartition::new(vec![f64::NAN], vec![1.0]).is_none());
        assert!(RbfPartition::new(vec![0.0, 1.0], vec![1.0]).is_none());
    }

    #[test]
    fn paper_tables_give_the_papers_full_throttle_deviation() {
        // The issue sizes the paper-like disturbance as about 4, 10 and -16 uT at full throttle.
        let t = paper_tables();
        let full: Vec<f64> = t
            .iter()
            .map(|m| (m.eval(1.0) - m.eval(0.0)) * UT_PER_GAUSS)
            .collect();
        assert!((full[0] - 4.6).abs() < 0.5, "{full:?}");
        assert!((full[1] - 9.7).abs() < 0.5, "{full:?}");
        assert!((full[2] + 16.4).abs() < 0.7, "{full:?}");
    }
}
