//! Diagnosing a 10-minute recording at 50 Hz (30 500 rows) against its nominal stand: a clean
//! one (every candidate tried once, none accepted) and one with a concealed slow spin-up (one
//! accepted, a second round). `cargo bench -p magstand-diagnose`.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_diagnose::{DiagnoseConfig, diagnose};
use magstand_sim::{Scenario, simulate};

const STAND: &str = r#"
name = "bench stand"
[program]
kind = "stair"
off_s = 10.0
steps = 10
dwell_s = 10.0
direction = "up_down"
repeats = 3
[supply]
kind = "bench"
voltage_v = 12.0
[magnetometer]
odr_hz = 50.0
"#;

fn bench(c: &mut Criterion) {
    let nominal = Scenario::from_toml_str(STAND, "stand")
        .unwrap()
        .check("stand", None)
        .unwrap();
    let lag =
        Scenario::from_toml_with_overrides(STAND, "lag", &["motors.spinup_tau_s=0.25".into()])
            .unwrap()
            .check("lag", None)
            .unwrap();
    let clean = simulate(&nominal, 1);
    let lagged = simulate(&lag, 1);
    assert_eq!(clean.len(), 30_500);
    let cfg = DiagnoseConfig::default().check().unwrap();
    let mut g = c.benchmark_group("diagnose 10 min at 50 Hz");
    g.sample_size(10);
    g.bench_function("clean", |b| {
        b.iter(|| diagnose(&clean, "clean", &nominal, &cfg).unwrap())
    });
    g.bench_function("concealed current_lag", |b| {
        b.iter(|| diagnose(&lagged, "lag", &nominal, &cfg).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
