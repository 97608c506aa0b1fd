//! Running a check: the Monte Carlo study for accuracy figures, and per run the diagnosis of
//! the identification recording and the firmware export of the fitted model; each limit is then
//! judged against the spread over the runs.
use std::collections::BTreeMap;

use magstand_diagnose::DiagnoseConfig;
use magstand_logs::export::{LineInput, Span, linear_approximation};
use magstand_study::summary::Stats;
use magstand_study::{StudyObserver, Summary, identification_series, run_study};
use rayon::prelude::*;

use crate::checks_file::{Limit, Ratio, ValidCheck};
use crate::{CheckError, number};

/// What one limit measured.
#[derive(Debug, Clone, PartialEq)]
pub struct LimitResult {
    /// The limit's key (`rmse_ut.max`).
    pub key: String,
    /// The bound (`<= 0.05`).
    pub bound: String,
    /// The measured value, as compared with the bound.
    pub measured: String,
    /// Its spread over the runs.
    pub spread: String,
    /// Whether the limit holds.
    pub passed: bool,
    /// Why it could not be measured (a run whose diagnosis or export failed), if so.
    pub error: Option<String>,
}

/// What one check measured.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckOutcome {
    /// The check's name.
    pub name: String,
    /// Its scenario, as the file names it.
    pub scenario: String,
    /// Its method, as the file names it.
    pub method: String,
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// One result per limit, in the check's order.
    pub results: Vec<LimitResult>,
}

impl CheckOutcome {
    /// Whether every limit holds.
    pub fn passed(&self) -> bool {
        self.results.iter().all(|r| r.passed)
    }
}

/// What each run gave for the per-run limits.
#[derive(Default)]
struct RunProducts {
    /// The diagnosis's names (sorted), or why it failed.
    verdict: Option<Result<Vec<String>, String>>,
    /// Exported parameters by name, or why the fit or the export failed.
    parameters: Option<Result<BTreeMap<String, f64>, String>>,
}

/// Units of work of a check, for progress: the study's runs and the per-run diagnoses and
/// exports.
pub fn work_units(check: &ValidCheck) -> usize {
    let study = check.limits.iter().any(Limit::needs_study);
    let per_run = check.limits.iter().any(|l| !l.needs_study());
    check.runs() * (usize::from(study) + usize::from(per_run))
}

