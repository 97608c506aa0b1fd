//! Reading a sampled column between its samples: one rule for the simulator's delayed replay,
//! the flight preparation's delayed inputs and the log import's streams.
use std::ops::{Add, Mul, Sub};

/// Where `x` falls among the increasing times `t`: the index of the sample at or before it and
/// the fraction of the way to the next. Before the first sample it is `(0, 0.0)`, at or after
/// the last `(last, 0.0)`: a column read through it is held at its ends.
pub fn locate(t: &[f64], x: f64) -> (usize, f64) {
    place(t, t.partition_point(|&v| v <= x), x)
}

/// [`locate`] of each of the nondecreasing times `xs` (a column's own times moved by a delay)
/// among the increasing times `t`, walking both once instead of a binary search per time:
/// the same places.
pub fn locate_increasing(t: &[f64], xs: impl Iterator<Item = f64>) -> Vec<(usize, f64)> {
    let mut k = 0;
    xs.map(|x| {
        // `k` counts the times at or before `x`, as `locate`'s partition point does.
        while k < t.len() && t[k] <= x {
            k += 1;
        }
        place(t, k, x)
    })
    .collect()
}

/// The place of `x` given `k`, the number of times in `t` at or before it.
fn place(t: &[f64], k: usize, x: f64) -> (usize, f64) {
    if k == 0 {
        (0, 0.0)
    } else if k >= t.len() {
        (t.len() - 1, 0.0)
    } else {
        (k - 1, (x - t[k - 1]) / (t[k] - t[k - 1]))
    }
}

/// The column `v` at a place found by [`locate`]: linear between its neighbours.
pub fn interpolate<T>(v: &[T], (k, f): (usize, f64)) -> T
where
    T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f64, Output = T>,
{
    if f == 0.0 {
        v[k]
    } else {
        v[k] + (v[k + 1] - v[k]) * f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_inside_and_holds_the_ends() {
        let t = [0.0, 1.0, 3.0];
        let v = [10.0, 20.0, 0.0];
        assert_eq!(locate(&t, -1.0), (0, 0.0));
        assert_eq!(locate(&t, 3.0), (2, 0.0));
        assert_eq!(locate(&t, 7.0), (2, 0.0));
        assert_eq!(locate(&t, 2.0), (1, 0.5));
        assert_eq!(interpolate(&v, locate(&t, 0.5)), 15.0);
        assert_eq!(interpolate(&v, locate(&t, 2.0)), 10.0);
        assert_eq!(interpolate(&v, locate(&t, 1.0)), 20.0);
        assert_eq!(interpolate(&v, locate(&t, -5.0)), 10.0);
        assert_eq!(interpolate(&v, locate(&t, 9.0)), 0.0);
    }

    #[test]
    fn walking_the_times_locates_as_the_binary_search_does() {
        // Uneven times with a repeated one and a gap; places before, inside and after them.
        let t = [0.0, 0.02, 0.04, 0.04, 0.07, 5.0, 5.02];
        let xs: Vec<f64> = (-3..=520).map(|i| f64::from(i) * 0.01 - 0.005).collect();
        let walked = locate_increasing(&t, xs.iter().copied());
        for (x, w) in xs.iter().zip(&walked) {
            assert_eq!(*w, locate(&t, *x), "x = {x}");
        }
    }
}
