//! Where a mismatch lives: axes, throttle range, time span, up- against down-ramps, around
//! command steps or in steady state, one motor or all.
//!
//! The signal (standardized residuals, or an accepted term's change to the prediction over the
//! noise sd) is averaged over short windows of consecutive rows. For white residuals a
//! window mean times the window length is chi-square with one degree of freedom, so any group
//! of windows (a throttle bin, a time bin, the up-ramps) has a chi-square test; a noise-free
//! signal is called present where its non-centrality exceeds what that test could detect.
use magstand_core::{Recording, Vec3};
use serde::{Deserialize, Serialize};

use crate::stats::{chi2_quantile, t_sf};

/// Where a mismatch, or an effect, shows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Location {
    /// Axes where it is significant (`x`, `y`, `z`).
    pub axes: Vec<String>,
    /// Overall-throttle range where it is significant, [lo, hi].
    pub throttle_range: [f64; 2],
    /// Time span where it is significant, s.
    pub time_span_s: [f64; 2],
    /// `up`, `down`, or `both` (ramps up against ramps down, or not distinguishable).
    pub direction: String,
    /// `steps` (within a second of a command change), `steady`, or `both`.
    pub phase: String,
    /// `all`, or the motors it follows (`motor 1`, `motors 1, 3`).
    pub motors: String,
}

/// Rows within this time after a command change count as "around a step", s.
pub const STEP_WINDOW_S: f64 = 1.0;
/// Smallest command change that counts as a step.
const STEP_SIZE: f64 = 0.02;
/// Window length, s (at least three rows).
const WINDOW_S: f64 = 0.5;
/// Bins of throttle and time.
const BINS: usize = 10;

/// Per-row context for locating.
pub(crate) struct Rows {
    throttle: Vec<f64>,
    direction: Vec<i8>,
    near_step: Vec<bool>,
    differential: Vec<Vec<f64>>,
    t_s: Vec<f64>,
    block: Vec<usize>,
}

impl Rows {
    pub fn new(rec: &Recording, block: &[usize]) -> Rows {
        let n = rec.len();
        let throttle = rec.overall_throttle_column();
        let mut direction = vec![0i8; n];
        let mut near_step = vec![false; n];
        let mut last_step_t = f64::NEG_INFINITY;
        let mut dir = 0i8;
        for r in 1..n {
            let dthr = throttle[r] - throttle[r - 1];
            if dthr.abs() > 1e-6 {
                dir = if dthr > 0.0 { 1 } else { -1 };
            }
            direction[r] = dir;
            if rec.thr.iter().any(|c| (c[r] - c[r - 1]).abs() > STEP_SIZE) {
                last_step_t = rec.t_s[r];
            }
            near_step[r] = rec.t_s[r] - last_step_t <= STEP_WINDOW_S;
        }
        let m = rec.thr.len();
        let differential = (0..m)
            .map(|k| (0..n).map(|r| rec.thr[k][r] - throttle[r]).collect())
            .collect();
        Rows {
            throttle,
            direction,
            near_step,
            differential,
            t_s: rec.t_s.clone(),
            block: block.to_vec(),
        }
    }
}

struct Window {
    stat: [f64; 3],
    mean: [f64; 3],
    t: f64,
    thr: f64,
    dir: i8,
    step: bool,
    diff: Vec<f64>,
}

/// Whether the signal is noisy residuals (tested against white noise) or a noise-free change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Signal {
    Residual,
    Change,
}

fn windows(rows: &Rows, signal: &[Vec3], keep: &[bool]) -> Vec<Window> {
    let n = signal.len();
    let dt = if n > 1 {
        (rows.t_s[n - 1] - rows.t_s[0]) / (n - 1) as f64
    } else {
        1.0
    };
    let w = ((WINDOW_S / dt).round() as usize).max(3);
    let mut out = Vec::new();
    let mut r = 0;
    while r < n {
        if !keep[r] {
            r += 1;
            continue;
        }
        let end = (r..n.min(r + w))
            .take_while(|&k| keep[k] && rows.block[k] == rows.block[r])
            .last()
            .map_or(r, |k| k + 1);
        let len = end - r;
        if len == w {
            let mut mean = [0.0; 3];
            for k in r..end {
                for a in 0..3 {
                    mean[a] += signal[k][a] / len as f64;
                }
            }
            let avg = |v: &dyn Fn(usize) -> f64| (r..end).map(v).sum::<f64>() / len as f64;
            out.push(Window {
                stat: mean.map(|m| len as f64 * m * m),
                mean,
                t: avg(&|k| rows.t_s[k]),
                thr: avg(&|k| rows.throttle[k]),
                dir: rows.direction[(r + end) / 2],
                step: (r..end).filter(|&k| rows.near_step[k]).count() * 2 > len,
                diff: rows.differential.iter().map(|d| avg(&|k| d[k])).collect(),
            });
        }
        r = end.max(r + 1);
    }
    out
}

