//! The weighted calibration shared by the baseline and every candidate: one design of
//! regressor columns, fitted per axis on the identification rows only, with inverse-variance
//! weights from the throttle-dependent noise model.
use magstand_core::Vec3;
use magstand_ident::least_squares::{NormalEquations, SharedRowEquations, SolveError};
use magstand_sim::replay::Trace;

/// Regressor columns (one value per row each) with their names.
#[derive(Debug, Clone, Default)]
pub(crate) struct Design {
    pub columns: Vec<Vec<f64>>,
    pub names: Vec<String>,
}

impl Design {
    /// Prediction of the design with coefficients `coef` (per column, per axis).
    pub fn predict(&self, coef: &[[f64; 3]]) -> Vec<Vec3> {
        let n = self.columns.first().map_or(0, Vec::len);
        (0..n)
            .map(|r| {
                coef.iter()
                    .zip(&self.columns)
                    .fold(Vec3::zeros(), |v, (c, col)| v + Vec3::from(*c) * col[r])
            })
            .collect()
    }

    /// The nominal physics: field linear in the motor currents, each motor's current a smooth
    /// function of its rotor speed while its ESC drives it (idle current, then powers of speed;
    /// the cubic term lets the calibration follow a current law other than the nominal one) and
    /// zero while it coasts. Columns are sums over motors, because the nominal stand treats all
    /// motors alike. With `measured_current`, the trace's supply current is a measured one
    /// (a flight's `bat_a`), which the commands' speeds only approximate: the field linear in
    /// it is a column of its own.
    pub fn baseline(trace: &Trace, measured_current: bool) -> Design {
        let n = trace.len();
        let mut d = Design::default();
        d.push("reference", vec![1.0; n]);
        // Each row's sums over the motors, motor after motor (the order of a sum per row), a
        // column at a time so that the loops run over contiguous rows; the powers by
        // multiplication (the bits `powi` gives for 2 and 3).
        let mut driven = vec![0.0; n];
        let mut powers: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        for (speed, on) in trace.speed.iter().zip(&trace.driven) {
            let [p1, p2, p3] = &mut powers;
            // Every column of the same length, so the loop runs without bounds checks.
            let (speed, on, driven) = (&speed[..n], &on[..n], &mut driven[..n]);
            let (p1, p2, p3) = (&mut p1[..n], &mut p2[..n], &mut p3[..n]);
            for r in 0..n {
                let (s, d) = (speed[r], on[r]);
                driven[r] += d;
                p1[r] += d * s;
                p2[r] += d * (s * s);
                p3[r] += d * (s * (s * s));
            }
        }
        d.push("driven", driven);
        for (k, column) in powers.into_iter().enumerate() {
            d.push(format!("speed^{}", k + 1), column);
        }
        if measured_current {
            d.push("current_a", trace.total_a.clone());
        }
        d
    }

    pub fn push(&mut self, name: impl Into<String>, column: Vec<f64>) {
        self.names.push(name.into());
        self.columns.push(column);
    }

    pub fn len(&self) -> usize {
        self.columns.len()
    }
}

/// Inverse noise variance of every row and axis.
#[derive(Debug, Clone)]
pub(crate) struct Weights(pub Vec<[f64; 3]>);

/// A calibrated design.
#[derive(Debug, Clone)]
pub(crate) struct Fitted {
    /// Coefficient of each column, per axis.
    pub coef: Vec<[f64; 3]>,
    /// Standard deviation of each coefficient, per axis (from the weights).
    pub coef_sd: Vec<[f64; 3]>,
    /// Prediction for every row, including any fixed part.
    pub pred: Vec<Vec3>,
    /// Weighted squared residual summed over identification rows and axes.
    pub chi2_fit: f64,
}

impl Fitted {
    /// Residual of every row.
    pub fn residuals(&self, y: &[Vec3]) -> Vec<Vec3> {
        y.iter().zip(&self.pred).map(|(y, p)| y - p).collect()
    }
}

/// Rows from which a fit's sums are split over two threads: fewer cost less than the split.
const PARALLEL_FIT_ROWS: usize = 4096;

/// Fits `design` to `y - fixed` on the rows not held out, per axis, and predicts every row.
pub(crate) fn fit(
    design: &Design,
    y: &[Vec3],
    fixed: Option<&[Vec3]>,
    weights: &Weights,
    holdout: &[bool],
) -> Result<Fitted, SolveError> {
    let p = design.len();
    let n = y.len();
    let target = |r: usize| match fixed {
        Some(f) => y[r] - f[r],
        None => y[r],
    };
    // The sums of a range of rows, per axis.
    let sums = |rows: std::ops::Range<usize>| {
        let mut ne = SharedRowEquations::<3>::new(p);
        let mut x = vec![0.0; p];
        for r in rows.filter(|&r| !holdout[r]) {
            for (xj, col) in x.iter_mut().zip(&design.columns) {
                *xj = col[r];
            }
            let t = target(r);
            ne.add(&x, [t.x, t.y, t.z], weights.0[r]);
        }
        ne
    };
    // Two fixed halves, summed on both cores when one is free (the searches' sequential steps
    // leave one idle), merged in the same order whatever the thread count.
    let half = n / 2;
    let (mut ne, second) = if n >= PARALLEL_FIT_ROWS {
        rayon::join(|| sums(0..half), || sums(half..n))
    } else {
        (sums(0..half), sums(half..n))
    };
    ne.merge(&second);
    let ne = ne.into_equations();
    let mut coef = vec![[0.0; 3]; p];
    let mut coef_sd = vec![[0.0; 3]; p];
    for a in 0..3 {
        let theta = ne[a].solve()?;
        let var = ne[a].coefficient_variances()?;
        for j in 0..p {
            coef[j][a] = theta[(j, 0)];
            coef_sd[j][a] = var[j].max(0.0).sqrt();
        }
    }
    let mut pred = design.predict(&coef);
    let mut chi2_fit = 0.0;
    for (r, v) in pred.iter_mut().enumerate() {
        if let Some(f) = fixed {
            *v += f[r];
        }
        if !holdout[r] {
            let e = y[r] - *v;
            chi2_fit += (0..3).map(|a| weights.0[r][a] * e[a] * e[a]).sum::<f64>();
        }
    }
    Ok(Fitted {
        coef,
        coef_sd,
        pred,
        chi2_fit,
    })
}

