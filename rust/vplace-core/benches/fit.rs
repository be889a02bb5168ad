//! Benchmarks of issue 3: feature extraction on a 1920x1080 G-buffer and the fit on
//! 8,100 cells x 14 features. Synthetic, deterministic input (fixed-seed PCG32).
//!
//! Run: `cargo bench -p vplace-core --bench fit`. Targets on 2 cores: extraction < 30 ms,
//! fit < 2 ms.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec3;
use std::hint::black_box;
use vplace_core::{
    features::{extract_features, fit_cells, FeatureInput, StrongestLight, FEATURE_COUNT},
    regression::{fit, FitParams},
    rng::Rng,
};

/// The passes of a synthetic view: a floor, a back wall and a sphere-ish bump, 8% background.
struct Passes {
    w: usize,
    h: usize,
    position: Vec<f32>,
    normal: Vec<f32>,
    albedo: Vec<f32>,
    depth: Vec<f32>,
    direct: Vec<f32>,
    gi: Vec<f32>,
    covered: Vec<bool>,
}

fn passes(w: usize, h: usize) -> Passes {
    let n = w * h;
    let mut rng = Rng::new(42, 1);
    let mut p = Passes {
        w,
        h,
        position: vec![0.0; 3 * n],
        normal: vec![0.0; 3 * n],
        albedo: vec![0.0; 3 * n],
        depth: vec![1e10; n],
        direct: vec![0.0; 3 * n],
        gi: vec![0.0; 3 * n],
        covered: vec![false; n],
    };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            if u > 0.92 && v < 0.5 {
                continue; // background
            }
            p.covered[i] = true;
            let floor = v > 0.6;
            let nrm = if floor {
                Vec3::Z
            } else {
                Vec3::new(0.0, -1.0, 0.0)
            };
            let pos = if floor {
                Vec3::new(u * 4.0 - 2.0, 4.0 * (v - 0.6), 0.0)
            } else {
                Vec3::new(u * 4.0 - 2.0, 3.0, 3.0 * (1.0 - v))
            };
            let alb = if (x / 64 + y / 64) % 2 == 0 { 0.8 } else { 0.3 };
            let d = 0.5 * alb * nrm.z.max(0.2) + 0.05 * rng.next_f32();
            let g = d + 0.1 * alb * (1.0 - v) + 0.02 * rng.next_f32();
            p.position[3 * i..3 * i + 3].copy_from_slice(&pos.to_array());
            p.normal[3 * i..3 * i + 3].copy_from_slice(&nrm.to_array());
            p.albedo[3 * i..3 * i + 3].fill(alb);
            p.depth[i] = 1.0 + 5.0 * (1.0 - v) + u;
            p.direct[3 * i..3 * i + 3].fill(d);
            p.gi[3 * i..3 * i + 3].fill(g);
        }
    }
    p
}

fn input(p: &Passes) -> FeatureInput<'_> {
    FeatureInput {
        width: p.w,
        height: p.h,
        position: &p.position,
        normal: &p.normal,
        albedo: &p.albedo,
        depth: &p.depth,
        direct: &p.direct,
        gi: Some(&p.gi),
        specular: None,
        covered: &p.covered,
        light: Some(StrongestLight::Position(Vec3::new(0.0, 1.0, 2.5))),
    }
}

/// A random 8,100 x 14 design with a linear label plus noise.
fn design(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(7, 2);
    let x: Vec<f64> = (0..n * FEATURE_COUNT)
        .map(|_| f64::from(rng.next_f32()))
        .collect();
    let y = x
        .chunks_exact(FEATURE_COUNT)
        .map(|r| {
            r.iter()
                .enumerate()
                .map(|(j, v)| v * (j % 4) as f64)
                .sum::<f64>()
                + 0.1 * f64::from(rng.next_f32())
        })
        .collect();
    (x, y)
}

fn bench(c: &mut Criterion) {
    let p = passes(1920, 1080);
    let inp = input(&p);
    c.bench_function("extract_features 1920x1080 cell 16", |b| {
        b.iter(|| extract_features(black_box(&inp), 16).unwrap())
    });
    let cells = extract_features(&inp, 16).unwrap();
    c.bench_function("fit_cells 1920x1080 (normalize + select + fit)", |b| {
        b.iter(|| fit_cells(black_box(&cells), &FitParams::DEFAULT).unwrap())
    });
    let (x, y) = design(8100);
    c.bench_function("fit 8100x14 plain OLS", |b| {
        b.iter(|| fit(black_box(&x), &y, FEATURE_COUNT, &FitParams::PLAIN_OLS).unwrap())
    });
    c.bench_function("fit 8100x14 default (collinear + CV selection)", |b| {
        b.iter(|| fit(black_box(&x), &y, FEATURE_COUNT, &FitParams::DEFAULT).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
