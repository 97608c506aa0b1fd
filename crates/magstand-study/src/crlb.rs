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
//! The bound treats the eq. 9 motors-off reference as known. Its own error (variance
//! `s_0^2 / n_off`, about 1e-5 µT² for ten seconds at 100 Hz) moves every intercept together and
//! is negligible next to the parameter variances of a stair run.
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
            Some(std::array::from_fn(|a| {
                net.coefficients[a].iter().flatten().copied().collect()
            }))
        }
        _ => None,
    }
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
    clean.y = truth.dist_ut.clone();
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
    let crlb_diag = fisher_inverse_diagonal(&data, &net, sd)?;
    Some(Bound {
        truth: std::array::from_fn(|a| net.coefficients[a].iter().flatten().copied().collect()),
        crlb_diag,
    })
}

fn fisher_inverse_diagonal(
    data: &Dataset,
    net: &LocalLinearNet,
    sd: &[magstand_core::Vec3],
) -> Option<[Vec<f64>; 3]> {
    let m = net.partition.len();
    let p = data.spec.regressor_count();
    let n = m * p;
    let mut fisher: [DMatrix<f64>; 3] = std::array::from_fn(|_| DMatrix::zeros(n, n));
    let mut phi = vec![0.0; m];
    let mut z = DVector::zeros(n);
    for k in 0..data.len() {
        net.partition.weights_into(data.u[k], &mut phi);
        let x = data.regressors(k);
        for i in 0..m {
            for j in 0..p {
                z[i * p + j] = phi[i] * x[j];
            }
        }
        for (a, f) in fisher.iter_mut().enumerate() {
            let s = sd[k][a];
            f.syger(1.0 / (s * s), &z, &z, 1.0);
        }
    }
    let mut out: [Vec<f64>; 3] = Default::default();
    for (a, f) in fisher.into_iter().enumerate() {
        // The bound is the covariance F^-1 itself; its diagonal comes from Cholesky solves
        // against the unit vectors.
        let chol = f.cholesky()?;
        let cov = chol.solve(&DMatrix::identity(n, n));
        out[a] = (0..n).map(|i| cov[(i, i)]).collect();
    }
    Some(out)
}