/// `max(c0 + c1 q + c2 q², floor)` per axis: the variance law of [`VarianceModel`], also
/// evaluated from a model file's [`NoiseLaw`](crate::augmented_model::NoiseLaw).
pub(crate) fn variance_at(coef: &[[f64; 3]; 3], floor: &[f64; 3], q: f64) -> [f64; 3] {
    std::array::from_fn(|a| (coef[0][a] + coef[1][a] * q + coef[2][a] * q * q).max(floor[a]))
}

/// Noise variance growing with the load, per axis: `c0 + c1 q + c2 q^2`, q the motor current
/// over its largest value (eq. 8: the variance grows with the control input).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct VarianceModel {
    coef: [[f64; 3]; 3],
    floor: [f64; 3],
}

impl VarianceModel {
    /// Fits the squared residuals of the identification rows.
    pub fn fit(resid: &[Vec3], q: &[f64], holdout: &[bool]) -> VarianceModel {
        let mut ne = NormalEquations::new(3, 3);
        let mut mean = [0.0; 3];
        let mut count = 0.0f64;
        for r in (0..resid.len()).filter(|&r| !holdout[r]) {
            let e2 = [resid[r].x.powi(2), resid[r].y.powi(2), resid[r].z.powi(2)];
            ne.add(&[1.0, q[r], q[r] * q[r]], &e2, 1.0);
            for a in 0..3 {
                mean[a] += e2[a];
            }
            count += 1.0;
        }
        let mean = mean.map(|m| m / count.max(1.0));
        // A variance model that reached zero would give one row all the weight.
        let floor = mean.map(|m| (0.05 * m).max(1e-12));
        let coef = match ne.solve() {
            Ok(c) => std::array::from_fn(|k| std::array::from_fn(|a| c[(k, a)])),
            Err(_) => [mean, [0.0; 3], [0.0; 3]],
        };
        VarianceModel { coef, floor }
    }

    /// The law as stored in a model file, with the motor current `full_load_a` that `q = 1`
    /// stands for.
    pub fn to_noise(&self, full_load_a: f64) -> crate::augmented_model::NoiseLaw {
        crate::augmented_model::NoiseLaw {
            variance_ut2: self.coef,
            floor_ut2: self.floor,
            full_load_a,
        }
    }

    /// Variance at load `q`, per axis.
    pub fn at(&self, q: f64) -> [f64; 3] {
        variance_at(&self.coef, &self.floor, q)
    }

    /// Inverse variances of every row: the noise at the row's load plus the spread of the
    /// prediction over the unknown moment, within one sample interval, at which a logged
    /// command changed (`timing`: prediction with the change at the end of the interval minus
    /// the one with it at the start; uniform over the interval, so its square over 12).
    pub fn weights(&self, q: &[f64], timing: &[Vec3]) -> Weights {
        Weights(
            q.iter()
                .zip(timing)
                .map(|(&q, d)| {
                    let noise = self.at(q);
                    std::array::from_fn(|k| 1.0 / (noise[k] + d[k] * d[k] / 12.0))
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_exact_coefficients_and_the_variance_law() {
        let n = 400;
        let x: Vec<f64> = (0..n).map(|k| k as f64 / n as f64).collect();
        let mut d = Design::default();
        d.push("one", vec![1.0; n]);
        d.push("x", x.clone());
        let y: Vec<Vec3> = x
            .iter()
            .map(|&x| Vec3::new(1.0 + 2.0 * x, -3.0 * x, 0.5))
            .collect();
        let w = Weights(vec![[1.0; 3]; n]);
        let hold: Vec<bool> = (0..n).map(|k| k % 3 == 2).collect();
        let f = fit(&d, &y, None, &w, &hold).unwrap();
        assert!((f.coef[1][0] - 2.0).abs() < 1e-10 && (f.coef[1][1] + 3.0).abs() < 1e-10);
        assert!(f.chi2_fit < 1e-18, "{}", f.chi2_fit);
        // Squared residuals exactly 0.1 + 0.4 q^2 on x, constant 0.2 elsewhere.
        let res: Vec<Vec3> = x
            .iter()
            .map(|&q| Vec3::new((0.1 + 0.4 * q * q).sqrt(), 0.2f64.sqrt(), 0.2f64.sqrt()))
            .collect();
        let v = VarianceModel::fit(&res, &x, &hold);
        let at = v.at(0.5);
        assert!(
            (at[0] - 0.2).abs() < 1e-9 && (at[1] - 0.2).abs() < 1e-9,
            "{at:?}"
        );
    }
}
