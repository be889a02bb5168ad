//! The three callers of the shading module on the test box with the blocker
//! (`vplace_core::test_util`): the evaluator's image, the refit's normal equations and solve,
//! and the layout's view efficiency. Deterministic VPLs (fixed-seed PCG32).
//!
//! Run: `cargo bench -p vplace-core --bench shading`. The whole layout with the Python
//! pipeline: `python -m vplace.bench_layout`.

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec3;
use std::hint::black_box;
use vplace_core::{
    layout::refit::{refit, RefitParams},
    layout::{view_efficiency, Emitter},
    rng::Rng,
    shade::evaluator::{evaluate, EvalParams},
    test_util::{box_with, inward_point, FloorView, BLOCKER},
    vpl::Vpl,
};

/// `n` VPLs on the ceiling and walls of the box, facing in.
fn vpls(n: usize, seed: u64) -> Vec<Vpl> {
    let mut rng = Rng::new(seed, 0);
    (0..n)
        .map(|_| {
            let (position, normal) = inward_point(&mut rng);
            let flux = Vec3::new(0.5 + rng.next_f32(), 0.8, 0.5 + rng.next_f32());
            Vpl {
                position,
                normal,
                flux,
            }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let scene = box_with(vec![], &[BLOCKER]);
    let floor = FloorView::new(128, Vec3::new(0.0, 0.0, 1.5), 10.0);
    let arrays = &floor.gbuffer;
    let g = arrays.gbuffer();
    let v = vpls(256, 1);
    let mut group = c.benchmark_group("shading_box_128x128_256_vpls");
    group.sample_size(10);
    group.bench_function("evaluate", |b| {
        b.iter(|| evaluate(&scene, black_box(&g), &v, &EvalParams::PREVIEW, None).unwrap())
    });
    let target = evaluate(&scene, &g, &vpls(256, 2), &EvalParams::PREVIEW, None)
        .unwrap()
        .0;
    let params = RefitParams {
        stride: 2,
        ..RefitParams::DEFAULT
    };
    let view = floor.view_with(Some(&target));
    group.bench_function("refit stride 2", |b| {
        b.iter(|| refit(&scene, black_box(&[&view]), &v, &params, None).unwrap())
    });
    let emitters: Vec<Emitter> = vpls(4096, 3)
        .into_iter()
        .map(|v| Emitter {
            position: v.position,
            normal: v.normal,
            flux: v.flux,
        })
        .collect();
    let refs: Vec<&Emitter> = emitters.iter().collect();
    let samples: Vec<(Vec3, Vec3, f32)> = (0..1024)
        .map(|p| {
            let q = 16 * p;
            let at = Vec3::from_slice(&arrays.position[3 * q..3 * q + 3]);
            (at, Vec3::Z, 0.5)
        })
        .collect();
    group.bench_function("view_efficiency 4096 emitters x 1024 samples", |b| {
        b.iter(|| view_efficiency(black_box(&refs), &samples, 0.03))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
