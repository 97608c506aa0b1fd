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
        let w = w.map(|w| if w > 0.0 { w } else { 0.0 });
        for k in 0..K {
            if w[k] > 0.0 {
                self.weight_sum[k] += w[k];
                self.rows[k] += 1;
            }
        }
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
