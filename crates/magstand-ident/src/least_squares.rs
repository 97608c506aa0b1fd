//! Weighted linear least squares by accumulated normal equations and a Cholesky solve.
//!
//! One pass over the data accumulates `X^T W X` and `X^T W y`, so a million samples cost a few
//! multiply-adds each and no large matrix is ever formed. The normal matrix is equilibrated
//! (scaled to a unit diagonal) before the Cholesky factorization, and the fit is refused when
//! its reciprocal condition estimate is too small to trust: degenerate data gives an error,
//! never NaN. No matrix is ever inverted.
use nalgebra::{DMatrix, DVector};

/// Smallest acceptable reciprocal condition estimate of the equilibrated normal matrix
/// (squared pivot ratio of its Cholesky factor). Below it, the coefficients are not determined
/// to even a few significant digits.
pub const MIN_RCOND: f64 = 1e-13;

/// Accumulator of weighted normal equations for `outputs` right-hand sides sharing one
/// regressor matrix and one weight per row.
#[derive(Debug, Clone)]
pub struct NormalEquations {
    xtx: DMatrix<f64>,
    xty: DMatrix<f64>,
    weight_sum: f64,
    rows: usize,
}

/// Why a solve failed.
#[derive(Debug, Clone, PartialEq)]
pub enum SolveError {
    /// No rows with positive weight.
    NoData,
    /// The regressors are (nearly) linearly dependent on the weighted data; the index is the
    /// first regressor found dependent on the ones before it.
    Singular {
        /// Index of the first dependent regressor.
        column: usize,
        /// Reciprocal condition estimate.
        rcond: f64,
    },
}

impl NormalEquations {
    /// An empty accumulator for `params` regressors and `outputs` right-hand sides.
    pub fn new(params: usize, outputs: usize) -> Self {
        Self {
            xtx: DMatrix::zeros(params, params),
            xty: DMatrix::zeros(params, outputs),
            weight_sum: 0.0,
            rows: 0,
        }
    }

    /// Adds one row `x` with outputs `y` and weight `w` (rows with `w <= 0` are skipped).
    #[inline]
    pub fn add(&mut self, x: &[f64], y: &[f64], w: f64) {
        if w <= 0.0 {
            return;
        }
        self.add_block(0, x, y, w);
    }

    /// Adds one row whose regressors are zero except `vals` at the columns `cols` (ascending):
    /// the same sums as [`NormalEquations::add`] of the full row, at the cost of the nonzero
    /// part only.
    #[inline]
    pub fn add_sparse(&mut self, cols: &[usize], vals: &[f64], y: &[f64], w: f64) {
        if w <= 0.0 {
            return;
        }
        debug_assert!(cols.windows(2).all(|c| c[0] < c[1]), "ascending columns");
        // A row's nonzero regressors are usually one run of columns (the local models near
        // its input): a dense block then.
        if let (Some(&first), Some(&last)) = (cols.first(), cols.last())
            && last - first + 1 == cols.len()
        {
            return self.add_block(first, vals, y, w);
        }
        let p = self.xtx.nrows();
        let xtx = self.xtx.as_mut_slice();
        for (a, &i) in cols.iter().enumerate() {
            let wxi = w * vals[a];
            if wxi == 0.0 {
                continue;
            }
            // The lower triangle, along column i (see `add_block`).
            let column = &mut xtx[i * p..(i + 1) * p];
            for (b, &j) in cols.iter().enumerate().skip(a) {
                column[j] += wxi * vals[b];
            }
            for (k, yk) in y.iter().enumerate() {
                self.xty[(i, k)] += wxi * yk;
            }
        }
        self.weight_sum += w;
        self.rows += 1;
    }

    /// Adds one row whose regressors are zero except `vals` at the columns `first..` (a dense
    /// run; `w > 0`). The sums go to the lower triangle, mirrored in `factor`: element (j, i),
    /// j >= i, lies in column i, whose rows are next to each other in nalgebra's column-major
    /// storage, so each regressor adds one contiguous run.
    fn add_block(&mut self, first: usize, vals: &[f64], y: &[f64], w: f64) {
        let p = self.xtx.nrows();
        let n = vals.len();
        let xtx = self.xtx.as_mut_slice();
        for a in 0..n {
            let wxi = w * vals[a];
            if wxi == 0.0 {
                continue;
            }
            let i = first + a;
            let column = &mut xtx[i * p + i..i * p + first + n];
            for (c, v) in column.iter_mut().zip(&vals[a..]) {
                *c += wxi * v;
            }
            for (k, yk) in y.iter().enumerate() {
                self.xty[(i, k)] += wxi * yk;
            }
        }
        self.weight_sum += w;
        self.rows += 1;
    }