/// Locates `signal` (per row, already divided by the noise sd) over the rows in `keep`.
pub(crate) fn locate(
    rows: &Rows,
    signal: &[Vec3],
    keep: &[bool],
    kind: Signal,
    significance: f64,
) -> Location {
    let win = windows(rows, signal, keep);
    // Excess over the white-noise expectation against the detection threshold of the group.
    let excess = |group: &[&Window], axes: &[usize], alpha: f64| -> f64 {
        let dof = (group.len() * axes.len()) as f64;
        if dof == 0.0 {
            return f64::NEG_INFINITY;
        }
        let s: f64 = group
            .iter()
            .map(|w| axes.iter().map(|&a| w.stat[a]).sum::<f64>())
            .sum();
        let noise = if kind == Signal::Residual { dof } else { 0.0 };
        (s - noise) - (chi2_quantile(1.0 - alpha, dof) - dof)
    };
    let all: Vec<&Window> = win.iter().collect();
    let mut axes: Vec<usize> = (0..3)
        .filter(|&a| excess(&all, &[a], significance / 3.0) > 0.0)
        .collect();
    let axis_names = axes
        .iter()
        .map(|&a| magstand_core::AXES[a].to_string())
        .collect();
    if axes.is_empty() {
        axes = vec![0, 1, 2];
    }
    let range_of = |value: &dyn Fn(&Window) -> f64, lo: f64, hi: f64| -> [f64; 2] {
        let width = (hi - lo).max(1e-12) / BINS as f64;
        let mut found = [f64::INFINITY, f64::NEG_INFINITY];
        for b in 0..BINS {
            let group: Vec<&Window> = win
                .iter()
                .filter(|w| (((value(w) - lo) / width).floor() as usize).min(BINS - 1) == b)
                .collect();
            if excess(&group, &axes, significance / BINS as f64) > 0.0 {
                for w in group {
                    found[0] = found[0].min(value(w));
                    found[1] = found[1].max(value(w));
                }
            }
        }
        if found[0].is_finite() {
            found
        } else {
            [lo, hi]
        }
    };
    let t0 = rows.t_s.first().copied().unwrap_or(0.0);
    let t1 = rows.t_s.last().copied().unwrap_or(0.0);
    let throttle_range = range_of(&|w| w.thr, 0.0, 1.0);
    let time_span_s = range_of(&|w| w.t, t0, t1);
    let which = |a_name: &str, b_name: &str, is_a: &dyn Fn(&Window) -> Option<bool>| -> String {
        let a: Vec<&Window> = win.iter().filter(|w| is_a(w) == Some(true)).collect();
        let b: Vec<&Window> = win.iter().filter(|w| is_a(w) == Some(false)).collect();
        if a.is_empty() || b.is_empty() {
            return "both".into();
        }
        let (ea, eb) = (
            excess(&a, &axes, significance / 2.0),
            excess(&b, &axes, significance / 2.0),
        );
        match (ea > 0.0, eb > 0.0) {
            (true, false) => a_name.into(),
            (false, true) => b_name.into(),
            _ => "both".into(),
        }
    };
    let direction = which("up", "down", &|w| match w.dir {
        1 => Some(true),
        -1 => Some(false),
        _ => None,
    });
    let phase = which("steps", "steady", &|w| Some(w.step));
    let motors = follows_motors(&win, &axes, significance);
    Location {
        axes: axis_names,
        throttle_range,
        time_span_s,
        direction,
        phase,
        motors,
    }
}

/// Motors whose differential command the windowed signal follows (significant correlation),
/// or "all".
fn follows_motors(win: &[Window], axes: &[usize], significance: f64) -> String {
    let m = win.first().map_or(0, |w| w.diff.len());
    if m < 2 || win.len() < 10 {
        return "all".into();
    }
    let mut found = Vec::new();
    for k in 0..m {
        let x: Vec<f64> = win.iter().map(|w| w.diff[k]).collect();
        let sx = spread(&x);
        if sx < 1e-9 {
            continue;
        }
        let significant = axes.iter().any(|&a| {
            let y: Vec<f64> = win.iter().map(|w| w.mean[a]).collect();
            let r = correlation(&x, &y);
            // |r| as a one-sided t over windows: t = |r| sqrt((n - 2) / (1 - r^2)).
            let n = x.len() as f64;
            let t = r.abs() * ((n - 2.0) / (1.0 - r * r).max(1e-12)).sqrt();
            let p = t_sf(t, n - 2.0);
            p < significance / (m * axes.len()) as f64 && r.abs() > 0.3
        });
        if significant {
            found.push(k + 1);
        }
    }
    match found.len() {
        0 => "all".into(),
        n if n == m => "all".into(),
        1 => format!("motor {}", found[0]),
        _ => format!(
            "motors {}",
            found
                .iter()
                .map(|k| k.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

fn spread(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        0.0
    } else {
        sxy / (sxx * syy).sqrt()
    }
}
