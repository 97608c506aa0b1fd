//! RBF-blended local linear models (eq. 10-14) and their two estimators.
//!
//! * Local estimation (eq. 15-19), the paper's: one weighted least squares per local model with
//!   weights `Q_i = diag(phi_i)`. Each local line is fitted to the data it is responsible for,
//!   so when the data come from a model of exactly this form it does *not* return that model's
//!   parameters (it fits each line to the blended curve around its centre).
//! * Global estimation: all local models in one least squares over the regressors
//!   `[phi_1 x, ..., phi_M x]`, which does return them.
//!
//! Both accept per-row, per-axis weights (inverse noise variances for the heteroscedastic fit).
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::IdentError;
use crate::dataset::Dataset;
use crate::least_squares::{NormalEquations, SolveError};
use magstand_core::Vec3;
use magstand_core::rbf::RbfPartition;

/// Local or global estimation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Estimation {
    /// One weighted least squares per local model (the paper's eq. 16).
    Local,
    /// All local models in one least squares.
    Global,
}

/// A fitted local linear network for the three axes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalLinearNet {
    /// The RBF partition of the normalized input (shared by the axes).
    pub partition: RbfPartition,
    /// `coefficients[axis][model]`: the local model's coefficients over the regressors
    /// (`[a_i, b_i]` for one input: slope per normalized input unit and intercept, µT).
    pub coefficients: [Vec<Vec<f64>>; 3],
}

impl LocalLinearNet {
    /// Output per axis at normalized input `u` and regressors `x` (eq. 12).
    pub fn eval(&self, u: f64, x: &[f64], phi: &mut [f64]) -> Vec3 {
        self.partition.weights_into(u, phi);
        Vec3::from_fn(|a, _| {
            self.coefficients[a]
                .iter()
                .zip(phi.iter())
                .map(|(theta, w)| w * theta.iter().zip(x).map(|(t, xi)| t * xi).sum::<f64>())
                .sum()
        })
    }
}

pub(crate) fn singular(data: &Dataset, what: &str, e: SolveError) -> IdentError {
    let why = match e {
        SolveError::NoData => "no rows carry weight".to_string(),
        SolveError::Singular { column, rcond } => {
            let regs = data.spec.regressor_count();
            let (model, reg) = (column / regs, column % regs);
            let name = match data.spec.kind {
                crate::InputKind::Motors if reg < regs - 1 => format!("thr_{}", reg + 1),
                _ if reg == regs - 1 => "intercept".to_string(),
                _ => "input".to_string(),
            };
            format!(
                "regressor `{name}` of local model {} is not independent of the others on this data (reciprocal condition {rcond:.1e}); \
                 the input does not vary enough where that model is responsible, or per-motor commands never differ",
                model + 1
            )
        }
    };
    IdentError::Singular {
        origin: data.origin.clone(),
        what: what.into(),
        why,
    }
}

/// Smallest normalized membership with which a row enters a local model's global fit.
pub const MIN_MEMBERSHIP: f64 = 1e-12;

/// Rows one worker accumulates at a time when a fit runs on every row of a long recording.
/// The chunks are fixed by the row count alone and summed in order, so the coefficients do not
/// depend on the number of threads.
pub const FIT_CHUNK_ROWS: usize = 1 << 16;

/// Fits the network on the rows where `use_row` is true, weighting row `k` on axis `a` by
/// `weight(k)[a]`.
pub fn fit(
    data: &Dataset,
    partition: &RbfPartition,
    estimation: Estimation,
    use_row: &(dyn Fn(usize) -> bool + Sync),
    weight: &(dyn Fn(usize) -> Vec3 + Sync),
) -> Result<LocalLinearNet, IdentError> {
    if data.group_index().is_some() {
        // Rows of equal input and regressors summed first: the same normal equations, with
        // the memberships computed once per distinct input.
        return crate::row_groups::Groups::of(data, use_row, weight).fit(partition, estimation);
    }
    let equations = NetEquations::of_rows(data, partition, estimation, use_row, weight);
    equations.solve(data)
}

