//! Rows of equal input and regressors, taken together.
//!
//! A stair-throttle recording holds a few dozen distinct commands over thousands of rows. A
//! fit's normal equations, a model's residual sums and its predictions depend on a row's input
//! and regressors only through their values, so rows that share them can be summed first and
//! the expensive part (the RBF memberships, an exponential per local model) done once per
//! distinct value. On a recording whose input never repeats, each group is one row.
use magstand_core::Vec3;
use magstand_core::rbf::RbfPartition;

use crate::IdentError;
use crate::dataset::Dataset;
use crate::local_linear::{Estimation, LocalLinearNet, NetEquations, sum_in_chunks};

/// Which group each row of a dataset belongs to; groups in ascending input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GroupIndex {
    /// Group of each row.
    pub of_row: Vec<u32>,
    /// A row of each group (its first in time).
    pub first_row: Vec<u32>,
}

impl GroupIndex {
    /// The index of a dataset's rows by exact (bit for bit) input and regressors.
    pub fn of(data: &Dataset) -> Self {
        let n = data.len();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let key = |k: u32| (data.u[k as usize], data.regressors(k as usize));
        order.sort_by(|&a, &b| {
            let ((ua, xa), (ub, xb)) = (key(a), key(b));
            ua.total_cmp(&ub)
                .then_with(|| {
                    xa.iter()
                        .zip(xb)
                        .map(|(p, q)| p.total_cmp(q))
                        .find(|o| o.is_ne())
                        .unwrap_or(std::cmp::Ordering::Equal)
                })
                .then(a.cmp(&b))
        });
        let mut of_row = vec![0u32; n];
        let mut first_row: Vec<u32> = Vec::new();
        let same = |a: u32, b: u32| {
            let ((ua, xa), (ub, xb)) = (key(a), key(b));
            ua.to_bits() == ub.to_bits()
                && xa.iter().zip(xb).all(|(p, q)| p.to_bits() == q.to_bits())
        };
        for &k in &order {
            if first_row.last().is_none_or(|&f| !same(f, k)) {
                first_row.push(k);
            }
            of_row[k as usize] = (first_row.len() - 1) as u32;
        }
        GroupIndex { of_row, first_row }
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.first_row.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.first_row.is_empty()
    }
}

/// Rows looked at to tell whether a dataset's inputs repeat.
const PROBE_ROWS: usize = 1024;

/// Groups one worker accumulates at a time in [`Groups::fit`] and
/// [`Groups::binned_residuals`]: a structure search fits and scores tens of thousands of
/// distinct rows once per candidate partition, in sequence, so those passes are what can use
/// the second core. Fixed, so the coefficients do not depend on the thread count;
/// a recording of up to this many distinct rows is one sequential pass, as before.
const GROUPS_PER_CHUNK: usize = 8192;

/// Whether the rows of `data` repeat their inputs enough for grouping to pay: at most one in
/// eight of [`PROBE_ROWS`] rows spread over the dataset has an input of its own. (A stair of a
/// few dozen levels has a few dozen; a flight's or a current's input is new at every row,
/// and sorting it would cost more than it saves.)
pub(crate) fn inputs_repeat(data: &Dataset) -> bool {
    let n = data.len();
    if n < PROBE_ROWS {
        return n > 0;
    }
    let mut probe: Vec<u64> = (0..PROBE_ROWS)
        .map(|i| data.u[i * n / PROBE_ROWS].to_bits())
        .collect();
    probe.sort_unstable();
    probe.dedup();
    probe.len() <= PROBE_ROWS / 8
}

/// The rows a fit selects, summed per group of equal input and regressors.
pub(crate) struct Groups<'d> {
    data: &'d Dataset,
    /// Input of each group, ascending.
    pub u: Vec<f64>,
    /// A row holding each group's regressors.
    row: Vec<usize>,
    /// Rows in each group.
    pub n: Vec<usize>,
    /// Sum of the rows' weights per axis.
    w: Vec<Vec3>,
    /// Weighted mean deviation per axis (zero where the weight is).
    y_w: Vec<Vec3>,
    /// Sum of the rows' deviations.
    y_sum: Vec<Vec3>,
}

