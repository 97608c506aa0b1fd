//! The Cramer-Rao lower bound for the paper's fixed structure, and the parameters it bounds.
//!
//! The fixed structure (3 RBFs at 0, 0.5, 1, width 4, local lines `a_i u + b_i`) is linear in its
//! parameters: `y_k = z_k^T theta + e_k` per axis, with `z_k = [phi_1 u, phi_1, ..., phi_3 u,
//! phi_3]` at the row's normalized throttle and `e_k` Gaussian with the simulator's true sd
//! `s_k`. The Fisher information is `F = sum_k z_k z_k^T / s_k^2 = X^T W X` and no unbiased
//! estimator has a covariance below `F^-1`.
//!
//! What the estimators aim at: the simulated disturbance comes from physics, not from this
//! structure, so the "true parameters" are the structure's inverse-variance weighted best fit
//! to the noise-free true disturbance (the pseudo-true parameters, the limit of an efficient
//! estimator). For a scenario whose disturbance *is* the paper's Tables I-III, they are the
//! tables. An unweighted estimator converges elsewhere when the structure is only an
//! approximation; that difference shows as bias (`mse_crlb_ratio`), not as variance
//! (`crlb_ratio`).
//!
//! The motors-off reference is a parameter too: motors-off rows read `r + noise`, the others
//! `r + z_k^T theta + noise`. Eq. 9 defines the disturbance as zero at zero command
//! (`z_0^T theta = 0`), which the estimators use when they subtract the motors-off mean, so the
//! bound is the constrained Cramer-Rao bound of `theta` in that joint model.
use magstand_core::Recording;
use magstand_core::rbf::RbfPartition;
use magstand_ident::local_linear;
use magstand_ident::{Dataset, Estimation, InputKind, LocalLinearNet, Model, Structure};
use nalgebra::{DMatrix, DVector};

/// Number of parameters per axis of the fixed structure.
pub const PARAMS_PER_AXIS: usize = 6;

/// Parameter names per axis, in the order of [`flatten`].
pub fn parameter_names() -> [&'static str; PARAMS_PER_AXIS] {
    ["a1", "b1", "a2", "b2", "a3", "b3"]
}

/// The pseudo-true parameters and the bound on one identification series.
#[derive(Debug, Clone)]
pub struct Bound {
    /// Pseudo-true parameters per axis.
    pub truth: [Vec<f64>; 3],
    /// Diagonal of the CRLB per axis (variance of each parameter), µT² per unit.
    pub crlb_diag: [Vec<f64>; 3],
}

/// A fixed-structure model's parameters per axis, `[a1, b1, a2, b2, a3, b3]`.
pub fn flatten(model: &Model) -> Option<[Vec<f64>; 3]> {
    match &model.structure {
        Structure::LocalLinear(net) if net.partition.len() * 2 == PARAMS_PER_AXIS => {
            Some(net_parameters(net))
        }
        _ => None,
    }
}

/// A local linear network's coefficients per axis, local model after local model.
fn net_parameters(net: &LocalLinearNet) -> [Vec<f64>; 3] {
    std::array::from_fn(|a| net.coefficients[a].iter().flatten().copied().collect())
}

/// The bound for the paper's fixed structure on `rec`, or `None` when the recording has no
/// truth, no noise, or data that cannot determine the parameters.
pub fn fixed_structure_bound(rec: &Recording) -> Option<Bound> {
    let truth = rec.truth.as_ref()?;
    let data = Dataset::from_recording(rec, InputKind::Throttle, "bound").ok()?;
    let sd = &truth.sd_ut;
    if sd
        .iter()
        .any(|s| s.iter().any(|v| !(*v > 0.0 && v.is_finite())))
    {
        return None;
    }
    // The pseudo-true parameters: the inverse-variance weighted fit to the noise-free truth,
    // the value an efficient estimator converges to (the tables themselves when the
    // disturbance has this structure).
    let mut clean = data.clone();
    clean.y = truth.dist_ut.as_slice().into();
    let partition = RbfPartition::paper();
    let inverse_variance = |k: usize| sd[k].map(|s| 1.0 / (s * s));
    let net = local_linear::fit(
        &clean,
        &partition,
        Estimation::Global,
        &|_| true,
        &inverse_variance,
    )
    .ok()?;
    let off: Vec<bool> = (0..rec.len()).map(|r| rec.motors_off(r)).collect();
    let crlb_diag = fisher_inverse_diagonal(&data, &off, &net, sd)?;
    Some(Bound {
        truth: net_parameters(&net),
        crlb_diag,
    })
}

fn fisher_inverse_diagonal(
    data: &Dataset,
    off: &[bool],
    net: &LocalLinearNet,
    sd: &[magstand_core::Vec3],
) -> Option<[Vec<f64>; 3]> {
    let m = net.partition.len();
    let p = data.spec.regressor_count();
    let n = m * p;
    // Joint parameters: the model's n, then the field reference r (the motors-off reading).
    let mut fisher: [DMatrix<f64>; 3] = std::array::from_fn(|_| DMatrix::zeros(n + 1, n + 1));
    let mut phi = vec![0.0; m];
    let mut z = DVector::zeros(n + 1);
    for k in 0..data.len() {
        if off[k] {
            // Motors off: the reading is the reference plus noise, no disturbance.
            z.fill(0.0);
        } else {
            net.partition.weights_into(data.u[k], &mut phi);
            let x = data.regressors(k);
            for i in 0..m {
                for j in 0..p {
                    z[i * p + j] = phi[i] * x[j];
                }
            }
        }
        z[n] = 1.0;
        for (a, f) in fisher.iter_mut().enumerate() {
            let s = sd[k][a];
            f.syger(1.0 / (s * s), &z, &z, 1.0);
        }
    }
    // Eq. 9 defines the disturbance as zero at zero command: c^T theta = 0 with c the model's
    // regressors at u = 0. The constrained bound is U (U^T F U)^-1 U^T, with U a basis of the
    // constraint's null space (eliminate the parameter with the largest coefficient).
    net.partition
        .weights_into(data.spec.normalize(data.spec.off_raw), &mut phi);
    let mut c = vec![0.0; n + 1];
    let mut x0 = vec![0.0; p];
    data.spec.off_regressors(&mut x0);
    for i in 0..m {
        for j in 0..p {
            c[i * p + j] = phi[i] * x0[j];
        }
    }
    let pivot = (0..n).max_by(|&i, &j| c[i].abs().total_cmp(&c[j].abs()))?;
    if c[pivot].abs() < 1e-12 {
        return None;
    }
    let free: Vec<usize> = (0..=n).filter(|&i| i != pivot).collect();
    let u = DMatrix::from_fn(n + 1, n, |row, col| {
        if row == pivot {
            -c[free[col]] / c[pivot]
        } else if row == free[col] {
            1.0
        } else {
            0.0
        }
    });
    let mut out: [Vec<f64>; 3] = Default::default();
    for (a, mut f) in fisher.into_iter().enumerate() {
        // `syger` filled the lower triangle only.
        f.fill_upper_triangle_with_lower_triangle();
        let reduced = u.transpose() * &f * &u;
        // The bound is a covariance, (U^T F U)^-1 itself; it comes from Cholesky solves.
        let chol = reduced.cholesky()?;
        let cov = &u * chol.solve(&u.transpose());
        out[a] = (0..n).map(|i| cov[(i, i)]).collect();
    }
    Some(out)
}