    /// Adds `r` rows at once whose regressors are zero except on the columns `first..first +
    /// n`: `scaled` holds each row's `n` regressors times the square root of its weight, one
    /// row after another, and `scaled_y` its `outputs` right-hand sides times the same root,
    /// row after row; `weight_sum` and `rows` are their weights' sum and the number with
    /// positive weight. The block's Gram matrix is one matrix product (BLAS-like, on the
    /// `matrixmultiply` kernels nalgebra uses), several times faster than row by row for
    /// blocks of more than a few columns.
    pub fn add_scaled_rows(
        &mut self,
        first: usize,
        n: usize,
        scaled: &[f64],
        scaled_y: &[f64],
        weight_sum: f64,
        rows: usize,
    ) {
        let r = scaled.len() / n.max(1);
        let outputs = self.xty.ncols();
        if r == 0 || n == 0 {
            return;
        }
        // Column k of `z` is row k's regressors; `zt` is the same memory read as rows.
        let z = nalgebra::DMatrixView::from_slice(&scaled[..r * n], n, r);
        let zt = nalgebra::DMatrixView::from_slice_with_strides(&scaled[..r * n], r, n, n, 1);
        let yt = nalgebra::DMatrixView::from_slice_with_strides(
            &scaled_y[..r * outputs],
            r,
            outputs,
            outputs,
            1,
        );
        let mut gram = DMatrix::zeros(n, n);
        gram.gemm(1.0, &z, &zt, 0.0);
        let mut zy = DMatrix::zeros(n, outputs);
        zy.gemm(1.0, &z, &yt, 0.0);
        for i in 0..n {
            for j in i..n {
                self.xtx[(first + j, first + i)] += gram[(j, i)];
            }
            for k in 0..outputs {
                self.xty[(first + i, k)] += zy[(i, k)];
            }
        }
        self.weight_sum += weight_sum;
        self.rows += rows;
    }

    /// Adds another accumulator's sums (for parallel or chunked accumulation).
    pub fn merge(&mut self, other: &NormalEquations) {
        self.xtx += &other.xtx;
        self.xty += &other.xty;
        self.weight_sum += other.weight_sum;
        self.rows += other.rows;
    }

    /// Number of rows added with positive weight.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Solves for the coefficients: one column per output.
    pub fn solve(&self) -> Result<DMatrix<f64>, SolveError> {
        let (chol, scale, rcond) = self.factor()?;
        let p = scale.len();
        let mut b = self.xty.clone();
        for i in 0..p {
            for k in 0..b.ncols() {
                b[(i, k)] *= scale[i];
            }
        }
        let mut theta = chol.solve(&b);
        for i in 0..p {
            for k in 0..theta.ncols() {
                theta[(i, k)] *= scale[i];
            }
        }
        if theta.iter().all(|v| v.is_finite()) {
            Ok(theta)
        } else {
            Err(SolveError::Singular { column: 0, rcond })
        }
    }

    /// The diagonal of `(X^T W X)^-1`: with weights equal to inverse noise variances, the
    /// variance of each coefficient. Found by Cholesky solves against unit vectors.
    pub fn coefficient_variances(&self) -> Result<DVector<f64>, SolveError> {
        let (chol, scale, _) = self.factor()?;
        let p = scale.len();
        Ok(DVector::from_fn(p, |i, _| {
            let mut e = DVector::zeros(p);
            e[i] = 1.0;
            chol.solve(&e)[i] * scale[i] * scale[i]
        }))
    }

    /// Equilibrated Cholesky factor of the normal matrix, the scale used and the reciprocal
    /// condition estimate; refuses empty and (nearly) singular systems.
    fn factor(&self) -> Result<Factor, SolveError> {
        let p = self.xtx.nrows();
        if self.rows == 0 || self.weight_sum <= 0.0 {
            return Err(SolveError::NoData);
        }
        let mut a = self.xtx.clone();
        // The sums are in the lower triangle (`add_block`): mirrored into the upper.
        for i in 0..p {
            for j in 0..i {
                a[(j, i)] = a[(i, j)];
            }
        }
        // Equilibrate: D^-1/2 A D^-1/2 has a unit diagonal, so the pivot test below is scale-free.
        let scale: DVector<f64> = DVector::from_fn(p, |i, _| {
            let d = a[(i, i)];
            if d > 0.0 { 1.0 / d.sqrt() } else { 0.0 }
        });
        if let Some(col) = (0..p).find(|&i| scale[i] == 0.0) {
            return Err(SolveError::Singular {
                column: col,
                rcond: 0.0,
            });
        }
        for i in 0..p {
            for j in 0..p {
                a[(i, j)] *= scale[i] * scale[j];
            }
        }
        let chol = nalgebra::Cholesky::new(a.clone()).ok_or_else(|| SolveError::Singular {
            column: first_dependent(&a),
            rcond: 0.0,
        })?;
        let l = chol.l_dirty();
        let diag: Vec<f64> = (0..p).map(|i| l[(i, i)].abs()).collect();
        let (lo, hi) = diag.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
        let rcond = (lo / hi).powi(2);
        if !(rcond >= MIN_RCOND) {
            let column = diag.iter().position(|&d| d == lo).unwrap_or(0);
            return Err(SolveError::Singular { column, rcond });
        }
        Ok((chol, scale, rcond))
    }
}

