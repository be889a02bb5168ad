//! PAR 2D light maps: `par` and `exact` against Monte Carlo, and `exact`'s scaling with the
//! number of occluders. Scenes from `par2d::procedural::random_scene` (deterministic seeds).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec2;
use std::hint::black_box;
use vplace_core::par2d::{procedural::random_scene, Bounds2, Method};

const BOUNDS: Bounds2 = Bounds2 {
    min: DVec2::new(-1.0, -1.0),
    max: DVec2::new(1.0, 1.0),
};

fn methods(c: &mut Criterion) {
    let scene = random_scene(8, 64, 1).unwrap();
    let mut g = c.benchmark_group("par2d_light_map_128_8l_64o");
    g.sample_size(10);
    for (name, m) in [
        ("par", Method::Par),
        ("exact", Method::Exact),
        ("mc_64", Method::MonteCarlo { rays: 64, seed: 1 }),
    ] {
        g.bench_function(name, |b| {
            b.iter(|| black_box(scene.light_map(BOUNDS, 128, 128, m, None).unwrap()));
        });
    }
    g.finish();
}

fn scaling(c: &mut Criterion) {
    let mut g = c.benchmark_group("par2d_exact_128_by_occluders");
    g.sample_size(10);
    for n in [64usize, 256, 1024] {
        let scene = random_scene(8, n, 2).unwrap();
        g.bench_with_input(BenchmarkId::from_parameter(n), &scene, |b, s| {
            b.iter(|| black_box(s.light_map(BOUNDS, 128, 128, Method::Exact, None).unwrap()));
        });
    }
    g.finish();
}

criterion_group!(benches, methods, scaling);
criterion_main!(benches);