/// Fits as [`fit`] does, and keeps the normal equations where the rows were summed one by one
/// (inputs that do not repeat): rows added to them later ([`NetEquations::add_rows`]) then
/// give the fit on both sets of rows without a second pass over the first.
pub(crate) fn fit_keeping_equations(
    data: &Dataset,
    partition: &RbfPartition,
    estimation: Estimation,
    use_row: &(dyn Fn(usize) -> bool + Sync),
    weight: &(dyn Fn(usize) -> Vec3 + Sync),
) -> Result<(LocalLinearNet, Option<NetEquations>), IdentError> {
    if data.group_index().is_some() {
        return Ok((fit(data, partition, estimation, use_row, weight)?, None));
    }
    let equations = NetEquations::of_rows(data, partition, estimation, use_row, weight);
    Ok((equations.solve(data)?, Some(equations)))
}

/// A network's normal equations over some rows, before the solve.
#[derive(Debug, Clone)]
pub(crate) struct NetEquations {
    partition: RbfPartition,
    estimation: Estimation,
    sums: Accumulated,
}

impl NetEquations {
    /// The equations of the rows where `use_row` is true, row `k` weighted by `weight(k)`,
    /// summed in fixed chunks on every core ([`NetEquations::of_chunks`]).
    fn of_rows(
        data: &Dataset,
        partition: &RbfPartition,
        estimation: Estimation,
        use_row: &(dyn Fn(usize) -> bool + Sync),
        weight: &(dyn Fn(usize) -> Vec3 + Sync),
    ) -> Self {
        let rows_of = |range: std::ops::Range<usize>| {
            range
                .filter(|&k| use_row(k))
                .map(|k| (data.u[k], data.regressors(k), data.y[k], weight(k)))
        };
        Self::of_chunks(
            data,
            partition,
            estimation,
            data.len(),
            FIT_CHUNK_ROWS,
            rows_of,
        )
    }

    /// The equations of `n` weighted rows `(u, regressors, y, weight per axis)`, which
    /// `rows_of` gives for a range of their indices. A row may stand for several of equal
    /// input and regressors: its weight is then their weights' sum and its `y` their weighted
    /// mean, which gives the same normal equations.
    ///
    /// Chunks of `chunk` rows are accumulated on every core and summed in row order
    /// ([`sum_in_chunks`]): the chunks are fixed by `n` and `chunk` alone, so the coefficients
    /// do not depend on the number of threads (and `n` up to `chunk` is one sequential pass;
    /// none is one empty chunk, and the solve says there is no data).
    pub(crate) fn of_chunks<'r, I>(
        data: &Dataset,
        partition: &RbfPartition,
        estimation: Estimation,
        n: usize,
        chunk: usize,
        rows_of: impl Fn(std::ops::Range<usize>) -> I + Sync,
    ) -> Self
    where
        I: Iterator<Item = (f64, &'r [f64], Vec3, Vec3)>,
    {
        let p = data.spec.regressor_count();
        let sums = sum_in_chunks(
            n,
            chunk,
            |range| accumulate(p, partition, estimation, rows_of(range)),
            |sum, part| sum.merge(&part),
        );
        NetEquations {
            partition: partition.clone(),
            estimation,
            sums,
        }
    }

    /// Adds the rows where `use_row` is true (rows not already in the sums), weighted by
    /// `weight`.
    pub(crate) fn add_rows(
        &mut self,
        data: &Dataset,
        use_row: &(dyn Fn(usize) -> bool + Sync),
        weight: &(dyn Fn(usize) -> Vec3 + Sync),
    ) {
        let more = NetEquations::of_rows(data, &self.partition, self.estimation, use_row, weight);
        self.sums.merge(&more.sums);
    }

    /// The network these equations give.
    pub(crate) fn solve(&self, data: &Dataset) -> Result<LocalLinearNet, IdentError> {
        solve(data, &self.partition, &self.sums)
    }
}

/// `part` of each chunk of `0..n`, `chunk` long (one empty chunk when `n` is 0), computed on
/// every core and folded by `merge` in chunk order: the chunks are fixed by `n` and `chunk`
/// alone, so the result does not depend on the number of threads.
pub(crate) fn sum_in_chunks<T: Send>(
    n: usize,
    chunk: usize,
    part: impl Fn(std::ops::Range<usize>) -> T + Sync,
    merge: impl Fn(&mut T, T),
) -> T {
    let starts: Vec<usize> = (0..n.max(1)).step_by(chunk.max(1)).collect();
    starts
        .par_iter()
        .map(|&a| part(a..(a + chunk).min(n)))
        .collect::<Vec<T>>()
        .into_iter()
        .reduce(|mut sum, next| {
            merge(&mut sum, next);
            sum
        })
        .expect("at least one chunk")
}

