//! Search over a candidate's nonlinear parameters (a time constant, a delay, a play width):
//! a grid over the allowed range, then refinement of each coordinate around the best grid
//! point by Brent's method (argmin). The objective is a weighted chi-square, so the
//! uncertainty of a parameter follows from the curvature: `sd = sqrt(2 / f'')`, conditional on
//! the others.
use argmin::core::{CostFunction, Executor};
use argmin::solver::brent::BrentOpt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// One nonlinear parameter and where to look for it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Search {
    /// Name, with its unit suffix.
    pub name: &'static str,
    /// Unit.
    pub unit: &'static str,
    /// Smallest value tried.
    pub lo: f64,
    /// Largest value tried.
    pub hi: f64,
    /// Grid evenly spaced in the logarithm (for scale parameters) rather than linearly.
    pub log: bool,
    /// Grid points.
    pub points: usize,
}

impl Search {
    /// Whether `v` lies at the edge of the range: within 2 % of one grid step of `lo` or `hi`
    /// (where the grid and its refinement end when the best value is beyond the range,
    /// so the data do not determine it).
    pub fn at_bound(&self, v: f64) -> bool {
        let (u, lo, hi) = (
            self.unit_of(v),
            self.unit_of(self.lo),
            self.unit_of(self.hi),
        );
        let step = (hi - lo) / (self.points.max(2) - 1) as f64;
        (u - lo).abs() < 0.02 * step || (hi - u).abs() < 0.02 * step
    }

    fn unit_of(&self, v: f64) -> f64 {
        if self.log { v.ln() } else { v }
    }
    fn value_at(&self, u: f64) -> f64 {
        if self.log { u.exp() } else { u }
    }
    fn u_range(&self) -> (f64, f64) {
        (self.unit_of(self.lo), self.unit_of(self.hi))
    }
    fn step(&self) -> f64 {
        let (a, b) = self.u_range();
        (b - a) / (self.points.max(2) - 1) as f64
    }
    /// The sd of the parameter at `u` (search coordinates) from the chi-square's `curvature`
    /// there in those coordinates, in the parameter's units; None where the curvature does
    /// not open upward.
    fn sd_from_curvature(&self, u: f64, curvature: f64) -> Option<f64> {
        let sd_u = (2.0 / curvature).sqrt();
        let dtheta_du = if self.log { self.value_at(u) } else { 1.0 };
        (curvature.is_finite() && curvature > 0.0).then_some(sd_u * dtheta_du)
    }
}

/// The best parameters found.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Optimum {
    pub theta: Vec<f64>,
    pub value: f64,
    pub sd: Vec<Option<f64>>,
}

/// Most steps of the refinement around the best grid point (each a replay of the recording
/// for most parameters): at most 12 evaluations, what golden-section search needs to shrink
/// the bracket (two grid steps) to 0.618^10 of it.
const REFINE_ITERATIONS: u64 = 11;

/// The refinement's accuracy as a fraction of a grid step: finer than [`Search::at_bound`]'s
/// 2 % of a step (so a minimum beyond the range is still seen at its edge) and than the
/// curvature's step/50 is sensitive to. Brent's method stops within three times this.
const REFINE_TOLERANCE_STEPS: f64 = 0.003;

/// Where the refinement looks just inside an end of the range, as a fraction of a grid step:
/// half of [`Search::at_bound`]'s 2 %, so a minimum between it and the end is at the bound.
const BOUND_PROBE_STEPS: f64 = 0.01;

/// The objective as argmin sees it.
struct Objective<F>(F);

impl<F: Fn(f64) -> f64> CostFunction for Objective<F> {
    type Param = f64;
    type Output = f64;
    fn cost(&self, x: &f64) -> Result<f64, argmin::core::Error> {
        Ok((self.0)(*x))
    }
}

/// Brent's method (argmin's `BrentOpt`: parabolic steps through the three best points where
/// the parabola is trusted, golden-section steps where it is not) on `[a, b]`, to within
/// `tolerance`. A smooth chi-square reaches the tolerance in a few parabolic steps where
/// golden-section search takes all of its steps; a rough one costs no more than golden
/// section. Returns the best point and its value.
fn brent(a: f64, b: f64, tolerance: f64, f: impl Fn(f64) -> f64) -> Option<(f64, f64)> {
    let solver = BrentOpt::new(a, b).set_tolerance(f64::EPSILON.sqrt(), tolerance);
    let result = Executor::new(Objective(f), solver)
        .configure(|state| state.max_iters(REFINE_ITERATIONS))
        .run()
        .ok()?;
    let state = result.state();
    Some((state.best_param?, state.best_cost))
}

/// The objective `f` in search coordinates: infinite where the fit fails.
fn in_search_coordinates<'a>(
    searches: &'a [Search],
    f: &'a (impl Fn(&[f64]) -> Option<f64> + Sync),
) -> impl Fn(&[f64]) -> f64 + Sync + 'a {
    move |u: &[f64]| -> f64 {
        let theta: Vec<f64> = searches
            .iter()
            .zip(u)
            .map(|(s, &u)| s.value_at(u))
            .collect();
        f(&theta).filter(|v| v.is_finite()).unwrap_or(f64::INFINITY)
    }
}

/// Each parameter of `theta` in its search's coordinates.
fn units_of(searches: &[Search], theta: &[f64]) -> Vec<f64> {
    searches
        .iter()
        .zip(theta)
        .map(|(s, &v)| s.unit_of(v))
        .collect()
}

/// Each parameter of `theta` in its search's coordinates, kept within its range.
fn units_in_range(searches: &[Search], theta: &[f64]) -> Vec<f64> {
    searches
        .iter()
        .zip(theta)
        .map(|(s, &v)| {
            let (lo, hi) = s.u_range();
            s.unit_of(v).clamp(lo, hi)
        })
        .collect()
}

/// [`minimize`] over the whole range, or, `from` the optimum of an objective close to this
/// one (the same search after another term's parameters moved a little), Brent's refinement
/// within a grid step of each parameter without the grid. The whole range is searched where
/// `f` cannot be evaluated at `from`.
pub(crate) fn minimize_near(
    searches: &[Search],
    from: Option<&[f64]>,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    minimize_near_or_whole(searches, from, false, Precision::Fine, f)
}

/// [`minimize_near`] to `precision`: [`Precision::Value`] for a search whose optimum's value
/// alone is used (the inner search of a profile, evaluated at every point of another search).
pub(crate) fn minimize_near_to(
    searches: &[Search],
    from: Option<&[f64]>,
    precision: Precision,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    minimize_near_or_whole(searches, from, false, precision, f)
}