/// The normal equations of `K` outputs that share one regressor row but weigh it each by its
/// own weight (a magnetometer's three axes under their own noise variances): `K` separate
/// systems, summed in one pass over the rows. Each product is the one
/// [`NormalEquations::add`] forms, in the same order, so the sums carry the same bits; the
/// row's products are formed once for all outputs instead of once per output.
#[derive(Debug, Clone)]
pub struct SharedRowEquations<const K: usize> {
    params: usize,
    /// The lower triangle of each `X^T W X`, column after column.
    xtx: Vec<[f64; K]>,
    xty: Vec<[f64; K]>,
    weight_sum: [f64; K],
    rows: [usize; K],
    /// The row's regressors times each output's weight, reused from row to row.
    scaled: Vec<[f64; K]>,
}

impl<const K: usize> SharedRowEquations<K> {
    /// An empty accumulator for `params` regressors.
    pub fn new(params: usize) -> Self {
        Self {
            params,
            xtx: vec![[0.0; K]; params * (params + 1) / 2],
            xty: vec![[0.0; K]; params],
            weight_sum: [0.0; K],
            rows: [0; K],
            scaled: vec![[0.0; K]; params],
        }
    }

    /// Adds one row `x` with output `k`'s value `y[k]` and weight `w[k]` (an output whose
    /// weight is not positive skips the row, as [`NormalEquations::add`] does).
    #[inline]
    pub fn add(&mut self, x: &[f64], y: [f64; K], w: [f64; K]) {
        let p = self.params;
        let x = &x[..p];
        let w = self.count_weights(w);
        for (s, &xi) in self.scaled.iter_mut().zip(x) {
            *s = w.map(|w| w * xi);
        }
        let mut at = 0;
        for i in 0..p {
            let wxi = self.scaled[i];
            for (c, &xj) in self.xtx[at..at + p - i].iter_mut().zip(&x[i..]) {
                for k in 0..K {
                    c[k] += wxi[k] * xj;
                }
            }
            at += p - i;
            for k in 0..K {
                self.xty[i][k] += wxi[k] * y[k];
            }
        }
    }

    /// Counts a row's weights `w` (an output's weight not positive, 0: the row is skipped
    /// there) and returns them.
    #[inline]
    fn count_weights(&mut self, w: [f64; K]) -> [f64; K] {
        let w = w.map(|w| if w > 0.0 { w } else { 0.0 });
        for k in 0..K {
            if w[k] > 0.0 {
                self.weight_sum[k] += w[k];
                self.rows[k] += 1;
            }
        }
        w
    }

    /// Adds another accumulator's sums (the rows of another chunk).
    pub fn merge(&mut self, other: &Self) {
        for (a, b) in self.xtx.iter_mut().zip(&other.xtx) {
            for k in 0..K {
                a[k] += b[k];
            }
        }
        for (a, b) in self.xty.iter_mut().zip(&other.xty) {
            for k in 0..K {
                a[k] += b[k];
            }
        }
        for k in 0..K {
            self.weight_sum[k] += other.weight_sum[k];
            self.rows[k] += other.rows[k];
        }
    }

    /// The `K` systems, each ready to solve.
    pub fn into_equations(self) -> [NormalEquations; K] {
        let p = self.params;
        std::array::from_fn(|k| {
            let mut xtx = DMatrix::zeros(p, p);
            let mut at = 0;
            for i in 0..p {
                for j in i..p {
                    xtx[(j, i)] = self.xtx[at][k];
                    at += 1;
                }
            }
            NormalEquations {
                xtx,
                xty: DMatrix::from_fn(p, 1, |i, _| self.xty[i][k]),
                weight_sum: self.weight_sum[k],
                rows: self.rows[k],
            }
        })
    }
}

/// Rows in one block of [`sum_column_rows`]: a block's columns stay in the first-level
/// cache while every pair of them is summed.
const ROW_BLOCK: usize = 128;

