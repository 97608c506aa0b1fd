//! Simulation speed: a 10-minute stair at 1 kHz physics with the rapier3d body, one core.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_sim::{Scenario, simulate};

fn ten_minute_stair(c: &mut Criterion) {
    let text = magstand_sim::builtin::get("czyba2015-stair").expect("shipped scenario");
    // 20 steps of 28.5 s plus 2 x 15 s off: 600 s of simulated time.
    let overrides = [
        "program.dwell_s=28.5".to_string(),
        "program.off_s=15.0".to_string(),
    ];
    let s = Scenario::from_toml_with_overrides(text, "czyba2015-stair", &overrides)
        .and_then(|s| s.check("czyba2015-stair", None))
        .expect("valid scenario");
    let mut g = c.benchmark_group("simulate");
    g.sample_size(10);
    g.bench_function("stair_600s_1khz_rapier", |b| b.iter(|| simulate(&s, 3)));
    g.finish();
}

criterion_group!(benches, ten_minute_stair);
criterion_main!(benches);
