//! Procedural 2D scenes for tests, benches and examples: random convex n-gons in `[-1, 1]^2`.

use std::f64::consts::TAU;

use glam::DVec2;

use super::Scene2d;
use crate::error::Result;
use crate::rng::Rng;

/// A random scene in the square `[-1, 1]^2`: `lights` regular n-gons of radius 0.03 to 0.08
/// with RGB emission in `[0.5, 2)`, then `occluders` n-gons (3 to 8 sides) of radius 0.01 to
/// `0.6 / sqrt(occluders)` that may overlap each other and the lights. Deterministic per
/// `seed`. Errors with [`VplaceError::Empty`](crate::VplaceError::Empty) when
/// `lights + occluders == 0`.
pub fn random_scene(lights: usize, occluders: usize, seed: u64) -> Result<Scene2d> {
    let mut rng = Rng::new(seed, 0x2d);
    let mut u = move || f64::from(rng.next_f32());
    let mut polys = Vec::with_capacity(lights + occluders);
    let mut emission = Vec::with_capacity(lights + occluders);
    let max_r = 0.6 / (occluders.max(1) as f64).sqrt();
    for k in 0..lights + occluders {
        let light = k < lights;
        let c = DVec2::new(1.8 * u() - 0.9, 1.8 * u() - 0.9);
        let r = if light {
            0.03 + 0.05 * u()
        } else {
            0.01 + (max_r - 0.01).max(0.0) * u()
        };
        let n = 3 + (u() * 6.0) as usize;
        let rot = TAU * u();
        polys.push(
            (0..n)
                .map(|i| c + r * DVec2::from_angle(rot + TAU * i as f64 / n as f64))
                .collect::<Vec<_>>(),
        );
        emission.push(if light {
            [0.5 + 1.5 * u(), 0.5 + 1.5 * u(), 0.5 + 1.5 * u()]
        } else {
            [0.0; 3]
        });
    }
    Scene2d::build(&polys, &emission)
}
