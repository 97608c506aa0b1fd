//! A small Monte Carlo accuracy study with the library: every run simulates the paper's stand
//! with its own seed, fits two methods and judges them against the truth; the summary gives
//! each figure's spread and the efficiency against the Cramer-Rao bound. An observer (here a
//! line per finished run) is kept apart from the study, as `magstand montecarlo` keeps its
//! progress bar.
//!
//! `cargo run --release -p magstand-cli --example accuracy_study`
use anyhow::Result;
use magstand_sim::Scenario;
use magstand_study::{FigureId, StudyConfig, StudyObserver, Summary, run_study};

/// Prints each finished run.
struct Lines;

impl StudyObserver for Lines {
    fn run_finished(&self, done: usize, total: usize) {
        eprintln!("run {done} of {total} done");
    }
}

fn run() -> Result<()> {
    let scenario = Scenario::load_spec(
        "builtin:czyba2015-tables",
        &["program.dwell_s=2.0".into(), "stand.enabled=false".into()],
    )?;
    let study = StudyConfig {
        methods: vec!["px4".into(), "global-weighted".into()],
        ..StudyConfig::new(6, 42)
    }
    .check(&scenario)?;
    let result = run_study(&study, None, &Lines)?;
    let summary = Summary::new(result.info, &result.outcomes);
    for m in &summary.methods {
        let rmse = m.figure(FigureId::RmseUt).map_or(f64::NAN, |s| s.p50);
        println!(
            "{:36} median disturbance error {rmse:.3} µT, variance over the Cramer-Rao bound {}",
            m.label,
            m.crlb_ratio.map_or("-".into(), |r| format!("{r:.2}"))
        );
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
