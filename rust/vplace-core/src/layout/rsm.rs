//! The reflective-shadow-map baseline (Dachsbacher and Stamminger 2005) at a given VPL count:
//! a regular grid of rays over each light's view, first hits become VPLs.
//!
//! Light `l` gets `n_l` of the `N` rays by largest remainder of `N * lum(P_l) / sum lum(P)`. Its
//! rays form a rank-1 (Fibonacci) lattice over `[0, 1)^2`, a regular grid with exactly `n_l`
//! points, mapped onto the light's view as a shadow map would be: the sphere (point), the cone
//! (spot, its rays weighted by the blend), the cosine-weighted hemisphere from the centre (area;
//! with a spread, the spread's cone weighted by its attenuation) or a disk of parallel rays
//! covering the scene (sun). The world and the emissive triangles, which have no single view,
//! map the lattice through their emission sampler ([`sample_emission`], further dimensions from
//! more rank-1 steps). Each ray carries `P_l / n_l` times its weight; its first hit becomes a VPL
//! of flux `P_l / n_l * weight * albedo`, like a texel of the map. Rays that leave the scene make no VPL (a
//! background texel), so an open scene gets fewer than `N`.

use glam::Vec3;
use std::f32::consts::PI;

use crate::error::Result;
use crate::layout::largest_remainder;
use crate::scene::emitters::{
    area_direction, basis, sample_emission, spot_attenuation, EmissionRay, Emitter,
};
use crate::scene::{LightKind, Scene};
use crate::vpl::{light_powers, Vpl};

/// The golden ratio's fractional part, the generator of the Fibonacci lattice.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

/// Irrational steps of the lattice's further dimensions (a point's position on an area light,
/// a sun's or the world's disk, a triangle's side and direction).
const STEPS: [f64; 4] = [
    0.414_213_562_373_095,
    0.732_050_807_568_877,
    0.236_067_977_499_79,
    0.645_751_311_064_591,
];

/// The ray of lattice point `i` of `m` (coordinates `(u, v)`) of `emitter`'s view, its weight
/// the ray's flux over `P / m` (see [`sample_emission`]).
fn lattice_ray(emitter: Emitter<'_>, scene: &Scene, (u, v): (f32, f32), i: usize) -> EmissionRay {
    let phi = 2.0 * PI * v;
    let light = match emitter {
        Emitter::Light(l) if !matches!(l.kind, LightKind::World { .. }) => l,
        _ => {
            // The world and the emissive triangles: the emission sampler on the lattice.
            let mut k = 0;
            let mut next = || {
                k += 1;
                match k {
                    1 => u,
                    2 => v,
                    _ => ((i as f64 + 0.5) * STEPS[(k - 3) % STEPS.len()]).fract() as f32,
                }
            };
            return sample_emission(emitter, scene, &mut next);
        }
    };
    let ray = |origin, direction, weight| EmissionRay {
        origin,
        direction,
        weight,
        back: false,
    };
    let (t, b) = basis(light.direction);
    let one = Vec3::ONE;
    match &light.kind {
        LightKind::Point { .. } => {
            let z = 1.0 - 2.0 * u;
            let r = (1.0 - z * z).max(0.0).sqrt();
            ray(
                light.position,
                Vec3::new(r * phi.cos(), r * phi.sin(), z),
                one,
            )
        }
        LightKind::Spot {
            half_angle, blend, ..
        } => {
            let cos_t = 1.0 - u * (1.0 - half_angle.cos());
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let d = light.direction * cos_t + (t * phi.cos() + b * phi.sin()) * sin_t;
            let w = if *blend > 0.0 {
                spot_attenuation(cos_t, *half_angle, *blend) / (1.0 - 0.5 * blend)
            } else {
                1.0
            };
            ray(light.position, d.normalize(), Vec3::splat(w))
        }
        LightKind::Area { spread, .. } if *spread < PI => {
            let (d, w) = area_direction(light.direction, *spread, u, v);
            ray(light.position, d, Vec3::splat(w))
        }
        LightKind::Area { .. } => {
            let r = u.sqrt();
            let d =
                light.direction * (1.0 - u).max(0.0).sqrt() + (t * phi.cos() + b * phi.sin()) * r;
            ray(light.position, d.normalize(), one)
        }
        LightKind::Sun { .. } => {
            let (centre, radius, start) = scene.emission_sphere();
            let r = radius * u.sqrt();
            let origin = centre - light.direction * start + (t * phi.cos() + b * phi.sin()) * r;
            ray(origin, light.direction, one)
        }
        LightKind::World { .. } => unreachable!("handled above"),
    }
}