/// Partial sums of each product over a block: independent sums in a fixed order, which the
/// processor runs side by side in vector registers (one after another, each addition waits
/// on the one before it), and whose bits do not depend on the vector width the machine has.
const LANES: usize = 16;

/// The normal equations of `K` outputs on the rows `rows` of the regressor columns
/// `columns`, with output `k`'s value `y(r)[k]` and weight `w(r)[k]` on row `r` (an output
/// whose weight is not positive skips the row, as [`NormalEquations::add`] does).
///
/// The rows are gathered a block at a time, column by column, and each pair of columns is
/// summed over the block in `LANES` partial sums: several times faster than
/// [`SharedRowEquations::add`] row by row on a wide design. The sums differ from its in their
/// last bits only (another order of the same additions); they do not depend on the thread
/// count or the machine's vector width.
pub fn sum_column_rows<const K: usize>(
    columns: &[&[f64]],
    rows: impl IntoIterator<Item = usize>,
    y: impl Fn(usize) -> [f64; K],
    w: impl Fn(usize) -> [f64; K],
) -> SharedRowEquations<K> {
    let mut block = RowBlock::<K>::new(columns.len());
    let mut sums = SharedRowEquations::new(columns.len());
    let mut at = [0usize; ROW_BLOCK];
    let mut len = 0;
    for r in rows {
        at[len] = r;
        len += 1;
        if len == ROW_BLOCK {
            block.gather(columns, &at, &y, &w, &mut sums);
            block.sum(&mut sums);
            len = 0;
        }
    }
    if len > 0 {
        block.gather(columns, &at[..len], &y, &w, &mut sums);
        block.sum(&mut sums);
    }
    sums
}

/// One block of rows of [`sum_column_rows`], column after column.
struct RowBlock<const K: usize> {
    params: usize,
    /// The block's regressors, [`ROW_BLOCK`] rows per column.
    x: Vec<f64>,
    /// The block's outputs, output after output.
    y: Vec<f64>,
    /// The block's weights (not positive: 0), output after output.
    w: Vec<f64>,
    /// One column times each output's weight, output after output.
    wx: Vec<f64>,
    /// Rows in the block, up to whole lanes (the tail weighs nothing).
    len: usize,
}

impl<const K: usize> RowBlock<K> {
    fn new(params: usize) -> Self {
        Self {
            params,
            x: vec![0.0; params * ROW_BLOCK],
            y: vec![0.0; K * ROW_BLOCK],
            w: vec![0.0; K * ROW_BLOCK],
            wx: vec![0.0; K * ROW_BLOCK],
            len: 0,
        }
    }

    /// Gathers the rows `at` (at most [`ROW_BLOCK`]), and counts their weights in `sums`.
    fn gather(
        &mut self,
        columns: &[&[f64]],
        at: &[usize],
        y: &impl Fn(usize) -> [f64; K],
        w: &impl Fn(usize) -> [f64; K],
        sums: &mut SharedRowEquations<K>,
    ) {
        let n = at.len().next_multiple_of(LANES);
        // Rows in one run (most blocks: a held-out split leaves long runs) are copied whole.
        let run = match (at.first(), at.last()) {
            (Some(&first), Some(&last)) if last - first + 1 == at.len() => Some(first..last + 1),
            _ => None,
        };
        for (j, column) in columns.iter().enumerate() {
            let x = &mut self.x[j * ROW_BLOCK..j * ROW_BLOCK + n];
            match &run {
                Some(rows) => x[..at.len()].copy_from_slice(&column[rows.clone()]),
                None => {
                    for (o, &r) in x.iter_mut().zip(at) {
                        *o = column[r];
                    }
                }
            }
            x[at.len()..].fill(0.0);
        }
        for (c, &r) in at.iter().enumerate() {
            let (yr, wr) = (y(r), sums.count_weights(w(r)));
            for k in 0..K {
                self.w[k * ROW_BLOCK + c] = wr[k];
                self.y[k * ROW_BLOCK + c] = yr[k];
            }
        }
        for c in at.len()..n {
            for k in 0..K {
                self.w[k * ROW_BLOCK + c] = 0.0;
                self.y[k * ROW_BLOCK + c] = 0.0;
            }
        }
        self.len = n;
    }

    /// Adds the gathered rows' products to `sums`.
    fn sum(&mut self, sums: &mut SharedRowEquations<K>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, the only feature `sum_block_avx2` enables.
            unsafe { sum_block_avx2(self, sums) };
            return;
        }
        sum_block(self, sums);
    }
}

