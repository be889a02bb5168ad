//! The reflective-shadow-map baseline (Dachsbacher and Stamminger 2005) at a given VPL count:
//! a regular grid of rays over each light's view, first hits become VPLs.
//!
//! Light `l` gets `n_l` of the `N` rays by largest remainder of `N * lum(P_l) / sum lum(P)`. Its
//! rays form a rank-1 (Fibonacci) lattice over `[0, 1)^2`, a regular grid with exactly `n_l`
//! points, mapped onto the light's view as a shadow map would be: the sphere (point), the cone
//! (spot), the cosine-weighted hemisphere from the centre (area) or a disk of parallel rays
//! covering the scene (sun). Each ray carries `P_l / n_l`; its first hit becomes a VPL of flux
//! `P_l / n_l * albedo`, like a texel of the map. Rays that leave the scene make no VPL (a
//! background texel), so an open scene gets fewer than `N`.

use glam::Vec3;
use std::f32::consts::PI;

use crate::error::Result;
use crate::layout::largest_remainder;
use crate::scene::{LightKind, Scene};
use crate::vpl::{light_powers, Vpl};

/// The golden ratio's fractional part, the generator of the Fibonacci lattice.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

fn basis(n: Vec3) -> (Vec3, Vec3) {
    let t = n.any_orthonormal_vector();
    (t, n.cross(t))
}

/// The ray of lattice point `(u, v)` of `light`'s view: `(origin, unit direction)`.
fn lattice_ray(light: &crate::scene::Light, scene: &Scene, u: f32, v: f32) -> (Vec3, Vec3) {
    let phi = 2.0 * PI * v;
    let (t, b) = basis(light.direction);
    match light.kind {
        LightKind::Point => {
            let z = 1.0 - 2.0 * u;
            let r = (1.0 - z * z).max(0.0).sqrt();
            (light.position, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        }
        LightKind::Spot { half_angle } => {
            let cos_t = 1.0 - u * (1.0 - half_angle.cos());
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let d = light.direction * cos_t + (t * phi.cos() + b * phi.sin()) * sin_t;
            (light.position, d.normalize())
        }
        LightKind::Area { .. } => {
            let r = u.sqrt();
            let d =
                light.direction * (1.0 - u).max(0.0).sqrt() + (t * phi.cos() + b * phi.sin()) * r;
            (light.position, d.normalize())
        }
        LightKind::Sun => {
            let (lo, hi) = scene.bounds();
            let centre = 0.5 * (lo + hi);
            let radius = 0.5 * scene.diagonal();
            let r = radius * u.sqrt();
            let origin =
                centre - light.direction * (2.0 * radius) + (t * phi.cos() + b * phi.sin()) * r;
            (origin, light.direction)
        }
    }
}

/// The RSM layout with `n` rays in all (see the module docs). Deterministic (no random numbers).
pub fn rsm_vpls(scene: &Scene, n: usize) -> Result<Vec<Vpl>> {
    let (powers, weights) = light_powers(scene, n)?;
    let weights: Vec<f64> = weights.into_iter().map(f64::from).collect();
    let counts = largest_remainder(&weights, n);
    let eps = scene.ray_epsilon();
    let offset = Vpl::SURFACE_OFFSET * scene.diagonal();
    let mut out = Vec::with_capacity(n);
    for ((light, power), &m) in scene.lights.iter().zip(&powers).zip(&counts) {
        if m == 0 {
            continue;
        }
        let per_ray = *power / m as f32;
        for i in 0..m {
            let u = ((i as f64 + 0.5) / m as f64) as f32;
            let v = ((i as f64 * GOLDEN).fract()) as f32;
            let (origin, dir) = lattice_ray(light, scene, u, v);
            if let Some(h) = scene.closest_hit(origin, dir, eps, f32::INFINITY) {
                let mut normal = scene.normal(h.triangle);
                if normal.dot(dir) > 0.0 {
                    normal = -normal;
                }
                out.push(Vpl {
                    position: origin + dir * h.t + normal * offset,
                    normal,
                    flux: per_ray * scene.albedo(h.triangle),
                });
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;
    use crate::test_util::closed_box;
    use crate::vpl::emitted_power;
    use crate::VplaceError;

    #[test]
    fn closed_box_gets_n_vpls_reflecting_albedo_times_power() {
        let lights = vec![
            Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.)),
            Light::area(
                Vec3::new(0., 0., 1.99),
                Vec3::NEG_Z,
                Vec3::X,
                true,
                0.3,
                0.0,
                Vec3::splat(4.),
            ),
            Light::spot(Vec3::new(0., 0., 1.9), Vec3::NEG_Z, 0.5, Vec3::splat(8.)),
        ];
        for n in [3, 10, 64, 257] {
            let s = closed_box(lights.clone());
            let v = rsm_vpls(&s, n).unwrap();
            assert_eq!(v.len(), n);
            assert_eq!(v, rsm_vpls(&s, n).unwrap());
            let total: Vec3 = v.iter().map(|v| v.flux).sum();
            if n < 64 {
                // Too few rays for the dim spot: it gets none and its light is lost.
                continue;
            }
            let expect: Vec3 = lights.iter().map(|l| emitted_power(l, &s) * 0.5).sum();
            assert!(
                (total - expect).abs().max_element() < 1e-3 * expect.max_element(),
                "{total} {expect}"
            );
        }
    }

    #[test]
    fn regular_grid_spreads_over_the_floor() {
        // A spot straight down: the lattice covers the lit disk evenly.
        let s = closed_box(vec![Light::spot(
            Vec3::new(0., 0., 1.9),
            Vec3::NEG_Z,
            0.4,
            Vec3::splat(8.),
        )]);
        let v = rsm_vpls(&s, 100).unwrap();
        let quads = [(1., 1.), (-1., 1.), (-1., -1.), (1., -1.)].map(|(sx, sy): (f32, f32)| {
            v.iter()
                .filter(|v| v.position.x * sx > 0.0 && v.position.y * sy > 0.0)
                .count()
        });
        assert!(quads.iter().all(|&q| (20..=30).contains(&q)), "{quads:?}");
    }

    #[test]
    fn errors() {
        assert!(rsm_vpls(&closed_box(vec![]), 4).is_err());
        let s = closed_box(vec![Light::point(Vec3::new(0., 0., 1.), Vec3::ONE)]);
        assert!(rsm_vpls(&s, 0).is_err());
        let s = closed_box(vec![Light::point(Vec3::new(0., 0., 1.), Vec3::ZERO)]);
        assert!(matches!(rsm_vpls(&s, 4), Err(VplaceError::Invalid { .. })));
    }
}