/// Runs one check on `threads` worker threads (all cores when `None`); the result does not
/// depend on the thread count.
pub fn run_check(
    check: &ValidCheck,
    threads: Option<usize>,
    observer: &dyn StudyObserver,
) -> Result<CheckOutcome, CheckError> {
    let study_error = |source| CheckError::Study {
        check: check.name.clone(),
        source: Box::new(source),
    };
    let total = work_units(check);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let step = || {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        observer.run_finished(d, total);
    };
    let summary = if check.limits.iter().any(Limit::needs_study) {
        struct Forward<'a>(&'a (dyn Fn() + Sync));
        impl StudyObserver for Forward<'_> {
            fn run_finished(&self, _: usize, _: usize) {
                (self.0)()
            }
        }
        let result = run_study(&check.study, threads, &Forward(&step)).map_err(study_error)?;
        Some(Summary::new(result.info, &result.outcomes))
    } else {
        None
    };
    let per_run: Vec<RunProducts> = if check.limits.iter().any(|l| !l.needs_study()) {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(t) = threads {
            builder = builder.num_threads(t.max(1));
        }
        let pool = builder
            .build()
            .map_err(|e| study_error(magstand_study::StudyError::Threads(e.to_string())))?;
        let runs: Vec<usize> = (0..check.runs()).collect();
        pool.install(|| {
            runs.par_iter()
                .map(|&r| {
                    let products = run_products(check, r);
                    step();
                    products
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .map_err(study_error)?
    } else {
        Vec::new()
    };
    let results = check
        .limits
        .iter()
        .map(|limit| judge(limit, check, summary.as_ref(), &per_run))
        .collect();
    Ok(CheckOutcome {
        name: check.name.clone(),
        scenario: check.scenario_spec.clone(),
        method: check.method_id.clone(),
        runs: check.runs(),
        seed: check.seed(),
        results,
    })
}

/// Run `run`'s identification recording diagnosed and its fitted model exported, as the
/// check's limits need.
fn run_products(check: &ValidCheck, run: usize) -> Result<RunProducts, magstand_study::StudyError> {
    let (_, _, rec) = identification_series(&check.study, run)?;
    let origin = format!("run {run} identification series");
    let mut products = RunProducts::default();
    if let Some(nominal) = &check.nominal {
        let config = DiagnoseConfig::default()
            .check()
            .expect("the default diagnosis settings are valid");
        products.verdict = Some(
            magstand_diagnose::diagnose(&rec, &origin, nominal, &config)
                .map(|d| {
                    let mut names = d.verdict;
                    names.sort();
                    names
                })
                .map_err(|e| e.to_string()),
        );
    }
    let exports: Vec<&Limit> = check
        .limits
        .iter()
        .filter(|l| matches!(l, Limit::Parameter { .. }))
        .collect();
    if !exports.is_empty() {
        let exported = (|| -> Result<BTreeMap<String, f64>, String> {
            let model = check
                .method
                .config
                .clone()
                .check()
                .and_then(|c| c.fit_recording(&rec, &origin))
                .map_err(|e| e.to_string())?;
            // As `magstand export --model M --to ...` without --recording: the line over the
            // model's own input range.
            let line = linear_approximation(&model, LineInput::of(&model), Span::ModelRange)
                .map_err(|e| e.to_string())?;
            let mut values = BTreeMap::new();
            for l in exports {
                if let Limit::Parameter {
                    autopilot,
                    instance,
                    ..
                } = l
                {
                    values.extend(autopilot.parameters(&line, *instance));
                }
            }
            Ok(values)
        })();
        products.parameters = Some(exported);
    }
    Ok(products)
}

/// Judges one limit.
fn judge(
    limit: &Limit,
    check: &ValidCheck,
    summary: Option<&Summary>,
    per_run: &[RunProducts],
) -> LimitResult {
    let mut result = LimitResult {
        key: limit.key(),
        bound: limit.bound(),
        measured: "-".into(),
        spread: String::new(),
        passed: false,
        error: None,
    };
    let method = summary.and_then(|s| s.method(check.method.id));
    match limit {
        Limit::Figure {
            figure,
            statistic,
            max,
        } => match method.and_then(|m| m.figure(*figure)) {
            Some(stats) => {
                let v = statistic.of(stats);
                result.measured = number(v);
                result.spread = spread(stats);
                result.passed = v <= *max;
            }
            None => result.error = Some(no_figure(method)),
        },
        Limit::Ratio { ratio, max } => {
            let v = method.and_then(|m| match ratio {
                Ratio::Crlb => m.crlb_ratio,
                Ratio::MseCrlb => m.mse_crlb_ratio,
            });
            match v {
                Some(v) => {
                    result.measured = number(v);
                    result.spread = format!("over {} runs", method.map_or(0, |m| m.runs));
                    result.passed = v <= *max;
                }
                None => result.error = Some(no_figure(method)),
            }
        }
        Limit::Failures { max } => {
            if let Some(m) = method {
                result.measured = m.failures.to_string();
                result.spread = match &m.first_failure {
                    Some(first) => format!("of {} runs; first: {first}", check.runs()),
                    None => format!("of {} runs", check.runs()),
                };
                result.passed = m.failures <= *max;
            }
        }
        Limit::Verdict { names } => {
            let mut counts: BTreeMap<String, usize> = BTreeMap::new();
            let mut matching = 0;
            for (run, p) in per_run.iter().enumerate() {
                match &p.verdict {
                    Some(Ok(v)) => {
                        matching += usize::from(v == names);
                        *counts.entry(format!("[{}]", v.join(", "))).or_default() += 1;
                    }
                    Some(Err(e)) => {
                        result.error.get_or_insert(format!("run {run}: {e}"));
                    }
                    None => {}
                }
            }
            result.measured = format!("{matching} of {} runs", per_run.len());
            result.spread = counts
                .iter()
                .map(|(v, n)| format!("{v} x{n}"))
                .collect::<Vec<_>>()
                .join("; ");
            result.passed = result.error.is_none() && matching == per_run.len();
        }
        Limit::Parameter { name, lo, hi, .. } => {
            let mut values = Vec::new();
            for (run, p) in per_run.iter().enumerate() {
                match &p.parameters {
                    Some(Ok(v)) => values.extend(v.get(name).copied()),
                    Some(Err(e)) => {
                        result.error.get_or_insert(format!("run {run}: {e}"));
                    }
                    None => {}
                }
            }
            if let Some(stats) = Stats::of(values.iter().copied()) {
                result.measured = format!("{} to {}", number(stats.min), number(stats.max));
                result.spread = spread(&stats);
                result.passed = result.error.is_none()
                    && values.len() == per_run.len()
                    && values.iter().all(|v| (lo..=hi).contains(&v));
            }
        }
    }
    if let Some(e) = &result.error {
        result.passed = false;
        if result.spread.is_empty() {
            result.spread = e.clone();
        }
    }
    result
}

/// Why a study figure is missing: every run failed, or the method has none.
fn no_figure(method: Option<&magstand_study::summary::MethodSummary>) -> String {
    match method.and_then(|m| m.first_failure.as_deref()) {
        Some(first) => format!("no run gave a value; first failure: {first}"),
        None => "no run gave a value".into(),
    }
}

/// A spread for people: percentiles and extremes over the runs.
fn spread(s: &Stats) -> String {
    format!(
        "min {} p50 {} p95 {} max {} over {} runs",
        number(s.min),
        number(s.p50),
        number(s.p95),
        number(s.max),
        s.n
    )
}
