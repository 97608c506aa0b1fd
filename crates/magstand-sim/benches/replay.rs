//! Replay speed: what a diagnosis pays for each fit of a battery whose voltage is not logged
//! (the motors coupled through the pack's sag, stepped together in substeps). 25,000 rows at
//! 50 Hz of a hexacopter on a battery: a stair with small attitude-like differences between
//! the motors, and the same stair with one command for all of them; and the first on a bench
//! supply, where the motors are uncoupled (the replay most of a diagnosis's fits make).
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_sim::Scenario;
use magstand_sim::battery::SupplyParams;
use magstand_sim::replay::{Logged, replay_logged};

fn battery_without_bat_v(c: &mut Criterion) {
    let text = magstand_sim::builtin::get("czyba2015-stair").expect("shipped scenario");
    let overrides = ["motors.count=6".to_string()];
    let s = Scenario::from_toml_with_overrides(text, "czyba2015-stair", &overrides)
        .and_then(|s| s.check("czyba2015-stair", None))
        .expect("valid scenario")
        .into_inner();
    let rows = 25_000;
    // A logger's clock with jitter: 20 ms +- 0.4 ms.
    let mut t = 0.0;
    let t_s: Vec<f64> = (0..rows)
        .map(|r| {
            let now = t;
            t += 0.02 + 0.0004 * (r as f64 * 0.7).sin();
            now
        })
        .collect();
    // Ten stairs of 50 s, each motor a few percent off the overall command.
    let thr: Vec<Vec<f64>> = (0..6)
        .map(|m| {
            (0..rows)
                .map(|r| {
                    let level = 0.1 * ((r / 2500) as f64) + 0.05;
                    let wobble = 0.02 * (r as f64 * 0.05 + m as f64).sin();
                    (level + wobble).clamp(0.0, 1.0)
                })
                .collect()
        })
        .collect();
    let one = vec![thr[0].clone(); 6];
    // The same stand on a bench without source resistance: the motors uncoupled, each stepped
    // once per part of an interval (what most of a diagnosis's fits replay).
    let mut bench = s.clone();
    bench.supply = SupplyParams::Bench {
        voltage_v: 12.0,
        source_resistance_ohm: 0.0,
        avionics_current_a: 0.3,
    };
    let mut g = c.benchmark_group("replay");
    g.sample_size(20);
    g.bench_function("hexa_25k_rows_battery_coupled", |b| {
        b.iter(|| replay_logged(&s, &t_s, &thr, Logged::default(), 1.0))
    });
    g.bench_function("hexa_25k_rows_battery_coupled_one_command", |b| {
        b.iter(|| replay_logged(&s, &t_s, &one, Logged::default(), 1.0))
    });
    g.bench_function("hexa_25k_rows_bench_uncoupled", |b| {
        b.iter(|| replay_logged(&bench, &t_s, &thr, Logged::default(), 0.5))
    });
    // A late magnetometer on the bench, one command for all motors: each row read a tenth of a
    // second earlier (a time offset's search replays the recording at dozens of delays).
    let mut late = bench.clone();
    late.logging.mag_delay_s = 0.1;
    g.bench_function("hexa_25k_rows_bench_uncoupled_late_magnetometer", |b| {
        b.iter(|| replay_logged(&late, &t_s, &one, Logged::default(), 0.5))
    });
    g.finish();
}

criterion_group!(benches, battery_without_bat_v);
criterion_main!(benches);
