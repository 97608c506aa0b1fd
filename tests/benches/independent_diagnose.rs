//! Issue 22's speed goal, measured on recordings magstand did not make: `diagnose` of 25,000
//! rows at 50 Hz from the independent generator's octocopter (eight motors, its slowest stand
//! to replay), without a scenario, on 2 cores. A control, and the board-heating drift with
//! `temp_c` logged (a finding, its refinement and a second catalog round).
//! `cargo bench -p magstand-tests --bench independent_diagnose`.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_diagnose::{DiagnoseConfig, diagnose};
use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, cases, nominal_on, recording_on};

fn bench(c: &mut Criterion) {
    let stand = Stand {
        rate_hz: 50.0,
        ..Stand::octocopter()
    };
    let nominal = nominal_on(&stand, Mode::Unstated);
    let cfg = DiagnoseConfig::default().check().expect("default config");
    let mut g = c.benchmark_group("diagnose 25,000 rows at 50 Hz, octocopter, unstated");
    g.sample_size(10);
    for label in ["control", "thermal drift"] {
        let case = cases()
            .into_iter()
            .find(|case| case.label == label)
            .expect("a case of the independent suite");
        let (rec, _) = recording_on(&stand, &case, 1);
        assert_eq!(rec.len(), 25_000, "{label}: rows");
        g.bench_function(label, |b| {
            b.iter(|| diagnose(&rec, label, &nominal, &cfg).expect("diagnosed"))
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