/// The RSM layout with `n` rays in all (see the module docs). Deterministic (no random numbers).
pub fn rsm_vpls(scene: &Scene, n: usize) -> Result<Vec<Vpl>> {
    let (powers, weights) = light_powers(scene, n)?;
    let weights: Vec<f64> = weights.into_iter().map(f64::from).collect();
    let counts = largest_remainder(&weights, n);
    let eps = scene.ray_epsilon();
    let offset = Vpl::SURFACE_OFFSET * scene.scale();
    let mut out = Vec::with_capacity(n);
    for ((emitter, power), &m) in scene.emitters().into_iter().zip(&powers).zip(&counts) {
        if m == 0 {
            continue;
        }
        let per_ray = *power / m as f32;
        for i in 0..m {
            let u = ((i as f64 + 0.5) / m as f64) as f32;
            let v = ((i as f64 * GOLDEN).fract()) as f32;
            let ray = lattice_ray(emitter, scene, (u, v), i);
            if ray.weight == Vec3::ZERO {
                continue;
            }
            let (origin, dir) = (ray.origin, ray.direction);
            let hit = scene.closest_hit(origin, dir, eps, f32::INFINITY);
            if let Some(h) = hit.filter(|h| !ray.trapped(scene, h.triangle)) {
                let mut normal = scene.normal(h.triangle);
                if normal.dot(dir) > 0.0 {
                    normal = -normal;
                }
                out.push(Vpl {
                    position: origin + dir * h.t + normal * offset,
                    normal,
                    flux: per_ray * ray.weight * scene.albedo_at(h.triangle, h.barycentrics),
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
    use crate::scene::{texture::AlphaTest, Material};
    use crate::test_util::{card_scene, closed_box, extend};
    use crate::vpl::emitted_power;
    use crate::vpl::uniform_vpls;
    use crate::VplaceError;
    use glam::Vec3;

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
    fn light_trapped_inside_a_closed_emitter_leaves_no_vpl() {
        // As for the light paths: the half of the cube's power its faces emit inward never
        // leaves it, so no VPL lies inside, and the rest reaches the box (albedo 0.5).
        let (s, c, h) = crate::test_util::emissive_cube_in_box();
        let v = rsm_vpls(&s, 4000).unwrap();
        crate::test_util::assert_none_inside(&v, c, h);
        let total: Vec3 = v.iter().map(|v| v.flux).sum();
        let want = s.emissive().power() * 0.5 * 0.5;
        assert!(
            (total - want).abs().max_element() < 0.03 * want.max_element(),
            "{total} {want}"
        );
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

    // Light paths and RSM rays through alpha-tested and textured materials (the scene stage
    // cuts and reads the texels; these are its callers).
    #[test]
    fn light_paths_pass_cut_texels_and_stop_at_opaque_ones() {
        let light = Light::point(Vec3::new(0.0, 0.0, 1.9), Vec3::splat(10.0));
        let card = Material {
            alpha_test: Some(AlphaTest::texture(extend(0))),
            ..Material::diffuse(Vec3::splat(0.5))
        };
        let s = card_scene(card, vec![light.clone()]);
        let opaque = card_scene(Material::diffuse(Vec3::splat(0.5)), vec![light]);
        let v = uniform_vpls(&s, 4000, 3).unwrap();
        let on_card = |v: &&Vpl| {
            (v.position.z - 1.0).abs() < 0.01
                && v.position.x.abs() < 0.5
                && v.position.y.abs() < 0.5
        };
        // Seen from the light, the card's point at x lies over the floor's point at x / 0.47:
        // the cut part (x < -0.25) shades nothing beyond x < -0.53 on the floor, the opaque
        // part (x > 0) shades the floor's x in (0, 1).
        let under = |v: &&Vpl, x0: f32, x1: f32| {
            v.position.z < 0.01 && (x0..x1).contains(&v.position.x) && v.position.y.abs() < 0.8
        };
        let (cut, opaque_half) = ((-0.95, -0.6), (0.05, 0.9));
        // No VPL on the cut half of the card; VPLs on its opaque half.
        assert_eq!(
            v.iter()
                .filter(on_card)
                .filter(|v| v.position.x < -0.25)
                .count(),
            0
        );
        assert!(
            v.iter()
                .filter(on_card)
                .filter(|v| v.position.x > 0.0)
                .count()
                > 100
        );
        // The floor under the cut half is lit through it; under the opaque half it is not.
        assert!(v.iter().filter(|v| under(v, cut.0, cut.1)).count() > 30);
        assert_eq!(
            v.iter()
                .filter(|v| under(v, opaque_half.0, opaque_half.1))
                .count(),
            0
        );
        // The opaque card shadows both halves.
        let w = uniform_vpls(&opaque, 4000, 3).unwrap();
        assert_eq!(w.iter().filter(|v| under(v, cut.0, cut.1)).count(), 0);
        // RSM rays too.
        let r = rsm_vpls(&s, 2000).unwrap();
        assert_eq!(
            r.iter()
                .filter(on_card)
                .filter(|v| v.position.x < -0.25)
                .count(),
            0
        );
        assert!(r.iter().filter(|v| under(v, cut.0, cut.1)).count() > 10);
        assert_eq!(
            r.iter()
                .filter(|v| under(v, opaque_half.0, opaque_half.1))
                .count(),
            0
        );
    }

    #[test]
    fn light_paths_reflect_the_textured_albedo() {
        // A textured floor under a point light: VPLs on the red half carry red flux only.
        let light = Light::point(Vec3::new(0.0, 0.0, 1.9), Vec3::splat(10.0));
        let s = card_scene(Material::textured(extend(0), Vec3::ONE), vec![light]);
        let v = uniform_vpls(&s, 3000, 8).unwrap();
        let card: Vec<_> = v
            .iter()
            .filter(|v| (v.position.z - 1.0).abs() < 0.01)
            .filter(|v| v.position.x.abs() < 0.5 && v.position.y.abs() < 0.5)
            .collect();
        assert!(card.len() > 100);
        for v in card {
            let u = v.position.x + 0.5;
            let g = ((u - 0.25) / 0.5).clamp(0.0, 1.0);
            let ratio = v.flux / v.flux.max_element();
            let expect = Vec3::new(1.0 - g, g, 0.0) / (1.0 - g).max(g);
            assert!(
                (ratio - expect).abs().max_element() < 1e-3,
                "{u}: {ratio} {expect}"
            );
        }
    }
}
