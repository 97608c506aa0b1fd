//! The one bounded 1-D search every fit of a nonlinear parameter uses: a grid over the range
//! finds the basin, golden-section search refines it inside the two grid steps around the best
//! point. A grid first, because the functions searched (a residual against a delay, an
//! exponent, a time constant) have flat stretches and local minima a bracket alone would miss.
//!
//! ```
//! use magstand_core::bounded_search::{Grid, minimize};
//! let (x, fx) = minimize(Grid { lo: 0.0, hi: 1.0, points: 11 }, 1e-9, 60, |x| (x - 0.37).powi(2));
//! assert!((x - 0.37).abs() < 1e-6 && fx < 1e-12);
//! ```

/// An even grid over `[lo, hi]` with `points` points (at least two).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Points, ends included.
    pub points: usize,
}

impl Grid {
    /// The spacing of the points.
    pub fn step(&self) -> f64 {
        (self.hi - self.lo) / (self.points.max(2) - 1) as f64
    }

    /// Point `i`.
    pub fn at(&self, i: usize) -> f64 {
        self.lo + i as f64 * self.step()
    }
}

/// The golden ratio's conjugate, the share of the bracket kept each iteration: the bits of
/// `(5f64.sqrt() - 1.0) / 2.0`, which every search here used before it was shared (one ulp
/// above the nearest double to the exact value), so their results did not move.
const GOLDEN: f64 = f64::from_bits(0x3fe3_c6ef_372f_e950);

/// Minimizes `f` over `[a, b]` by golden section: one new evaluation per iteration, until the
/// bracket is narrower than `tolerance` or after `iterations`. Returns the better of the two
/// last interior points and its value. A non-finite value counts as worse than any finite one.
pub fn golden_section(
    mut a: f64,
    mut b: f64,
    tolerance: f64,
    iterations: usize,
    mut f: impl FnMut(f64) -> f64,
) -> (f64, f64) {
    let mut value = |x: f64| {
        let v = f(x);
        if v.is_nan() { f64::INFINITY } else { v }
    };
    let mut c = b - GOLDEN * (b - a);
    let mut d = a + GOLDEN * (b - a);
    let (mut fc, mut fd) = (value(c), value(d));
    for _ in 0..iterations {
        if b - a <= tolerance {
            break;
        }
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - GOLDEN * (b - a);
            fc = value(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + GOLDEN * (b - a);
            fd = value(d);
        }
    }
    if fc < fd { (c, fc) } else { (d, fd) }
}

/// Minimizes `f` over a grid, then by [`golden_section`] within one grid step on each side of
/// the best grid point. Returns the best point found and its value (the grid point itself when
/// the refinement finds nothing better).
pub fn minimize(
    grid: Grid,
    tolerance: f64,
    iterations: usize,
    mut f: impl FnMut(f64) -> f64,
) -> (f64, f64) {
    let mut best = (grid.lo, f64::INFINITY);
    for i in 0..grid.points.max(2) {
        let x = grid.at(i);
        let v = f(x);
        if v < best.1 {
            best = (x, v);
        }
    }
    let h = grid.step();
    let (a, b) = ((best.0 - h).max(grid.lo), (best.0 + h).min(grid.hi));
    let refined = golden_section(a, b, tolerance, iterations, &mut f);
    if refined.1 < best.1 { refined } else { best }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_minimum_beside_a_local_one() {
        // A shallow local minimum at 0.2 and the global one at 0.8.
        let f = |x: f64| {
            -(-((x - 0.2) / 0.05).powi(2)).exp() - 2.0 * (-((x - 0.8) / 0.05).powi(2)).exp()
        };
        let (x, _) = minimize(
            Grid {
                lo: 0.0,
                hi: 1.0,
                points: 21,
            },
            1e-9,
            80,
            f,
        );
        assert!((x - 0.8).abs() < 1e-5, "{x}");
    }

    #[test]
    fn a_minimum_at_the_end_stays_in_range() {
        let (x, _) = minimize(
            Grid {
                lo: 1.0,
                hi: 2.0,
                points: 5,
            },
            1e-9,
            80,
            |x| x,
        );
        assert!((1.0..1.0 + 1e-6).contains(&x), "{x}");
    }

    #[test]
    fn the_ratio_is_the_golden_one_to_the_last_bit() {
        assert_eq!(GOLDEN.to_bits(), ((5f64.sqrt() - 1.0) / 2.0).to_bits());
    }

    #[test]
    fn nan_counts_as_worse() {
        let (x, fx) = golden_section(0.0, 1.0, 1e-9, 80, |x| {
            if x > 0.5 { f64::NAN } else { (x - 0.3).powi(2) }
        });
        assert!((x - 0.3).abs() < 1e-5 && fx.is_finite(), "{x} {fx}");
    }
}
