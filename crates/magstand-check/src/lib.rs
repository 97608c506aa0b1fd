//! Ground-truth recovery as a gate in a user's own CI (`magstand check`).
//!
//! A check file holds `[[check]]` entries. Each names a scenario (a file, or `builtin:NAME`),
//! a method (or `default`, what `magstand fit` does with no options), a number of runs and a
//! seed, and limits on what those runs give:
//!
//! - the Monte Carlo study's figures against the simulator's truth, as a statistic over the
//!   runs: `rmse_ut.max = 0.05`, `heading_after_deg.p95 = 0.5` (every figure of runs.csv; each
//!   statistic `max`, `p95`, `p50` or `mean` is an upper limit);
//! - the efficiency against the Cramer-Rao bound, for the paper's fixed structure:
//!   `mse_crlb_ratio.max = 1.2`;
//! - the runs allowed to fail: `failures.max` (0 unless stated);
//! - the diagnosis of each run's recording: `diagnose.verdict = ["thermal_drift"]`, against
//!   `diagnose.nominal` (a scenario; by default the unstated default stand);
//! - the exported firmware parameters of each run's model:
//!   `export.ardupilot.COMPASS_MOT_Z = [40, 260]`, `export.px4.CAL_MAG0_ZCOMP = [-1, 0]`.
//!
//! Everything is checked before anything runs ([`CheckFile::check`]). The runs are the
//! study's own ([`magstand_study`]), diagnosed and exported by the same code as the commands,
//! so the same file and seed give the same verdict on any machine and thread count.
//!
//! # Example
//! ```
//! use magstand_check::{CheckFile, run_check};
//!
//! let file = CheckFile::from_toml_str(
//!     r#"
//!     [[check]]
//!     name = "cubic on a short stair"
//!     scenario = "builtin:czyba2015-stair"
//!     set = ["program.dwell_s=2.0", "program.steps=4"]
//!     method = "cubic"
//!     runs = 2
//!     seed = 7
//!     rmse_ut.max = 5.0
//!     export.ardupilot.COMPASS_MOT_Z = [-1000, 1000]
//!     "#,
//!     "example",
//!     std::path::Path::new("."),
//! )?;
//! let checks = file.check()?;
//! let outcome = run_check(&checks.checks[0], Some(1), &magstand_study::Silent)?;
//! assert!(outcome.passed(), "{outcome:?}");
//! # Ok::<(), magstand_check::CheckError>(())
//! ```
#![warn(missing_docs)]

mod checks_file;
mod error;
mod junit;
mod run;

pub use checks_file::{
    CheckFile, DEFAULT_METHOD, Limit, Ratio, Statistic, ValidCheck, ValidChecks,
};
pub use error::CheckError;
pub use junit::junit_xml;
pub use run::{CheckOutcome, LimitResult, run_check, work_units};

/// A number for tables and reports: four significant digits, plain notation.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    if v == 0.0 {
        return "0".into();
    }
    let decimals = (3 - v.abs().log10().floor() as i32).clamp(0, 9) as usize;
    format!("{v:.decimals$}")
}

/// The outcomes as a fixed-width table, one row per limit, with the measured value's spread
/// over the runs.
pub fn table(outcomes: &[CheckOutcome]) -> String {
    let rows: Vec<[String; 6]> = outcomes
        .iter()
        .flat_map(|c| {
            c.results.iter().map(|r| {
                [
                    c.name.clone(),
                    r.key.clone(),
                    r.bound.clone(),
                    r.measured.clone(),
                    if r.passed { "pass" } else { "FAIL" }.to_string(),
                    r.spread.clone(),
                ]
            })
        })
        .collect();
    let header = [
        "check",
        "figure",
        "limit",
        "measured",
        "result",
        "spread over the runs",
    ];
    let widths: Vec<usize> = (0..6)
        .map(|i| {
            rows.iter()
                .map(|r| r[i].chars().count())
                .chain([header[i].len()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cells: [&str; 6]| -> String {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        padded.join("  ").trim_end().to_string() + "\n"
    };
    let mut out = line(header);
    for r in &rows {
        out += &line([&r[0], &r[1], &r[2], &r[3], &r[4], &r[5]]);
    }
    out
}

/// Every failed limit, one line each with its spread over the runs, for the terminal.
pub fn failures(outcomes: &[CheckOutcome]) -> String {
    let mut out = String::new();
    for c in outcomes {
        for r in c.results.iter().filter(|r| !r.passed) {
            out += &format!(
                "check \"{}\": {} = {} is not {} ({})\n",
                c.name, r.key, r.measured, r.bound, r.spread
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_four_significant_digits() {
        for (v, text) in [
            (0.012345, "0.01235"),
            (1.5, "1.500"),
            (152.36, "152.4"),
            (-3.0, "-3.000"),
            (0.0, "0"),
            (123456.0, "123456"),
        ] {
            assert_eq!(number(v), text, "{v}");
        }
    }
}
