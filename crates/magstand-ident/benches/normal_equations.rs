//! Normal equations of a wide design (36 columns x 3 outputs, 25,000 rows of which a fifth
//! held out: the size of a diagnosis's battery candidate), row by row and a block of columns
//! at a time.
use criterion::{Criterion, criterion_group, criterion_main};
use magstand_ident::least_squares::{SharedRowEquations, sum_column_rows};

fn normal_equations(c: &mut Criterion) {
    let (p, n) = (36, 25_000);
    let columns: Vec<Vec<f64>> = (0..p)
        .map(|j| {
            (0..n)
                .map(|r| ((r * (j + 3)) as f64 * 0.001).sin())
                .collect()
        })
        .collect();
    let held_out: Vec<bool> = (0..n).map(|r| (r / 500) % 5 == 4).collect();
    let y = |r: usize| [r as f64 * 1e-4, 2.0, -1.0];
    let w = |r: usize| [1.0, 0.5 + (r % 3) as f64, 0.25];
    let mut g = c.benchmark_group("normal_equations_36x3_25k");
    g.sample_size(20);
    g.bench_function("row_by_row", |b| {
        let mut x = vec![0.0; p];
        b.iter(|| {
            let mut ne = SharedRowEquations::<3>::new(p);
            for r in (0..n).filter(|&r| !held_out[r]) {
                for (xj, column) in x.iter_mut().zip(&columns) {
                    *xj = column[r];
                }
                ne.add(&x, y(r), w(r));
            }
            ne
        })
    });
    g.bench_function("column_blocks", |b| {
        let refs: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
        b.iter(|| sum_column_rows(&refs, (0..n).filter(|&r| !held_out[r]), y, w))
    });
    g.finish();
}

criterion_group!(benches, normal_equations);
criterion_main!(benches);