/// [`minimize_near`] for a search whose objective may have moved its optimum to another
/// basin (a finding whose misfit a newer term took over runs towards the edge of its range):
/// where the refinement from `from` ends at the end of its bracket inside the range, the whole
/// range is searched too and the better of the two kept.
pub(crate) fn minimize_near_or_beyond(
    searches: &[Search],
    from: &[f64],
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    minimize_near_or_whole(searches, Some(from), true, Precision::Fine, f)
}

/// [`minimize_near`], and, with `beyond`, [`minimize_near_or_beyond`], to `precision`.
fn minimize_near_or_whole(
    searches: &[Search],
    from: Option<&[f64]>,
    beyond: bool,
    precision: Precision,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    let Some(theta) = from.filter(|t| t.len() == searches.len()) else {
        return minimize_to(searches, precision, f);
    };
    let eval = in_search_coordinates(searches, &f);
    let start = units_in_range(searches, theta);
    let value = eval(&start);
    if !value.is_finite() {
        return minimize_to(searches, precision, &f);
    }
    let near = polish(searches, start.clone(), value, &eval, precision)?;
    let left_basin = beyond
        && searches
            .iter()
            .zip(&start)
            .zip(&near.theta)
            .any(|((s, &u0), &v)| {
                let (u, h) = (s.unit_of(v), s.step());
                (u - u0).abs() >= (1.0 - BRACKET_END_STEPS) * h && !s.at_bound(v)
            });
    if !left_basin {
        return Some(near);
    }
    match minimize_to(searches, precision, &f) {
        Some(whole) if whole.value < near.value => Some(whole),
        _ => Some(near),
    }
}

/// How near the end of its bracket (a grid step either way), as a fraction of a grid step, a
/// refinement from a nearby optimum ends where the optimum lies beyond it: Brent's method
/// closes on an end to within three times [`REFINE_TOLERANCE_STEPS`].
const BRACKET_END_STEPS: f64 = 0.02;

/// How far a search refines the best point of its grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Precision {
    /// To [`REFINE_TOLERANCE_STEPS`] of a grid step, with each parameter's uncertainty.
    Fine,
    /// To [`COARSE_TOLERANCE_STEPS`], without uncertainties: where a
    /// fine search from the point found follows (a refinement's first pass, which only has to
    /// find the basin).
    Coarse,
    /// As [`Precision::Fine`], without uncertainties: where only the optimum's value and
    /// parameters are used (the inner search of a profile, run at every point of the outer
    /// search, where the curvature's two evaluations would be a sixth of its cost).
    Value,
}

/// The coarse refinement's accuracy as a fraction of a grid step (see [`Precision::Coarse`]).
const COARSE_TOLERANCE_STEPS: f64 = 0.03;

/// Minimizes `f` (None where the fit fails) over the searches.
pub(crate) fn minimize(
    searches: &[Search],
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    minimize_to(searches, Precision::Fine, f)
}

/// [`minimize`] to `precision`.
pub(crate) fn minimize_to(
    searches: &[Search],
    precision: Precision,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    let eval = in_search_coordinates(searches, &f);
    if searches.is_empty() {
        let value = eval(&[]);
        return value.is_finite().then(|| Optimum {
            theta: vec![],
            value,
            sd: vec![],
        });
    }
    // Grid, its points evaluated in parallel: the candidates of a round are searched in
    // parallel too, but their searches differ tenfold in size, and the refinement after an
    // acceptance searches alone. The first best point in grid order wins, as a sequential
    // scan would have it. One parameter: its whole grid. Several: a grid along each in turn
    // from the middle of the others' ranges, the first one again at the end (a full factorial
    // of two parameters costs their product, and each point is a replay of the recording);
    // the refinement passes below then refine them together.
    let grid_along = |k: usize, base: &[f64]| -> Vec<Vec<f64>> {
        (0..searches[k].points.max(2))
            .map(|i| {
                let mut u = base.to_vec();
                u[k] = searches[k].u_range().0 + i as f64 * searches[k].step();
                u
            })
            .collect()
    };
    let mut best_u: Vec<f64> = searches
        .iter()
        .map(|s| {
            let (lo, hi) = s.u_range();
            let middle = (s.points.max(2) - 1) / 2;
            (lo + middle as f64 * s.step()).min(hi)
        })
        .collect();
    let mut best = f64::INFINITY;
    let sweeps: Vec<usize> = if searches.len() == 1 {
        vec![0]
    } else {
        (0..searches.len()).chain([0]).collect()
    };
    for k in sweeps {
        let grid = grid_along(k, &best_u);
        let values = coarse_to_fine(grid.len(), |i| eval(&grid[i]));
        for (u, v) in grid.into_iter().zip(values) {
            if v < best {
                best = v;
                best_u = u;
            }
        }
    }
    if !best.is_finite() {
        return None;
    }
    polish(searches, best_u, best, &eval, precision)
}

/// Values of a grid of `n` points where the search needs them, evaluated in parallel: every
/// `stride`th point first ([`coarse_stride`]: every other on the grids of a few dozen points),
/// then, halving the stride down to one, the two points that far either side of the best so
/// far, so that the best of the whole grid is found wherever the objective varies over more
/// than `stride` grid steps (as the grids here are sized to resolve), for a fraction of the
/// evaluations. The points not evaluated are infinite. Grids of fewer than
/// [`COARSE_GRID_POINTS`] points are evaluated whole.
fn coarse_to_fine(n: usize, f: impl Fn(usize) -> f64 + Sync) -> Vec<f64> {
    let mut values = vec![f64::INFINITY; n];
    let mut evaluated = vec![false; n];
    let mut evaluate = |values: &mut Vec<f64>, at: Vec<usize>| {
        let at: Vec<usize> = at.into_iter().filter(|&i| !evaluated[i]).collect();
        let got: Vec<f64> = at.par_iter().map(|&i| f(i)).collect();
        for (i, v) in at.into_iter().zip(got) {
            values[i] = v;
            evaluated[i] = true;
        }
    };
    if n < COARSE_GRID_POINTS {
        evaluate(&mut values, (0..n).collect());
        return values;
    }
    let mut stride = coarse_stride(n);
    evaluate(&mut values, (0..n).step_by(stride).collect());
    // The first best in grid order, as a scan of the whole grid takes it.
    let best_of = |values: &[f64]| {
        (0..n).fold(None, |b: Option<usize>, i| match b {
            Some(j) if values[j] <= values[i] => Some(j),
            _ if values[i].is_finite() => Some(i),
            _ => b,
        })
    };
    if best_of(&values).is_none() {
        // Nothing could be fitted on the coarse points: the rest may still be.
        evaluate(&mut values, (0..n).collect());
        return values;
    }
    while stride > 1 {
        stride /= 2;
        let i = best_of(&values).expect("a finite value stays");
        evaluate(
            &mut values,
            [i.checked_sub(stride), Some(i + stride).filter(|&j| j < n)]
                .into_iter()
                .flatten()
                .collect(),
        );
    }
    values
}