/// [`sum_block`] with [`lane_dots`] in AVX2 registers: four registers of four lanes per
/// output, the same products and additions in the same order as the portable code (no fused
/// multiply-add), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sum_block_avx2<const K: usize>(block: &mut RowBlock<K>, sums: &mut SharedRowEquations<K>) {
    sum_block_with(block, sums, |wx, x| {
        use std::arch::x86_64::*;
        let n = x.len();
        // What the loads below rely on: whole lanes, within `x` and each output's row.
        assert!(n % LANES == 0 && n <= ROW_BLOCK && wx.len() >= K * ROW_BLOCK);
        let mut acc = [[_mm256_setzero_pd(); LANES / 4]; K];
        for c in (0..n).step_by(LANES) {
            for q in 0..LANES / 4 {
                // SAFETY: c + 4q + 4 <= n, within `x` and within each output's row of `wx`.
                let vx = unsafe { _mm256_loadu_pd(x.as_ptr().add(c + 4 * q)) };
                for (k, acc) in acc.iter_mut().enumerate() {
                    let vw = unsafe { _mm256_loadu_pd(wx.as_ptr().add(k * ROW_BLOCK + c + 4 * q)) };
                    acc[q] = _mm256_add_pd(acc[q], _mm256_mul_pd(vw, vx));
                }
            }
        }
        acc.map(|acc| {
            let mut lanes = [0.0; LANES];
            for (q, v) in acc.iter().enumerate() {
                // SAFETY: `lanes` holds LANES values, so four from 4q are in bounds.
                unsafe { _mm256_storeu_pd(lanes.as_mut_ptr().add(4 * q), *v) };
            }
            lane_total(lanes)
        })
    })
}

/// Adds the products of a gathered block to `sums`.
#[inline(always)]
fn sum_block<const K: usize>(block: &mut RowBlock<K>, sums: &mut SharedRowEquations<K>) {
    sum_block_with(block, sums, lane_dots::<K>)
}

/// Adds the products of a gathered block to `sums`, each column's products with every
/// output's weighted column summed by `dots`.
#[inline(always)]
fn sum_block_with<const K: usize>(
    block: &mut RowBlock<K>,
    sums: &mut SharedRowEquations<K>,
    dots: impl Fn(&[f64], &[f64]) -> [f64; K],
) {
    let (p, n) = (block.params, block.len);
    let mut at = 0;
    for i in 0..p {
        let xi = &block.x[i * ROW_BLOCK..i * ROW_BLOCK + n];
        for k in 0..K {
            let wk = &block.w[k * ROW_BLOCK..k * ROW_BLOCK + n];
            let wxk = &mut block.wx[k * ROW_BLOCK..k * ROW_BLOCK + n];
            for ((o, &wr), &xr) in wxk.iter_mut().zip(wk).zip(xi) {
                *o = wr * xr;
            }
        }
        for k in 0..K {
            let wxk = &block.wx[k * ROW_BLOCK..k * ROW_BLOCK + n];
            sums.xty[i][k] += lane_dot(wxk, &block.y[k * ROW_BLOCK..k * ROW_BLOCK + n]);
        }
        for j in i..p {
            let d = dots(&block.wx, &block.x[j * ROW_BLOCK..j * ROW_BLOCK + n]);
            for k in 0..K {
                sums.xtx[at][k] += d[k];
            }
            at += 1;
        }
    }
}

/// [`lane_dot`] of each output's row of `wx` (rows [`ROW_BLOCK`] apart) with `x`.
#[inline(always)]
fn lane_dots<const K: usize>(wx: &[f64], x: &[f64]) -> [f64; K] {
    std::array::from_fn(|k| lane_dot(&wx[k * ROW_BLOCK..k * ROW_BLOCK + x.len()], x))
}

/// `sum_r a[r] * b[r]` in [`LANES`] partial sums (the lengths a multiple of [`LANES`]),
/// added in a fixed order.
#[inline(always)]
fn lane_dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; LANES];
    let chunks = a.len() / LANES;
    for c in 0..chunks {
        let ca: &[f64; LANES] = a[c * LANES..(c + 1) * LANES]
            .try_into()
            .expect("whole lanes");
        let cb: &[f64; LANES] = b[c * LANES..(c + 1) * LANES]
            .try_into()
            .expect("whole lanes");
        for l in 0..LANES {
            acc[l] += ca[l] * cb[l];
        }
    }
    lane_total(acc)
}

/// The sum of a product's partial sums, pairwise in a fixed order.
#[inline(always)]
fn lane_total(mut acc: [f64; LANES]) -> f64 {
    let mut width = LANES;
    while width > 1 {
        width /= 2;
        for l in 0..width {
            acc[l] += acc[l + width];
        }
    }
    acc[0]
}

