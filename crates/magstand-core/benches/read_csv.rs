//! Reading and writing speed of the recording CSV: 1,000,000 rows (time, four motor commands,
//! the magnetometer, battery voltage and current), as `fit`, `compensate`, `diagnose` and
//! `report` read them and `simulate`, `compensate` and `import` write them.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use magstand_core::{Recording, Vec3, recording_csv};

fn million() -> Recording {
    let n = 1_000_000;
    let mut rec = Recording {
        thr: (0..4).map(|_| Vec::with_capacity(n)).collect(),
        bat_v: Some(Vec::with_capacity(n)),
        bat_a: Some(Vec::with_capacity(n)),
        ..Default::default()
    };
    for k in 0..n {
        let u = ((k / 20_000) as f64 / 49.0).min(1.0);
        rec.t_s.push(k as f64 * 0.01);
        for (m, thr) in rec.thr.iter_mut().enumerate() {
            thr.push((u + 0.01 * m as f64 * (k as f64 * 0.37).sin()).clamp(0.0, 1.0));
        }
        let wobble = (k as f64 * 0.91).sin();
        rec.mag_ut.push(Vec3::new(
            20.0 + 12.0 * u + 0.3 * wobble,
            1.0 - 6.0 * u,
            45.0 + 20.0 * u * u - 0.2 * wobble,
        ));
        rec.bat_v.as_mut().unwrap().push(16.8 - 1.2 * u);
        rec.bat_a.as_mut().unwrap().push(0.5 + 60.0 * u.powf(1.5));
    }
    rec
}

fn read(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("million.csv");
    let rec = million();
    recording_csv::write(&rec, &path).unwrap();
    let bytes = std::fs::metadata(&path).unwrap().len();
    let mut g = c.benchmark_group("read_csv");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("read_1M_rows", |b| {
        b.iter(|| recording_csv::read(&path).unwrap())
    });
    // Formatting only: the text goes to a sink, not to the disk.
    g.bench_function("write_1M_rows", |b| {
        b.iter(|| recording_csv::write_to(&rec, std::io::sink(), &path).unwrap())
    });
    g.finish();
}

criterion_group!(benches, read);
criterion_main!(benches);
