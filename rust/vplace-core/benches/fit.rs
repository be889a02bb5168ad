//! Benchmarks of issue 3: feature extraction on a 1920x1080 G-buffer and the fit on
//! 8,100 cells x 14 features. Synthetic, deterministic input (fixed-seed PCG32) from
//! `vplace_core::test_util`.
//!
//! Run: `cargo bench -p vplace-core --bench fit`. Targets on 2 cores: extraction < 30 ms,
//! fit < 2 ms.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use vplace_core::{
    fit::features::{extract_features, fit_cells, FEATURE_COUNT},
    fit::regression::{fit, FitParams},
    test_util::{linear_design, Passes},
};

fn bench(c: &mut Criterion) {
    let p = Passes::room(1920, 1080);
    let inp = p.input();
    c.bench_function("extract_features 1920x1080 cell 16", |b| {
        b.iter(|| extract_features(black_box(&inp), 16).unwrap())
    });
    let cells = extract_features(&inp, 16).unwrap();
    c.bench_function("fit_cells 1920x1080 (normalize + select + fit)", |b| {
        b.iter(|| {
            let all = black_box(std::slice::from_ref(&cells));
            fit_cells(all, &["room"], Some(p.light), true, &FitParams::DEFAULT).unwrap()
        })
    });
    let (x, y) = linear_design(8100);
    c.bench_function("fit 8100x14 plain OLS", |b| {
        b.iter(|| fit(black_box(&x), &y, FEATURE_COUNT, &FitParams::PLAIN_OLS).unwrap())
    });
    c.bench_function("fit 8100x14 default (collinear + CV selection)", |b| {
        b.iter(|| fit(black_box(&x), &y, FEATURE_COUNT, &FitParams::DEFAULT).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