impl<'d> Groups<'d> {
    /// The groups of the rows `rows` selects, weighted by `weight`; groups no selected row
    /// falls in are left out.
    pub fn of(
        data: &'d Dataset,
        rows: &dyn Fn(usize) -> bool,
        weight: &dyn Fn(usize) -> Vec3,
    ) -> Self {
        let Some(index) = data.group_index() else {
            // Inputs that do not repeat: each selected row is its own group.
            let rows: Vec<usize> = (0..data.len()).filter(|&k| rows(k)).collect();
            let w: Vec<Vec3> = rows.iter().map(|&k| weight(k)).collect();
            return Groups {
                data,
                u: rows.iter().map(|&k| data.u[k]).collect(),
                y_w: rows
                    .iter()
                    .zip(&w)
                    .map(|(&k, w)| {
                        Vec3::from_fn(|a, _| if w[a] > 0.0 { data.y[k][a] } else { 0.0 })
                    })
                    .collect(),
                n: vec![1; rows.len()],
                y_sum: rows.iter().map(|&k| data.y[k]).collect(),
                w,
                row: rows,
            };
        };
        let g = index.len();
        let (mut n, mut w, mut wy, mut y_sum) = (
            vec![0usize; g],
            vec![Vec3::zeros(); g],
            vec![Vec3::zeros(); g],
            vec![Vec3::zeros(); g],
        );
        for k in (0..data.len()).filter(|&k| rows(k)) {
            let i = index.of_row[k] as usize;
            let (wk, y) = (weight(k), data.y[k]);
            n[i] += 1;
            w[i] += wk;
            wy[i] += wk.component_mul(&y);
            y_sum[i] += y;
        }
        let kept: Vec<usize> = (0..g).filter(|&i| n[i] > 0).collect();
        Groups {
            data,
            u: kept
                .iter()
                .map(|&i| data.u[index.first_row[i] as usize])
                .collect(),
            row: kept.iter().map(|&i| index.first_row[i] as usize).collect(),
            y_w: kept
                .iter()
                .map(|&i| {
                    Vec3::from_fn(|a, _| {
                        if w[i][a] > 0.0 {
                            wy[i][a] / w[i][a]
                        } else {
                            0.0
                        }
                    })
                })
                .collect(),
            n: kept.iter().map(|&i| n[i]).collect(),
            w: kept.iter().map(|&i| w[i]).collect(),
            y_sum: kept.iter().map(|&i| y_sum[i]).collect(),
        }
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// Regressors of group `i`.
    pub fn regressors(&self, i: usize) -> &'d [f64] {
        self.data.regressors(self.row[i])
    }

    /// Fits the network on the groups: the same normal equations as on their rows.
    pub fn fit(
        &self,
        partition: &RbfPartition,
        estimation: Estimation,
    ) -> Result<LocalLinearNet, IdentError> {
        NetEquations::of_chunks(
            self.data,
            partition,
            estimation,
            self.len(),
            GROUPS_PER_CHUNK,
            |range: std::ops::Range<usize>| {
                range.map(|i| (self.u[i], self.regressors(i), self.y_w[i], self.w[i]))
            },
        )
        .solve(self.data)
    }