/// Index of the first column of `a` whose pivot collapses in an unpivoted elimination.
fn first_dependent(a: &DMatrix<f64>) -> usize {
    let p = a.nrows();
    let mut m = a.clone();
    for k in 0..p {
        if m[(k, k)] <= 1e-12 {
            return k;
        }
        for i in k + 1..p {
            let f = m[(i, k)] / m[(k, k)];
            for j in k..p {
                m[(i, j)] -= f * m[(k, j)];
            }
        }
    }
    p.saturating_sub(1)
}

/// An equilibrated Cholesky factor, the column scale used and the reciprocal condition
/// estimate.
type Factor = (nalgebra::Cholesky<f64, nalgebra::Dyn>, DVector<f64>, f64);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_rows_give_each_output_the_sums_of_its_own_equations() {
        // Three outputs, their own weights (one of them zero on some rows), rows split in two
        // chunks and merged: the same bits as three accumulators fed row by row.
        let mut shared = [SharedRowEquations::<3>::new(4), SharedRowEquations::new(4)];
        let mut chunks: [[NormalEquations; 3]; 2] =
            std::array::from_fn(|_| std::array::from_fn(|_| NormalEquations::new(4, 1)));
        for r in 0..200 {
            let t = r as f64 * 0.37;
            let x = [1.0, t.sin(), t.cos() * 2.0, (t * 0.1).powi(2)];
            let y = [t.sin() + 0.3, -t, 1.0 / (1.0 + t)];
            let w = [1.0 + t.cos().abs(), if r % 7 == 0 { 0.0 } else { 0.5 }, 2.0];
            shared[r / 120].add(&x, y, w);
            for k in 0..3 {
                chunks[r / 120][k].add(&x, &[y[k]], w[k]);
            }
        }
        let [mut first, second] = shared;
        first.merge(&second);
        let mut merged: [NormalEquations; 3] = std::array::from_fn(|_| NormalEquations::new(4, 1));
        for k in 0..3 {
            merged[k].merge(&chunks[0][k]);
            merged[k].merge(&chunks[1][k]);
        }
        for (k, eq) in first.into_equations().iter().enumerate() {
            assert_eq!(eq.rows(), merged[k].rows(), "output {k}");
            assert_eq!(eq.weight_sum, merged[k].weight_sum, "output {k}");
            for i in 0..4 {
                assert_eq!(eq.xty[(i, 0)], merged[k].xty[(i, 0)], "output {k} xty {i}");
                for j in i..4 {
                    assert_eq!(
                        eq.xtx[(j, i)],
                        merged[k].xtx[(j, i)],
                        "output {k} ({j}, {i})"
                    );
                }
            }
            assert_eq!(
                eq.solve().unwrap(),
                merged[k].solve().unwrap(),
                "output {k}"
            );
        }
    }

    /// One value per output.
    type Triple = [f64; 3];

    /// Columns, outputs and weights of [`sum_column_rows`]' tests: weights of each output zero
    /// or negative on some rows, and rows left out (a held-out split) so that blocks end
    /// within a lane.
    fn column_rows_case(p: usize, n: usize) -> (Vec<Vec<f64>>, Vec<Triple>, Vec<Triple>) {
        let columns = (0..p)
            .map(|j| {
                (0..n)
                    .map(|r| ((r * (j + 3)) as f64 * 0.0137).sin() * (j as f64 + 0.5))
                    .collect()
            })
            .collect();
        let y = (0..n)
            .map(|r| {
                let t = r as f64 * 0.01;
                [t.sin(), t.cos() + 2.0, -t]
            })
            .collect();
        let w = (0..n)
            .map(|r| {
                [
                    1.0 + (r as f64 * 0.1).cos().abs(),
                    if r % 11 == 0 { 0.0 } else { 0.5 },
                    if r % 13 == 0 { -1.0 } else { 2.0 },
                ]
            })
            .collect();
        (columns, y, w)
    }

    #[test]
    fn column_rows_give_the_sums_of_the_rows_one_by_one() {
        // Rows scattered (no block is one run) and in runs (held-out blocks: most blocks are
        // one run, copied whole, and some straddle a gap).
        column_rows_match_rows_one_by_one(|r| r % 7 != 3);
        column_rows_match_rows_one_by_one(|r| (r / 300) % 4 != 3);
    }

    fn column_rows_match_rows_one_by_one(kept: fn(&usize) -> bool) {
        let (p, n) = (9, 1000);
        let (columns, y, w) = column_rows_case(p, n);
        let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
        let blocked = sum_column_rows(&refs, (0..n).filter(kept), |r| y[r], |r| w[r]);
        let mut by_row = SharedRowEquations::<3>::new(p);
        for r in (0..n).filter(kept) {
            let x: Vec<f64> = columns.iter().map(|c| c[r]).collect();
            by_row.add(&x, y[r], w[r]);
        }
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-12 * scale.max(1.0);
        for (k, (got, want)) in blocked
            .into_equations()
            .iter()
            .zip(by_row.into_equations().iter())
            .enumerate()
        {
            assert_eq!(got.rows(), want.rows(), "output {k}");
            assert!(
                close(got.weight_sum, want.weight_sum, want.weight_sum),
                "output {k}: weight sum {} against {}",
                got.weight_sum,
                want.weight_sum
            );
            let scale = want.xtx.amax();
            for i in 0..p {
                assert!(
                    close(got.xty[(i, 0)], want.xty[(i, 0)], want.xty.amax()),
                    "output {k} xty {i}: {} against {}",
                    got.xty[(i, 0)],
                    want.xty[(i, 0)]
                );
                for j in i..p {
                    assert!(
                        close(got.xtx[(j, i)], want.xtx[(j, i)], scale),
                        "output {k} ({j}, {i}): {} against {}",
                        got.xtx[(j, i)],
                        want.xtx[(j, i)]
                    );
                }
            }
        }
    }

    #[test]
    fn column_rows_of_no_rows_are_empty() {
        let column = [1.0, 2.0];
        let sums = sum_column_rows(&[&column[..]], std::iter::empty(), |_| [1.0], |_| [1.0]);
        let [eq] = sums.into_equations();
        assert_eq!(eq.rows(), 0);
        assert_eq!(eq.xtx[(0, 0)], 0.0);
    }

    /// The vector code and the portable code sum the same products in the same order: the
    /// same bits, so a diagnosis does not depend on the machine's vector width.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_vector_sums_are_the_portable_sums_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let (p, n) = (12, 101);
        let (columns, y, w) = column_rows_case(p, n);
        let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
        let at: Vec<usize> = (0..n).collect();
        let mut portable = SharedRowEquations::<3>::new(p);
        let mut vector = SharedRowEquations::<3>::new(p);
        let mut block = RowBlock::<3>::new(p);
        block.gather(&refs, &at, &|r| y[r], &|r| w[r], &mut portable);
        sum_block(&mut block, &mut portable);
        block.gather(&refs, &at, &|r| y[r], &|r| w[r], &mut vector);
        // SAFETY: the processor has AVX2 (checked above).
        unsafe { sum_block_avx2(&mut block, &mut vector) };
        assert_eq!(portable.xtx, vector.xtx);
        assert_eq!(portable.xty, vector.xty);
    }

    #[test]
    fn recovers_an_exact_line() {
        let mut ne = NormalEquations::new(2, 1);
        for k in 0..100 {
            let x = k as f64 / 99.0;
            ne.add(&[x, 1.0], &[3.0 * x - 2.0], 1.0);
        }
        let th = ne.solve().unwrap();
        assert!(
            (th[(0, 0)] - 3.0).abs() < 1e-12 && (th[(1, 0)] + 2.0).abs() < 1e-12,
            "{th}"
        );
    }

    #[test]
    fn coefficient_variances_match_the_closed_form_of_a_line() {
        // y = a + b x with unit weights: var(b) = 1 / sum (x - mean)^2, var(a) = sum x^2 / (n Sxx).
        let mut ne = NormalEquations::new(2, 1);
        let xs: Vec<f64> = (0..10).map(|k| k as f64).collect();
        for &x in &xs {
            ne.add(&[1.0, x], &[0.0], 1.0);
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| (x - mean).powi(2)).sum();
        let sx2: f64 = xs.iter().map(|x| x * x).sum();
        let v = ne.coefficient_variances().unwrap();
        assert!(
            (v[1] - 1.0 / sxx).abs() < 1e-12,
            "{} vs {}",
            v[1],
            1.0 / sxx
        );
        assert!(
            (v[0] - sx2 / (n * sxx)).abs() < 1e-12,
            "{} vs {}",
            v[0],
            sx2 / (n * sxx)
        );
    }

    #[test]
    fn weights_matter() {
        // Two clusters disagree; the heavier one wins in proportion.
        let mut ne = NormalEquations::new(1, 1);
        ne.add(&[1.0], &[0.0], 1.0);
        ne.add(&[1.0], &[4.0], 3.0);
        assert!((ne.solve().unwrap()[(0, 0)] - 3.0).abs() < 1e-12);
    }

    #[test]
    fn constant_input_is_singular_not_nan() {
        let mut ne = NormalEquations::new(2, 1);
        for k in 0..50 {
            ne.add(&[0.5, 1.0], &[k as f64], 1.0);
        }
        assert!(
            matches!(ne.solve(), Err(SolveError::Singular { .. })),
            "{:?}",
            ne.solve()
        );
    }

    #[test]
    fn empty_is_an_error() {
        assert_eq!(
            NormalEquations::new(2, 1).solve().unwrap_err(),
            SolveError::NoData
        );
    }

    #[test]
    fn sparse_rows_sum_exactly_as_their_full_rows() {
        // Rows nonzero on a run of columns (the dense fast path) and on scattered columns
        // (the general one) give the very sums of the same rows written out in full.
        let p = 6;
        let (mut full, mut sparse) = (NormalEquations::new(p, 2), NormalEquations::new(p, 2));
        let rows: [(&[usize], &[f64]); 4] = [
            (&[1, 2, 3], &[0.7, -1.3, 2.1]),
            (&[0, 2, 5], &[1.1, 0.4, -0.9]),
            (&[3, 4, 5], &[0.2, 3.3, -0.6]),
            (&[0, 1, 2, 3, 4, 5], &[1.0, 0.5, 0.25, -0.5, 2.0, 0.1]),
        ];
        for (r, (cols, vals)) in rows.iter().enumerate() {
            let mut x = vec![0.0; p];
            for (c, v) in cols.iter().zip(vals.iter()) {
                x[*c] = *v;
            }
            let (y, w) = ([r as f64 - 1.5, 0.3 * r as f64], 0.5 + r as f64);
            full.add(&x, &y, w);
            sparse.add_sparse(cols, vals, &y, w);
        }
        let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            (bits(&full.xtx), bits(&full.xty)),
            (bits(&sparse.xtx), bits(&sparse.xty)),
            "full rows {} {} vs sparse rows {} {}",
            full.xtx,
            full.xty,
            sparse.xtx,
            sparse.xty
        );
        assert_eq!((full.rows(), sparse.rows()), (4, 4));
    }

    #[test]
    fn rows_summed_as_one_matrix_product_give_the_row_by_row_sums() {
        // 100 rows on the run of columns 2..9 of 12 (a local model window), two outputs, one
        // row of zero weight: as one product of rows scaled by their weights' roots, the sums
        // equal the row-by-row ones up to rounding.
        let (p, first, n) = (12, 2, 7);
        let (mut by_row, mut product) = (NormalEquations::new(p, 2), NormalEquations::new(p, 2));
        let (mut scaled, mut scaled_y, mut weight_sum, mut rows) = (vec![], vec![], 0.0, 0);
        for r in 0..100 {
            let vals: Vec<f64> = (0..n)
                .map(|j| ((r * 7 + j * 3) as f64 * 0.37).sin() + 0.1 * j as f64)
                .collect();
            let y = [((r as f64) * 0.11).cos(), r as f64 * 0.01 - 0.4];
            let w = if r == 17 { 0.0 } else { 0.5 + (r % 5) as f64 };
            let cols: Vec<usize> = (first..first + n).collect();
            by_row.add_sparse(&cols, &vals, &y, w);
            let root = w.sqrt();
            scaled.extend(vals.iter().map(|v| root * v));
            scaled_y.extend(y.iter().map(|v| root * v));
            if w > 0.0 {
                weight_sum += w;
                rows += 1;
            }
        }
        product.add_scaled_rows(first, n, &scaled, &scaled_y, weight_sum, rows);
        assert_eq!(product.rows(), by_row.rows());
        let close = |a: &DMatrix<f64>, b: &DMatrix<f64>| {
            a.iter()
                .zip(b.iter())
                .all(|(x, y)| (x - y).abs() <= 1e-12 * (1.0 + y.abs()))
        };
        assert!(
            close(&product.xtx, &by_row.xtx) && close(&product.xty, &by_row.xty),
            "product {} {} vs rows {} {}",
            product.xtx,
            product.xty,
            by_row.xtx,
            by_row.xty
        );
        // The upper triangle stays empty: the sums live in the lower one.
        assert_eq!(product.xtx[(first, first + 1)], 0.0);
    }

    #[test]
    fn badly_scaled_but_independent_columns_still_solve() {
        let mut ne = NormalEquations::new(2, 1);
        for k in 0..200 {
            let x = k as f64 * 1e-6;
            ne.add(&[x, 1e6], &[5.0 * x + 7.0], 1.0);
        }
        let th = ne.solve().unwrap();
        assert!(
            (th[(0, 0)] - 5.0).abs() < 1e-6 && (th[(1, 0)] - 7e-6).abs() < 1e-15,
            "{th}"
        );
    }
}