/// The normal equations of a network's fit, before the solve.
#[derive(Debug, Clone)]
enum Accumulated {
    /// One set per local model and axis.
    Local(Vec<[NormalEquations; 3]>),
    /// One set per axis over every local model's regressors.
    Global(Box<[NormalEquations; 3]>),
}

impl Accumulated {
    /// Adds the rows `other` holds.
    fn merge(&mut self, other: &Accumulated) {
        match (self, other) {
            (Accumulated::Local(a), Accumulated::Local(b)) => {
                for (x, y) in a.iter_mut().zip(b) {
                    for k in 0..3 {
                        x[k].merge(&y[k]);
                    }
                }
            }
            (Accumulated::Global(a), Accumulated::Global(b)) => {
                for (x, y) in a.iter_mut().zip(b.iter()) {
                    x.merge(y);
                }
            }
            // Both come from the same estimation.
            _ => {}
        }
    }
}

/// The normal equations of `rows` for `p` regressors per local model.
fn accumulate<'r>(
    p: usize,
    partition: &RbfPartition,
    estimation: Estimation,
    rows: impl Iterator<Item = (f64, &'r [f64], Vec3, Vec3)>,
) -> Accumulated {
    let m = partition.len();
    let mut phi = vec![0.0; m];
    match estimation {
        Estimation::Local => {
            let mut ne: Vec<[NormalEquations; 3]> = (0..m)
                .map(|_| std::array::from_fn(|_| NormalEquations::new(p, 1)))
                .collect();
            for (u, x, y, w) in rows {
                partition.weights_into(u, &mut phi);
                for i in 0..m {
                    for a in 0..3 {
                        ne[i][a].add(x, &[y[a]], phi[i] * w[a]);
                    }
                }
            }
            Accumulated::Local(ne)
        }
        Estimation::Global => {
            let mut ne: [NormalEquations; 3] =
                std::array::from_fn(|_| NormalEquations::new(m * p, 1));
            // Only the local models a row belongs to carry its regressors: a normalized
            // Gaussian membership below MIN_MEMBERSHIP adds less than a part in 1e12 of what
            // the model's own rows add, and skipping it makes a row cost the few models near
            // it rather than all of them.
            let (mut cols, mut z) = (Vec::with_capacity(m * p), Vec::with_capacity(m * p));
            let mut batches = GramBatches::default();
            for (u, x, y, w) in rows {
                partition.weights_into(u, &mut phi);
                cols.clear();
                z.clear();
                for i in (0..m).filter(|&i| phi[i] >= MIN_MEMBERSHIP) {
                    for j in 0..p {
                        cols.push(i * p + j);
                        z.push(phi[i] * x[j]);
                    }
                }
                // A run of columns wide enough for a matrix product waits for others of the
                // same run; the rest are summed at once.
                match (cols.first(), cols.last()) {
                    (Some(&first), Some(&last))
                        if last - first + 1 == cols.len() && cols.len() >= MIN_GRAM_COLUMNS =>
                    {
                        batches.push(first, &z, y, w, &mut ne);
                    }
                    _ => {
                        for a in 0..3 {
                            ne[a].add_sparse(&cols, &z, &[y[a]], w[a]);
                        }
                    }
                }
            }
            batches.finish(&mut ne);
            Accumulated::Global(Box::new(ne))
        }
    }
}

/// Rows a batch of [`GramBatches`] holds before it is summed.
const GRAM_BATCH_ROWS: usize = 64;

/// Fewest nonzero columns for which a row waits for a batch: below it a matrix product gains
/// nothing over summing the row at once.
const MIN_GRAM_COLUMNS: usize = 6;

/// Rows of a global fit waiting to be summed into its normal equations, one batch per run of
/// nonzero columns (the local models near the rows' input): a full batch is summed as one
/// matrix product per axis ([`NormalEquations::add_scaled_rows`]). The batches fill and are
/// summed in an order fixed by the rows alone.
#[derive(Default)]
struct GramBatches {
    batches: Vec<GramBatch>,
    scaled: Vec<f64>,
    scaled_y: Vec<f64>,
}