/// The stride of [`coarse_to_fine`]'s first pass over a grid of `n` points: the widest power
/// of two that still leaves [`COARSE_PASS_POINTS`] points, and at least two (every other point
/// on the grids of a few dozen points). Only a late magnetometer's delay at 48 Hz and faster,
/// one point per sample interval over a second, is long enough for more: every fourth point,
/// or every eighth from 97 points.
fn coarse_stride(n: usize) -> usize {
    let mut stride = 2;
    while n.div_ceil(2 * stride) >= COARSE_PASS_POINTS {
        stride *= 2;
    }
    stride
}

/// Fewest points the first pass of [`coarse_to_fine`] evaluates at a stride wider than two.
const COARSE_PASS_POINTS: usize = 13;

/// Fewest grid points searched coarse to fine ([`coarse_to_fine`]).
const COARSE_GRID_POINTS: usize = 9;

/// The finite-difference step of [`newton_step`], as a fraction of a grid step.
const NEWTON_PROBE_STEPS: f64 = 0.1;

/// Farthest a [`newton_step`] moves a parameter, in grid steps.
const NEWTON_REACH_STEPS: f64 = 2.0;

/// One Newton step of `f` from `from` over all the searches together: the gradient and the
/// Hessian from central differences at a tenth of a grid step (evaluated in parallel), the
/// step solved by Cholesky, kept within [`NEWTON_REACH_STEPS`] grid steps and the ranges.
/// Where parameters trade off (a slow lag's time constant and the moment within an interval at
/// which commands act), the chi-square is a narrow diagonal valley that a search of one
/// parameter at a time crosses in ever smaller steps; a Newton step follows it. Returns the
/// point reached and its value where it is lower than at `from` (value `at_from`), else None
/// (no upward curvature, or no fall).
pub(crate) fn newton_step(
    searches: &[Search],
    from: &[f64],
    at_from: f64,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<(Vec<f64>, f64)> {
    let n = searches.len();
    if n == 0 || from.len() != n || !at_from.is_finite() {
        return None;
    }
    let eval = in_search_coordinates(searches, &f);
    let u0 = units_of(searches, from);
    let d: Vec<f64> = searches
        .iter()
        .map(|s| NEWTON_PROBE_STEPS * s.step())
        .collect();
    let shifted = |moves: &[(usize, f64)]| {
        let mut u = u0.clone();
        for &(i, sign) in moves {
            u[i] += sign * d[i];
        }
        u
    };
    // Each axis either way, then each pair's four corners.
    let mut probes: Vec<Vec<(usize, f64)>> = Vec::new();
    for i in 0..n {
        probes.push(vec![(i, 1.0)]);
        probes.push(vec![(i, -1.0)]);
    }
    for i in 0..n {
        for j in i + 1..n {
            for (si, sj) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                probes.push(vec![(i, si), (j, sj)]);
            }
        }
    }
    let values: Vec<f64> = probes.par_iter().map(|m| eval(&shifted(m))).collect();
    if values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut gradient = nalgebra::DVector::zeros(n);
    let mut hessian = nalgebra::DMatrix::zeros(n, n);
    for i in 0..n {
        let (up, down) = (values[2 * i], values[2 * i + 1]);
        gradient[i] = (up - down) / (2.0 * d[i]);
        hessian[(i, i)] = (up - 2.0 * at_from + down) / (d[i] * d[i]);
    }
    let mut at = 2 * n;
    for i in 0..n {
        for j in i + 1..n {
            let c = &values[at..at + 4];
            let h = (c[0] - c[1] - c[2] + c[3]) / (4.0 * d[i] * d[j]);
            hessian[(i, j)] = h;
            hessian[(j, i)] = h;
            at += 4;
        }
    }
    let step = hessian.cholesky()?.solve(&(-gradient));
    // The step scaled back as a whole (its direction kept) to the reach, then each parameter
    // kept within its range.
    let reach = (0..n)
        .map(|i| step[i].abs() / (NEWTON_REACH_STEPS * searches[i].step()))
        .fold(1.0, f64::max);
    let u: Vec<f64> = (0..n)
        .map(|i| {
            let (lo, hi) = searches[i].u_range();
            (u0[i] + step[i] / reach).clamp(lo, hi)
        })
        .collect();
    let value = eval(&u);
    (value < at_from).then(|| {
        let theta = searches
            .iter()
            .zip(&u)
            .map(|(s, &u)| s.value_at(u))
            .collect();
        (theta, value)
    })
}