    /// Per-bin residual sums and row counts over `BINS` bins of the input on `lo..hi`.
    pub fn binned_residuals(
        &self,
        net: &LocalLinearNet,
        bins: usize,
        lo: f64,
        hi: f64,
    ) -> Vec<(Vec3, usize)> {
        let width = (hi - lo).max(1e-12);
        sum_in_chunks(
            self.len(),
            GROUPS_PER_CHUNK,
            |range| {
                let mut phi = vec![0.0; net.partition.len()];
                let mut out = vec![(Vec3::zeros(), 0usize); bins];
                for i in range {
                    let u = self.u[i];
                    let b = (((u - lo) / width * bins as f64) as usize).min(bins - 1);
                    out[b].0 += self.y_sum[i]
                        - net.eval(u, self.regressors(i), &mut phi) * self.n[i] as f64;
                    out[b].1 += self.n[i];
                }
                out
            },
            |out, part| {
                for (o, p) in out.iter_mut().zip(part) {
                    o.0 += p.0;
                    o.1 += p.1;
                }
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::InputKind;
    use magstand_core::Recording;

    /// A 21-level stair with a curved deviation and a ripple that differs row by row, and a
    /// stretch of distinct inputs (a ramp) between the levels.
    fn data() -> Dataset {
        let mut rec = Recording {
            thr: vec![vec![]],
            overall_only: true,
            ..Default::default()
        };
        for k in 0..4400 {
            let u = if k < 4200 {
                ((k / 200) as f64 / 20.0).min(1.0)
            } else {
                (k - 4200) as f64 / 200.0
            };
            rec.t_s.push(k as f64 * 0.01);
            rec.thr[0].push(u);
            let ripple = 0.3 * ((k as f64) * 1.7).sin();
            rec.mag_ut.push(
                Vec3::new(20.0 + 6.0 * u * u, 1.0 - 3.0 * u, 45.0 + 9.0 * u.powi(3))
                    + Vec3::repeat(ripple),
            );
        }
        Dataset::from_recording(&rec, InputKind::Throttle, "stair").unwrap()
    }

    #[test]
    fn rows_group_by_exact_input_in_ascending_order() {
        let d = data();
        let index = GroupIndex::of(&d);
        // 21 levels and a ramp of 200 inputs j/200, of which the 20 at j = 10 i are the
        // levels i/20 again (the same double: both are the correctly rounded quotient).
        assert_eq!(index.len(), 21 + 200 - 20, "groups");
        assert!(d.group_index().is_some(), "a stair's inputs repeat");
        for k in 0..d.len() {
            let g = index.of_row[k] as usize;
            assert_eq!(
                d.u[k].to_bits(),
                d.u[index.first_row[g] as usize].to_bits(),
                "row {k}"
            );
        }
        let firsts: Vec<f64> = index.first_row.iter().map(|&k| d.u[k as usize]).collect();
        assert!(firsts.windows(2).all(|w| w[0] < w[1]), "{firsts:?}");
    }

    #[test]
    fn inputs_that_never_repeat_are_not_grouped() {
        let mut rec = Recording {
            thr: vec![vec![]],
            overall_only: true,
            ..Default::default()
        };
        for k in 0..3000 {
            rec.t_s.push(k as f64 * 0.01);
            rec.thr[0].push(if k < 200 {
                0.0
            } else {
                (k - 200) as f64 / 2800.0
            });
            rec.mag_ut.push(Vec3::new(20.0, 1.0, 45.0));
        }
        let d = Dataset::from_recording(&rec, InputKind::Throttle, "ramp").unwrap();
        assert!(d.group_index().is_none());
        // Each row is then its own group.
        let g = Groups::of(&d, &|k| k % 2 == 0, &|_| Vec3::repeat(1.0));
        assert_eq!(g.len(), 1500);
    }

    #[test]
    fn a_fit_on_groups_equals_the_fit_on_their_rows() {
        let d = data();
        assert!(d.group_index().is_some());
        let partition = RbfPartition::new(vec![0.0, 0.3, 0.7, 1.0], vec![5.0; 4]).unwrap();
        let rows = |k: usize| k % 7 != 3;
        let weight = |k: usize| Vec3::new(1.0 + d.u[k], 2.0, 1.0 / (1.0 + d.u[k]));
        for estimation in [Estimation::Local, Estimation::Global] {
            let grouped = Groups::of(&d, &rows, &weight)
                .fit(&partition, estimation)
                .unwrap();
            let by_row =
                NetEquations::of_chunks(&d, &partition, estimation, d.len(), d.len(), |r| {
                    r.filter(|&k| rows(k))
                        .map(|k| (d.u[k], d.regressors(k), d.y[k], weight(k)))
                })
                .solve(&d)
                .unwrap();
            for a in 0..3 {
                for (g, r) in grouped.coefficients[a].iter().zip(&by_row.coefficients[a]) {
                    for (x, y) in g.iter().zip(r) {
                        assert!(
                            (x - y).abs() <= 1e-9 * (1.0 + y.abs()),
                            "{estimation:?} axis {a}: grouped {g:?} vs by row {r:?}"
                        );
                    }
                }
            }
        }
    }
}