/// Rows sharing one run of nonzero columns.
struct GramBatch {
    first: usize,
    n: usize,
    z: Vec<f64>,
    y: Vec<Vec3>,
    w: Vec<Vec3>,
}

impl GramBatches {
    /// Adds a row nonzero on the columns `first..first + z.len()`, summing its batch into `ne`
    /// when full.
    fn push(&mut self, first: usize, z: &[f64], y: Vec3, w: Vec3, ne: &mut [NormalEquations; 3]) {
        let n = z.len();
        let i = match self
            .batches
            .iter()
            .position(|b| b.first == first && b.n == n)
        {
            Some(i) => i,
            None => {
                self.batches.push(GramBatch {
                    first,
                    n,
                    z: Vec::with_capacity(GRAM_BATCH_ROWS * n),
                    y: Vec::with_capacity(GRAM_BATCH_ROWS),
                    w: Vec::with_capacity(GRAM_BATCH_ROWS),
                });
                self.batches.len() - 1
            }
        };
        let batch = &mut self.batches[i];
        batch.z.extend_from_slice(z);
        batch.y.push(y);
        batch.w.push(w);
        if batch.y.len() == GRAM_BATCH_ROWS {
            batch.sum_into(&mut self.scaled, &mut self.scaled_y, ne);
        }
    }

    /// Sums every batch's remaining rows.
    fn finish(mut self, ne: &mut [NormalEquations; 3]) {
        for batch in &mut self.batches {
            batch.sum_into(&mut self.scaled, &mut self.scaled_y, ne);
        }
    }
}

impl GramBatch {
    /// Sums the batch's rows into `ne` (per axis, each row scaled by the root of its weight on
    /// that axis; a row without positive weight there is left out) and empties it.
    fn sum_into(
        &mut self,
        scaled: &mut Vec<f64>,
        scaled_y: &mut Vec<f64>,
        ne: &mut [NormalEquations; 3],
    ) {
        let n = self.n;
        for a in 0..3 {
            scaled.clear();
            scaled_y.clear();
            let (mut weight_sum, mut rows) = (0.0, 0);
            for (k, (y, w)) in self.y.iter().zip(&self.w).enumerate() {
                let root = if w[a] > 0.0 {
                    weight_sum += w[a];
                    rows += 1;
                    w[a].sqrt()
                } else {
                    0.0
                };
                scaled.extend(self.z[k * n..(k + 1) * n].iter().map(|v| root * v));
                scaled_y.push(root * y[a]);
            }
            if rows > 0 {
                ne[a].add_scaled_rows(self.first, n, scaled, scaled_y, weight_sum, rows);
            }
        }
        self.z.clear();
        self.y.clear();
        self.w.clear();
    }
}

/// Solves accumulated normal equations for the network's coefficients.
fn solve(
    data: &Dataset,
    partition: &RbfPartition,
    acc: &Accumulated,
) -> Result<LocalLinearNet, IdentError> {
    let m = partition.len();
    let p = data.spec.regressor_count();
    let coefficients = match acc {
        Accumulated::Local(ne) => {
            let mut out: [Vec<Vec<f64>>; 3] = Default::default();
            for (i, per_axis) in ne.iter().enumerate() {
                for a in 0..3 {
                    let th = per_axis[a]
                        .solve()
                        .map_err(|e| singular(data, &format!("local model {}", i + 1), e))?;
                    out[a].push(th.column(0).iter().copied().collect());
                }
            }
            out
        }
        Accumulated::Global(ne) => {
            let mut out: [Vec<Vec<f64>>; 3] = Default::default();
            for a in 0..3 {
                let th: DMatrix<f64> = ne[a]
                    .solve()
                    .map_err(|e| singular(data, "global local-linear model", e))?;
                out[a] = (0..m)
                    .map(|i| (0..p).map(|j| th[(i * p + j, 0)]).collect())
                    .collect();
            }
            out
        }
    };
    Ok(LocalLinearNet {
        partition: partition.clone(),
        coefficients,
    })
}
