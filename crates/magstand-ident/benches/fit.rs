//! Fitting speed: 1,000,000 samples x 3 axes, fixed structure and automatic, and compensation.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_core::rbf::paper_tables;
use magstand_core::{Recording, Vec3};
use magstand_ident::{Dataset, Estimation, Fit, FitConfig, InputKind};
use rand::{RngExt, SeedableRng};

fn million() -> Recording {
    let tables = paper_tables();
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(1);
    let n = 1_000_000;
    let mut rec = Recording {
        thr: vec![Vec::with_capacity(n)],
        overall_only: true,
        ..Default::default()
    };
    for k in 0..n {
        let u = ((k / 20_000) as f64 / 49.0).min(1.0);
        rec.t_s.push(k as f64 * 0.01);
        rec.thr[0].push(u);
        let d = |a: usize| (tables[a].eval(u) - tables[a].eval(0.0)) * 100.0;
        let noise = 0.2 + 1.5 * u;
        rec.mag_ut.push(
            Vec3::new(20.0 + d(0), 1.0 + d(1), 45.0 + d(2))
                + Vec3::from_fn(|_, _| noise * (rng.random::<f64>() - 0.5) * 3.46),
        );
    }
    rec
}

fn fit(c: &mut Criterion) {
    let rec = million();
    let data = Dataset::from_recording(&rec, InputKind::Throttle, "bench").unwrap();
    let fixed = FitConfig::fixed(vec![0.0, 0.5, 1.0], 4.0, Estimation::Global)
        .check()
        .unwrap();
    let auto = FitConfig::automatic().check().unwrap();
    let model = fixed.fit(&data).unwrap();
    let mut g = c.benchmark_group("fit_1M_x3");
    g.sample_size(10);
    g.bench_function("dataset_from_recording", |b| {
        b.iter(|| Dataset::from_recording(&rec, InputKind::Throttle, "bench").unwrap())
    });
    g.bench_function("fixed_3rbf_global", |b| {
        b.iter(|| fixed.fit(&data).unwrap())
    });
    g.bench_function("automatic_weighted", |b| {
        b.iter(|| auto.fit(&data).unwrap())
    });
    g.bench_function("compensate", |b| {
        b.iter(|| model.compensate(&rec, "bench").unwrap())
    });
    g.finish();
}

criterion_group!(benches, fit);
criterion_main!(benches);
