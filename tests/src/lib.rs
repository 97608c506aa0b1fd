//! Helpers shared by the end-to-end tests in this folder.

pub mod concealed;
pub mod independent;
pub mod semireal;
use magstand_core::Recording;
use magstand_sim::{Scenario, ValidScenario, simulate};

/// A shipped scenario with overrides, checked.
pub fn scenario(name: &str, overrides: &[&str]) -> ValidScenario {
    let text =
        magstand_sim::builtin::get(name).unwrap_or_else(|| panic!("no shipped scenario {name}"));
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    Scenario::from_toml_with_overrides(text, name, &o)
        .and_then(|s| s.check(name, None))
        .unwrap_or_else(|e| panic!("{name} {overrides:?}: {e}"))
}

/// Simulates a shipped scenario with overrides.
pub fn run(name: &str, overrides: &[&str], seed: u64) -> Recording {
    simulate(&scenario(name, overrides), seed)
}

/// Mean of a per-row quantity over rows whose overall throttle is `level` (to 1e-9).
pub fn level_mean(rec: &Recording, level: f64, f: impl Fn(usize) -> f64) -> f64 {
    let rows: Vec<usize> = (0..rec.len())
        .filter(|&r| (rec.overall_throttle(r) - level).abs() < 1e-9)
        .collect();
    assert!(!rows.is_empty(), "no rows at throttle {level}");
    rows.iter().map(|&r| f(r)).sum::<f64>() / rows.len() as f64
}

/// Rows at least `settle_s` after the last change of any motor command.
pub fn steady_rows(rec: &Recording, settle_s: f64) -> Vec<usize> {
    let mut last_change = f64::NEG_INFINITY;
    (0..rec.len())
        .filter(|&r| {
            if r > 0 && rec.thr.iter().any(|m| m[r] != m[r - 1]) {
                last_change = rec.t_s[r];
            }
            rec.t_s[r] - last_change >= settle_s
        })
        .collect()
}

/// The command line of a suite binary: `[SEEDS [LABEL]]`, and `FIRST_SEED` in the environment.
pub struct SuiteArgs {
    /// The seeds to run, `FIRST_SEED..FIRST_SEED + SEEDS`.
    pub seeds: std::ops::Range<u64>,
    /// Keep only the cases whose label contains this (empty: every case).
    pub only: String,
}

impl SuiteArgs {
    /// Reads the arguments, with `default_seeds` seeds when none are given.
    pub fn from_env(default_seeds: u64) -> Self {
        let count: u64 = std::env::args()
            .nth(1)
            .map(|s| s.parse().expect("SEEDS: a whole number"))
            .unwrap_or(default_seeds);
        let first: u64 = std::env::var("FIRST_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(1);
        SuiteArgs {
            seeds: first..first + count,
            only: std::env::args().nth(2).unwrap_or_default(),
        }
    }
}
