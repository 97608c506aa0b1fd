//! Import speed: one run (magnetometer, motors, battery and attitude at 100 Hz, 200 minutes)
//! as a ULog of about 170 MB and a DataFlash log of about 100 MB, parsed, aligned and turned
//! into a recording. `cargo bench -p magstand-logs --bench import`.
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use magstand_core::{Quat, Recording, Vec3};
use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::{LogWriteOptions, dataflash_bytes, ulog_bytes};

fn long_run(rows: usize) -> Recording {
    let mut rec = Recording {
        thr: (0..4).map(|_| Vec::with_capacity(rows)).collect(),
        bat_v: Some(Vec::with_capacity(rows)),
        bat_a: Some(Vec::with_capacity(rows)),
        attitude: Some(Vec::with_capacity(rows)),
        ..Recording::default()
    };
    for r in 0..rows {
        let t = r as f64 * 0.01;
        let c = 0.5 + 0.4 * (0.1 * t).sin();
        rec.t_s.push(t);
        for m in rec.thr.iter_mut() {
            m.push(c);
        }
        rec.mag_ut
            .push(Vec3::new(20.0 + 5.0 * c, 3.0 - 4.0 * c, -45.0 + 8.0 * c));
        rec.bat_v.as_mut().unwrap().push(16.0 - c);
        rec.bat_a.as_mut().unwrap().push(40.0 * c);
        rec.attitude
            .as_mut()
            .unwrap()
            .push(Quat::from_euler_angles(0.1, -0.05, 0.01 * t));
    }
    rec
}

fn bench(c: &mut Criterion) {
    let rec = long_run(1_200_000);
    let opts = LogWriteOptions::default();
    let ulog = ulog_bytes(&rec, &opts);
    let df = dataflash_bytes(&rec, &opts);
    let mut g = c.benchmark_group("import");
    g.sample_size(10);
    g.bench_function(format!("ulog_{}MB", ulog.len() / 1_000_000), |b| {
        b.iter(|| import_bytes(&ulog, Path::new("big.ulg"), &ImportOptions::default()).unwrap())
    });
    g.bench_function(format!("dataflash_{}MB", df.len() / 1_000_000), |b| {
        b.iter(|| import_bytes(&df, Path::new("big.bin"), &ImportOptions::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