/// How far the optimum of `f` lies from `from` (where `f` is `at_from`), as the fall of `f`
/// that one parabola per parameter predicts: each parameter probed either way at a tenth of a
/// grid step with the others held (all probes evaluated in parallel), the fall to its
/// parabola's minimum within a grid step of `from` and its range, summed over the
/// parameters. None where a probe cannot be evaluated: how far the optimum lies is then not
/// known.
///
/// Costs two evaluations per parameter, where a search near `from` costs a dozen: what a
/// refinement asks before it runs, where the objective may have moved little.
pub(crate) fn predicted_fall(
    searches: &[Search],
    from: &[f64],
    at_from: f64,
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<f64> {
    let n = searches.len();
    if from.len() != n || !at_from.is_finite() {
        return None;
    }
    let eval = in_search_coordinates(searches, &f);
    let u0 = units_of(searches, from);
    // Each parameter's probes inside its range: centred on it, or moved in by the probe's
    // distance at an end (one more evaluation, at the centre).
    let mut probes: Vec<Vec<f64>> = Vec::new();
    let mut centres = Vec::with_capacity(n);
    for (i, s) in searches.iter().enumerate() {
        let (lo, hi) = s.u_range();
        let d = NEWTON_PROBE_STEPS * s.step();
        if hi - lo < 2.0 * d {
            return None;
        }
        let c = u0[i].clamp(lo + d, hi - d);
        centres.push((c, d));
        for x in [c - d, c + d] {
            let mut u = u0.clone();
            u[i] = x;
            probes.push(u);
        }
        if c != u0[i] {
            let mut u = u0.clone();
            u[i] = c;
            probes.push(u);
        }
    }
    let values: Vec<f64> = probes.par_iter().map(|u| eval(u)).collect();
    if values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut at = 0;
    let mut fall = 0.0;
    for (i, (s, &(c, d))) in searches.iter().zip(&centres).enumerate() {
        let (down, up) = (values[at], values[at + 1]);
        at += 2;
        let fc = if c == u0[i] {
            at_from
        } else {
            at += 1;
            values[at - 1]
        };
        let curvature = (up - 2.0 * fc + down) / (d * d);
        let slope = (up - down) / (2.0 * d);
        let parabola = |u: f64| fc + slope * (u - c) + 0.5 * curvature * (u - c) * (u - c);
        let (lo, hi) = s.u_range();
        let h = s.step();
        let (a, b) = ((u0[i] - h).max(lo), (u0[i] + h).min(hi));
        // The parabola's least value within reach: at its vertex where it opens upward, else
        // at an end. A flat or downward parabola extrapolated that far falls at least as fast
        // as a chi-square that turns upward beyond the probes, so the fall is not understated.
        let least = if curvature > 0.0 {
            parabola((c - slope / curvature).clamp(a, b))
        } else {
            parabola(a).min(parabola(b))
        };
        fall += (parabola(u0[i]) - least).max(0.0);
    }
    fall.is_finite().then_some(fall)
}

/// Most parabolas [`minimize_near_by_parabolas`] fits.
const PARABOLA_ITERATIONS: usize = 4;

/// How far either side [`minimize_near_by_parabolas`] probes, as a fraction of a grid step:
/// half of [`NEWTON_PROBE_STEPS`], because a parabola's vertex errs by the chi-square's third
/// derivative times the probes' distance squared.
const PARABOLA_PROBE_STEPS: f64 = NEWTON_PROBE_STEPS / 2.0;

/// The minimum of `f` over one parameter within a grid step of `from`, its value alone (as
/// [`Precision::Value`]): Newton's steps on parabolas through three points
/// [`PARABOLA_PROBE_STEPS`] of a grid step apart, the vertex evaluated each time, until a
/// vertex lies between its probes (where the parabola interpolates instead of extrapolating).
///
/// For the inner search of a profile (a slow lag refitted at each delay): the lag's
/// chi-square is smooth in its time constant and its optimum is near where it starts, so
/// four to seven evaluations reach it about as closely as Brent's method
/// ([`minimize_near_to`]) does in about twelve, each a design of the whole recording. Where a
/// parabola opens downward (no minimum near) or cannot be evaluated, or there are several
/// parameters, [`minimize_near_to`] does the search.
pub(crate) fn minimize_near_by_parabolas(
    searches: &[Search],
    from: &[f64],
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    let fallback = |f| minimize_near_to(searches, Some(from), Precision::Value, f);
    let ([s], [from]) = (searches, from) else {
        return fallback(&f);
    };
    let eval = in_search_coordinates(searches, &f);
    let at = |u: f64| eval(&[u]);
    let (ulo, uhi) = s.u_range();
    let start = s.unit_of(*from).clamp(ulo, uhi);
    let Some(steps) = parabola_steps(s, start, at(start), &at) else {
        return fallback(&f);
    };
    steps.value.is_finite().then(|| Optimum {
        theta: vec![s.value_at(steps.u)],
        value: steps.value,
        sd: vec![None],
    })
}

/// [`minimize_near`] from `from` by Newton's steps on parabolas, as
/// [`minimize_near_by_parabolas`] takes them, one parameter after another (each from where the
/// steps before left the others), with each parameter's uncertainty from the curvature of its
/// last parabola (as [`Precision::Fine`]). Where a parameter's parabolas open downward, cannot
/// be evaluated or do not close on a vertex between their probes within
/// [`PARABOLA_ITERATIONS`], [`minimize_near`] does the search.
///
/// For a refinement's searches near an optimum the model before moved a little (another term
/// refitted, the weights estimated again): the chi-square is smooth there, and three to seven
/// evaluations per parameter reach the optimum about as closely as Brent's method's dozen
/// and its curvature's two.
pub(crate) fn minimize_near_fine_by_parabolas(
    searches: &[Search],
    from: &[f64],
    f: impl Fn(&[f64]) -> Option<f64> + Sync,
) -> Option<Optimum> {
    let fallback = |f| minimize_near(searches, Some(from), f);
    if searches.is_empty() || from.len() != searches.len() {
        return fallback(&f);
    }
    let eval = in_search_coordinates(searches, &f);
    let mut u = units_in_range(searches, from);
    let mut value = eval(&u);
    if !value.is_finite() {
        return fallback(&f);
    }
    let mut sd = Vec::with_capacity(searches.len());
    for (k, s) in searches.iter().enumerate() {
        let base = u.clone();
        let at = |x: f64| {
            let mut v = base.clone();
            v[k] = x;
            eval(&v)
        };
        let Some(steps) = parabola_steps(s, u[k], value, &at).filter(|p| p.closed) else {
            return fallback(&f);
        };
        (u[k], value) = (steps.u, steps.value);
        sd.push(s.sd_from_curvature(steps.u, steps.curvature));
    }
    Some(Optimum {
        theta: searches
            .iter()
            .zip(&u)
            .map(|(s, &u)| s.value_at(u))
            .collect(),
        value,
        sd,
    })
}

/// Where [`parabola_steps`] ended.
struct ParabolaSteps {
    /// The best point evaluated, in search coordinates.
    u: f64,
    /// The objective there.
    value: f64,
    /// The last parabola's curvature, in search coordinates (positive).
    curvature: f64,
    /// Whether the last vertex lay between its probes.
    closed: bool,
}

/// Newton's steps on parabolas for one parameter of search `s` from `start` (where the
/// objective `at` is `at_start`), within a grid step of it: parabolas through three points
/// [`PARABOLA_PROBE_STEPS`] of a grid step apart, the vertex evaluated each time, until a
/// vertex lies between its probes or [`PARABOLA_ITERATIONS`] were fitted. None where the
/// bracket is too narrow to probe or a parabola does not open upward.
fn parabola_steps(
    s: &Search,
    start: f64,
    at_start: f64,
    at: &(impl Fn(f64) -> f64 + Sync),
) -> Option<ParabolaSteps> {
    let (ulo, uhi) = s.u_range();
    let h = s.step();
    // The bracket of `minimize_near_to`'s refinement: a grid step either way.
    let (a, b) = ((start - h).max(ulo), (start + h).min(uhi));
    let d = PARABOLA_PROBE_STEPS * h;
    if b - a < 2.0 * d {
        return None;
    }
    let (mut u, mut fu) = (start, at_start);
    let mut best = (u, fu);
    let mut last_curvature = f64::NAN;
    for _ in 0..PARABOLA_ITERATIONS {
        // The probes within the bracket.
        let c = u.clamp(a + d, b - d);
        let fc = if c == u { fu } else { at(c) };
        let (up, down) = rayon::join(|| at(c + d), || at(c - d));
        for (x, fx) in [(c, fc), (c + d, up), (c - d, down)] {
            if fx < best.1 {
                best = (x, fx);
            }
        }
        let curvature = (up - 2.0 * fc + down) / (d * d);
        if !(curvature.is_finite() && curvature > 0.0) {
            return None;
        }
        last_curvature = curvature;
        let vertex = (c - (up - down) / (2.0 * d) / curvature).clamp(a, b);
        (u, fu) = (vertex, at(vertex));
        if fu < best.1 {
            best = (u, fu);
        }
        if (vertex - c).abs() <= d {
            return Some(ParabolaSteps {
                u: best.0,
                value: best.1,
                curvature,
                closed: true,
            });
        }
    }
    Some(ParabolaSteps {
        u: best.0,
        value: best.1,
        curvature: last_curvature,
        closed: false,
    })
}

/// Brent's refinement of each coordinate around `best_u` (value `best`) to `precision`, then
/// (when fine) each parameter's uncertainty from the curvature.
fn polish(
    searches: &[Search],
    mut best_u: Vec<f64>,
    mut best: f64,
    eval: &(impl Fn(&[f64]) -> f64 + Sync),
    precision: Precision,
) -> Option<Optimum> {
    // Refinement by Brent's method, each coordinate once: where parameters trade off, the
    // coordinate passes of the refinement after an acceptance (and its pattern and Newton
    // steps) follow the coupling; a candidate's search only has to rank and test it, and a
    // second pass over a battery's two parameters cost a round a tenth of a second.
    let tolerance_steps = match precision {
        Precision::Fine | Precision::Value => REFINE_TOLERANCE_STEPS,
        Precision::Coarse => COARSE_TOLERANCE_STEPS,
    };
    // Coordinate `k` refined from `base` (value `at_base`): the point and value where lower.
    let along = |k: usize, base: &[f64], at_base: f64| -> Option<(f64, f64)> {
        let (ulo, uhi) = searches[k].u_range();
        let h = searches[k].step();
        let (a, b) = ((base[k] - h).max(ulo), (base[k] + h).min(uhi));
        let at = |x: f64| {
            let mut u = base.to_vec();
            u[k] = x;
            eval(&u)
        };
        // A best point at an end of the range whose value rises just inside it: the
        // minimum of the (unimodal) bracket lies within that distance of the end, which
        // `Search::at_bound` calls the bound, so Brent's steps towards it (all of its
        // evaluations, each a replay) would not change what is reported.
        let inside = BOUND_PROBE_STEPS * h;
        let end = if base[k] <= ulo {
            Some(ulo + inside)
        } else if base[k] >= uhi {
            Some(uhi - inside)
        } else {
            None
        };
        if end.is_some_and(|x| at(x) >= at_base) {
            return None;
        }
        brent(a, b, tolerance_steps * h, at).filter(|&(_, fx)| fx < at_base)
    };
    // Each coordinate from the same point, on its own core where there are several (Brent's
    // steps are sequential, and a round's other candidates are often done by then), then all
    // the moves together where that is lower still; else the best single move.
    let moves: Vec<Option<(f64, f64)>> = (0..searches.len())
        .into_par_iter()
        .map(|k| along(k, &best_u, best))
        .collect();
    let mut joint = best_u.clone();
    for (k, m) in moves.iter().enumerate() {
        if let Some((x, _)) = m {
            joint[k] = *x;
        }
    }
    let single = moves
        .iter()
        .enumerate()
        .filter_map(|(k, m)| m.map(|(x, fx)| (k, x, fx)))
        .fold(None, |b: Option<(usize, f64, f64)>, m| match b {
            Some(b) if b.2 <= m.2 => Some(b),
            _ => Some(m),
        });
    if let Some((k, x, fx)) = single {
        let at_joint = if moves.iter().filter(|m| m.is_some()).count() > 1 {
            eval(&joint)
        } else {
            f64::INFINITY
        };
        if at_joint < fx {
            (best_u, best) = (joint, at_joint);
        } else {
            best_u[k] = x;
            best = fx;
        }
    }
    let theta = searches
        .iter()
        .zip(&best_u)
        .map(|(s, &u)| s.value_at(u))
        .collect();
    if precision != Precision::Fine {
        return Some(Optimum {
            theta,
            value: best,
            sd: vec![None; searches.len()],
        });
    }
    // Curvature in the search coordinate, converted to the parameter's units (the two
    // neighbours of each parameter evaluated in parallel).
    let sd = searches
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let h = s.step() / 50.0;
            let mut up = best_u.clone();
            up[k] += h;
            let mut down = best_u.clone();
            down[k] -= h;
            let (f_up, f_down) = rayon::join(|| eval(&up), || eval(&down));
            s.sd_from_curvature(best_u[k], (f_up - 2.0 * best + f_down) / (h * h))
        })
        .collect();
    Some(Optimum {
        theta,
        value: best,
        sd,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn search(name: &'static str, lo: f64, hi: f64, log: bool) -> Search {
        Search {
            name,
            unit: "",
            lo,
            hi,
            log,
            points: 9,
        }
    }

    /// The predicted fall is exact on a chi-square quadratic in each parameter, capped at a
    /// grid step's reach; it is zero along a parameter that does not act (flat, at the end
    /// of its range), not understated where the chi-square curves down, and unknown where a
    /// probe cannot be evaluated.
    #[test]
    fn the_predicted_fall_is_each_parabolas_fall_within_a_grid_step() {
        let s = [search("x", 0.0, 1.0, false), search("y", 0.0, 1.0, false)];
        let f = |t: &[f64]| Some(((t[0] - 0.37) / 0.02).powi(2) + ((t[1] - 0.6) / 0.05).powi(2));
        let at = |x: f64, y: f64| f(&[x, y]).unwrap();
        let step = 1.0 / 8.0;
        for (x, y, expected) in [
            (0.38, 0.6, 0.25),
            (0.30, 0.65, 12.25 + 1.0),
            // 0.27 from the optimum, beyond a grid step: the fall to a step away.
            (0.10, 0.6, 182.25 - ((0.27 - step) / 0.02f64).powi(2)),
            // At the end of the range: the probes move inside it.
            (
                1.0,
                0.6,
                (0.63 / 0.02f64).powi(2) - ((0.63 - step) / 0.02f64).powi(2),
            ),
        ] {
            let fall = predicted_fall(&s, &[x, y], at(x, y), f).expect("a fall");
            assert!(
                (fall - expected).abs() < 1e-6 * expected.max(1.0),
                "from ({x}, {y}): predicted {fall}, expected {expected}"
            );
        }
        let flat = |t: &[f64]| Some(((t[0] - 0.37) / 0.02).powi(2) + 0.0 * t[1]);
        let fall = predicted_fall(&s, &[0.37, 0.0], 0.0, flat).expect("a fall");
        assert!(fall.abs() < 1e-9, "flat at its bound: {fall}");
        let down = |t: &[f64]| Some(-((t[0] - 0.5) / 0.1).powi(2));
        let fall = predicted_fall(&s[..1], &[0.5], 0.0, down).expect("a fall");
        let expected = (step / 0.1f64).powi(2);
        assert!(
            (fall - expected).abs() < 1e-6,
            "curving down: predicted {fall}, expected {expected}"
        );
        let partial = |t: &[f64]| (t[0] < 0.5).then(|| ((t[0] - 0.37) / 0.02).powi(2));
        let fall = predicted_fall(&s[..1], &[0.5], at(0.5, 0.6), partial);
        assert!(fall.is_none(), "a probe not evaluated: {fall:?}");
    }

    #[test]
    fn finds_the_minimum_of_a_parabola_and_its_curvature_sd() {
        // chi2 = ((x - 0.37) / 0.02)^2: minimum 0.37, sd 0.02.
        let o = minimize(&[search("x", 0.0, 1.0, false)], |t| {
            Some(((t[0] - 0.37) / 0.02).powi(2))
        })
        .unwrap();
        assert!((o.theta[0] - 0.37).abs() < 1e-4, "{:?}", o.theta);
        let sd = o.sd[0].unwrap();
        assert!((sd - 0.02).abs() < 1e-4, "sd {sd}");
    }

    #[test]
    fn a_search_from_a_nearby_optimum_refines_it_without_the_grid() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let calls = AtomicUsize::new(0);
        let f = |t: &[f64]| {
            calls.fetch_add(1, Ordering::Relaxed);
            Some(((t[0] - 0.37) / 0.02).powi(2))
        };
        let s = [search("x", 0.0, 1.0, false)];
        let o = minimize_near(&s, Some(&[0.40]), f).unwrap();
        assert!((o.theta[0] - 0.37).abs() < 1e-4, "{:?}", o.theta);
        assert!((o.sd[0].unwrap() - 0.02).abs() < 1e-4, "{:?}", o.sd);
        let near = calls.swap(0, Ordering::Relaxed);
        minimize(&s, f).unwrap();
        let whole = calls.load(Ordering::Relaxed);
        assert!(
            near < whole,
            "{near} evaluations from nearby, {whole} over the range"
        );
        // Where the start cannot be evaluated, the whole range is searched.
        let o = minimize_near(&s, Some(&[0.9]), |t| {
            (t[0] < 0.8).then(|| ((t[0] - 0.37) / 0.02).powi(2))
        })
        .unwrap();
        assert!((o.theta[0] - 0.37).abs() < 1e-4, "{:?}", o.theta);
    }

    /// A search whose optimum moved far from where it was (a finding whose misfit a newer term
    /// took over): the refinement near the old optimum ends at its bracket, a grid step away;
    /// searched for beyond, the whole range finds it.
    #[test]
    fn a_search_near_an_optimum_that_moved_away_looks_beyond_its_bracket() {
        let f = |t: &[f64]| Some(((t[0] - 0.9) / 0.02).powi(2));
        let s = [search("x", 0.0, 1.0, false)];
        let near = minimize_near(&s, Some(&[0.3]), f).unwrap();
        let step = 1.0 / 8.0;
        assert!(
            (near.theta[0] - (0.3 + step)).abs() < 0.01 * step,
            "the near search ended at {:?}, not at its bracket's end",
            near.theta
        );
        let beyond = minimize_near_or_beyond(&s, &[0.3], f).unwrap();
        assert!((beyond.theta[0] - 0.9).abs() < 1e-4, "{:?}", beyond.theta);
        // Where the optimum lies within the bracket, nothing more is searched.
        use std::sync::atomic::{AtomicUsize, Ordering};
        let calls = AtomicUsize::new(0);
        let counted = |t: &[f64]| {
            calls.fetch_add(1, Ordering::Relaxed);
            f(t)
        };
        minimize_near(&s, Some(&[0.85]), counted).unwrap();
        let near_calls = calls.swap(0, Ordering::Relaxed);
        let o = minimize_near_or_beyond(&s, &[0.85], counted).unwrap();
        assert!((o.theta[0] - 0.9).abs() < 1e-4, "{:?}", o.theta);
        assert_eq!(calls.load(Ordering::Relaxed), near_calls);
    }

    /// The inner search of a profile: a lag's smooth chi-square in its log time constant
    /// (with a cubic part, so that a parabola is not exact) from a start within a grid step.
    #[test]
    fn parabolas_find_a_smooth_minimum_near_the_start_in_a_few_evaluations() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let s = [Search {
            points: 15,
            ..search("tau", 0.001, 3.0, true)
        }];
        let calls = AtomicUsize::new(0);
        let f = |t: &[f64]| {
            calls.fetch_add(1, Ordering::Relaxed);
            let x = (t[0] / 0.5).ln() / 0.002;
            Some(x * x + 0.002 * x * x * x)
        };
        for start in [0.5, 0.51, 0.53, 0.56, 0.47] {
            calls.store(0, Ordering::Relaxed);
            let o = minimize_near_by_parabolas(&s, &[start], f).unwrap();
            let n = calls.load(Ordering::Relaxed);
            // Within half the time constant's uncertainty (0.2 %), and the chi-square within a
            // tenth of the one unit that an uncertainty's worth adds: what a profile needs.
            assert!((o.theta[0] / 0.5 - 1.0).abs() < 1e-3, "from {start}: {o:?}");
            assert!(o.value < 0.1, "from {start}: {o:?}");
            assert!(n <= 7, "from {start}: {n} evaluations");
            calls.store(0, Ordering::Relaxed);
            let brent = minimize_near_to(&s, Some(&[start]), Precision::Value, f).unwrap();
            let by_brent = calls.load(Ordering::Relaxed);
            assert!(
                o.value <= brent.value + 0.1 && n < by_brent,
                "{o:?} in {n} evaluations against Brent's {brent:?} in {by_brent}"
            );
        }
        // A minimum beyond the bracket (a grid step from the start) ends at its end, as
        // Brent's refinement does.
        let o = minimize_near_by_parabolas(&s, &[1.5], f).unwrap();
        let end = 1.5 * (-(3000.0f64).ln() / 14.0).exp();
        assert!((o.theta[0] / end - 1.0).abs() < 1e-9, "{o:?}, end {end}");
        // No minimum near (a chi-square that opens downward): Brent's refinement decides.
        let hill = |t: &[f64]| Some(-((t[0] / 0.5).ln()).powi(2));
        assert_eq!(
            minimize_near_by_parabolas(&s, &[0.55], hill),
            minimize_near_to(&s, Some(&[0.55]), Precision::Value, hill)
        );
    }

    /// A refinement's search near an optimum by parabolas: two parameters (one on a log
    /// grid, each chi-square with a cubic part, so that a parabola is not exact) reach the
    /// optimum and its curvature's sd as Brent's refinement does, in fewer evaluations; a
    /// minimum beyond the bracket ends at its end, as Brent's refinement does; where a
    /// parabola opens downward, Brent's refinement decides.
    #[test]
    fn fine_parabolas_reach_brents_optimum_and_sd_in_fewer_evaluations() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let s = [
            Search {
                points: 15,
                ..search("tau", 0.001, 3.0, true)
            },
            search("x", 0.0, 1.0, false),
        ];
        let calls = AtomicUsize::new(0);
        // Optimum at tau 0.5 (sd 0.2 % of it) and x 0.37 (sd 0.02).
        let f = |t: &[f64]| {
            calls.fetch_add(1, Ordering::Relaxed);
            let a = (t[0] / 0.5).ln() / 0.002;
            let b = (t[1] - 0.37) / 0.02;
            Some(a * a + 0.002 * a * a * a + b * b + 0.01 * b * b * b)
        };
        for start in [[0.5, 0.37], [0.52, 0.40], [0.47, 0.33]] {
            calls.store(0, Ordering::Relaxed);
            let o = minimize_near_fine_by_parabolas(&s, &start, f).expect("an optimum");
            let n = calls.load(Ordering::Relaxed);
            calls.store(0, Ordering::Relaxed);
            let brent = minimize_near(&s, Some(&start), f).expect("Brent's optimum");
            let by_brent = calls.load(Ordering::Relaxed);
            assert!(
                (o.theta[0] / 0.5 - 1.0).abs() < 1e-3 && (o.theta[1] - 0.37).abs() < 0.01,
                "from {start:?}: {o:?}"
            );
            assert!(o.value < 0.1, "from {start:?}: {o:?}");
            for (k, (got, want)) in o.sd.iter().zip(&brent.sd).enumerate() {
                let (got, want) = (got.expect("an sd"), want.expect("Brent's sd"));
                assert!(
                    (got / want - 1.0).abs() < 0.05,
                    "from {start:?}: parameter {k}'s sd {got}, Brent's {want}"
                );
            }
            assert!(
                n < by_brent,
                "{o:?} in {n} evaluations against Brent's {brent:?} in {by_brent}"
            );
        }
        // An optimum beyond the bracket (a grid step, 0.125, from the start): both end at
        // its end.
        let far = |t: &[f64]| Some(((t[0] - 0.9) / 0.02).powi(2));
        let one = [search("x", 0.0, 1.0, false)];
        for o in [
            minimize_near_fine_by_parabolas(&one, &[0.3], far),
            minimize_near(&one, Some(&[0.3]), far),
        ] {
            let x = o.expect("an optimum").theta[0];
            assert!((x - 0.425).abs() < 1e-3, "ended at {x}");
        }
        let hill = |t: &[f64]| Some(-((t[0] - 0.5) / 0.1).powi(2));
        assert_eq!(
            minimize_near_fine_by_parabolas(&one, &[0.55], hill),
            minimize_near(&one, Some(&[0.55]), hill)
        );
    }

    #[test]
    fn two_parameters_on_a_log_grid() {
        let o = minimize(
            &[search("a", 0.01, 10.0, true), search("b", 0.0, 1.0, false)],
            |t| Some((t[0].ln() - 0.3f64.ln()).powi(2) * 100.0 + (t[1] - 0.6).powi(2) * 100.0),
        )
        .unwrap();
        assert!(
            (o.theta[0] - 0.3).abs() < 1e-3 && (o.theta[1] - 0.6).abs() < 1e-3,
            "{:?}",
            o.theta
        );
    }

    #[test]
    fn a_minimum_beyond_the_range_is_reported_at_its_edge_in_one_evaluation() {
        // chi2 falls towards 0 and beyond: the grid's best point is 0, and one look just
        // inside it shows the value rising, so the bound is the answer and Brent's steps are
        // not taken.
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let s = search("x", 0.0, 1.0, false);
        let o = minimize(std::slice::from_ref(&s), |t| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            Some((t[0] + 0.3).powi(2))
        })
        .unwrap();
        let n = calls.into_inner();
        assert_eq!(o.theta, vec![0.0], "{o:?}");
        assert!(s.at_bound(o.theta[0]));
        // The 9-point grid's 5 coarse points and the fine one beside the best, the probe, and
        // the curvature's two.
        assert_eq!(n, 5 + 1 + 1 + 2, "{n} evaluations");
        // A minimum just inside the edge is still refined.
        let o = minimize(std::slice::from_ref(&s), |t| Some((t[0] - 0.05).powi(2))).unwrap();
        assert!((o.theta[0] - 0.05).abs() < 1e-3, "{o:?}");
        assert!(!s.at_bound(o.theta[0]));
    }

    #[test]
    fn a_long_grid_is_searched_from_a_wider_stride_and_finds_its_best_point() {
        // A late magnetometer's delay at 50 and 100 Hz: 51 and 101 points, every fourth and
        // eighth first, then two points at each halved stride; shorter grids every other.
        for (n, stride) in [
            (9, 2),
            (31, 2),
            (41, 2),
            (49, 4),
            (51, 4),
            (76, 4),
            (101, 8),
        ] {
            assert_eq!(coarse_stride(n), stride, "{n} points");
        }
        for (n, most) in [(51, 13 + 2 + 2), (101, 13 + 2 + 2 + 2)] {
            for k in 0..=40 {
                // Minima on every kind of point, at both ends, and between points; a ripple of
                // a tenth of a step's rise (the chi-square's kink at each sample interval).
                let at = k as f64 * (n - 1) as f64 / 40.0 + if k % 3 == 0 { 0.37 } else { 0.0 };
                let f = |i: usize| {
                    let x = i as f64 - at;
                    x.abs() + 0.1 * (i % 2) as f64
                };
                let values = coarse_to_fine(n, f);
                let evaluated = values.iter().filter(|v| v.is_finite()).count();
                assert!(
                    evaluated <= most,
                    "{n} points: {evaluated} evaluations, minimum at {at}"
                );
                let best = |v: &[f64]| (0..v.len()).fold(0, |b, i| if v[i] < v[b] { i } else { b });
                let whole: Vec<f64> = (0..n).map(f).collect();
                assert_eq!(best(&values), best(&whole), "{n} points, minimum at {at}");
            }
        }
    }

    #[test]
    fn a_coarse_then_fine_grid_finds_the_whole_grids_best_point() {
        // Minima anywhere on a 31-point grid, on an even or an odd point, at either end, and a
        // tie (the first in grid order wins, as a scan of the whole grid has it).
        for at in [0.0, 0.4, 3.0, 14.5, 14.6, 15.0, 29.5, 30.0] {
            let f = |i: usize| (i as f64 - at).powi(2);
            let values = coarse_to_fine(31, f);
            let evaluated = values.iter().filter(|v| v.is_finite()).count();
            assert!(
                evaluated <= 16 + 2,
                "{evaluated} evaluations for a minimum at {at}"
            );
            let best = |v: &[f64]| (0..v.len()).fold(0, |b, i| if v[i] < v[b] { i } else { b });
            let whole: Vec<f64> = (0..31).map(f).collect();
            assert_eq!(best(&values), best(&whole), "minimum at {at}");
        }
        // Small grids are evaluated whole; coarse points that cannot be fitted leave the
        // others to be tried.
        assert!(
            coarse_to_fine(5, |i| i as f64)
                .iter()
                .all(|v| v.is_finite())
        );
        let v = coarse_to_fine(9, |i| if i % 2 == 0 { f64::INFINITY } else { i as f64 });
        assert_eq!(v[1], 1.0, "{v:?}");
    }

    #[test]
    fn a_coarse_search_finds_the_basin_in_fewer_evaluations_without_uncertainties() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let calls = AtomicUsize::new(0);
        // Two basins; the deeper one at 0.71 (sd 0.05), which a fine search then refines.
        let f = |t: &[f64]| {
            calls.fetch_add(1, Ordering::Relaxed);
            let x = t[0];
            Some((((x - 0.2) / 0.05).powi(2) + 3.0).min(((x - 0.71) / 0.05).powi(2)))
        };
        let s = [search("x", 0.0, 1.0, false)];
        let coarse = minimize_to(&s, Precision::Coarse, f).unwrap();
        let n_coarse = calls.swap(0, Ordering::Relaxed);
        let fine = minimize(&s, f).unwrap();
        let n_fine = calls.load(Ordering::Relaxed);
        let step = 1.0 / 8.0;
        assert!(
            (coarse.theta[0] - 0.71).abs() < 3.0 * COARSE_TOLERANCE_STEPS * step,
            "coarse {:?}",
            coarse.theta
        );
        assert!(coarse.sd.iter().all(Option::is_none), "{:?}", coarse.sd);
        assert!((fine.theta[0] - 0.71).abs() < 1e-4, "fine {:?}", fine.theta);
        assert!(fine.sd[0].is_some(), "{:?}", fine.sd);
        assert!(
            n_coarse < n_fine,
            "{n_coarse} evaluations coarse, {n_fine} fine"
        );
        // Refined from the coarse point, the fine search ends where the whole search did.
        let near = minimize_near(&s, Some(&coarse.theta), f).unwrap();
        assert!(
            (near.theta[0] - fine.theta[0]).abs() < 1e-4,
            "{near:?} vs {fine:?}"
        );
    }

    /// A narrow diagonal valley (two parameters that trade off, 100 times better determined
    /// across the valley than along it): one Newton step from a point on its floor, where a
    /// search of one parameter at a time stands still, reaches the minimum; from the minimum
    /// it finds no fall.
    #[test]
    fn a_newton_step_follows_a_narrow_valley_to_its_minimum() {
        let f = |t: &[f64]| {
            let (x, y) = (t[0], t[1]);
            Some(((x - y) / 0.001).powi(2) + ((x + y - 1.0) / 0.1).powi(2))
        };
        let s = [search("x", 0.0, 1.0, false), search("y", 0.0, 1.0, false)];
        let from = [0.4, 0.4];
        let at_from = f(&from).unwrap();
        // On the valley's floor each coordinate alone is at its minimum (to 1e-4).
        for (dx, dy) in [(1e-4, 0.0), (-1e-4, 0.0), (0.0, 1e-4), (0.0, -1e-4)] {
            assert!(f(&[0.4 + dx, 0.4 + dy]).unwrap() > at_from, "{dx} {dy}");
        }
        let (theta, value) = newton_step(&s, &from, at_from, f).expect("a fall");
        assert!(
            (theta[0] - 0.5).abs() < 1e-6 && (theta[1] - 0.5).abs() < 1e-6,
            "{theta:?} (value {value}), not the minimum at (0.5, 0.5)"
        );
        assert!(newton_step(&s, &theta, value, f).is_none());
        // A saddle has no Newton step downhill.
        let saddle = |t: &[f64]| Some((t[0] - 0.5).powi(2) - (t[1] - 0.5).powi(2));
        assert!(newton_step(&s, &[0.4, 0.4], saddle(&[0.4, 0.4]).unwrap(), saddle).is_none());
    }

    #[test]
    fn all_failures_give_none() {
        assert!(minimize(&[search("x", 0.0, 1.0, false)], |_| None).is_none());
    }
}
