//! Monte Carlo speed: a 100-run study of the paper-like stair (2 x 110 s simulated per run,
//! the eight catalog methods fitted and judged), on every core.
//!
//! Run by `cargo bench -p magstand-study --bench study`. Under `cargo test` (no `--bench`
//! flag) it runs a 2-run study once, as a smoke test of the bench itself.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_sim::Scenario;
use magstand_study::{Silent, StudyConfig, run_study};

fn study(c: &mut Criterion) {
    let bench_mode = std::env::args().any(|a| a == "--bench");
    let runs = if bench_mode { 100 } else { 2 };
    let text = magstand_sim::builtin::get("czyba2015-stair").expect("shipped scenario");
    let scenario = Scenario::from_toml_str(text, "czyba2015-stair")
        .and_then(|s| s.check("czyba2015-stair", None))
        .expect("valid scenario");
    let study = StudyConfig::new(runs, 3)
        .check(&scenario)
        .expect("valid study");
    let mut g = c.benchmark_group("montecarlo");
    g.sample_size(10);
    g.bench_function(format!("czyba2015_stair_{runs}_runs"), |b| {
        b.iter(|| run_study(&study, None, &Silent).expect("the study runs"))
    });
    g.finish();
}

criterion_group!(benches, study);
criterion_main!(benches);
