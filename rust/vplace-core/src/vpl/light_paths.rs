//! Keller's light paths: rays from every emitter by power, a VPL at each surface hit, the path
//! continued in a cosine direction with Russian roulette ([`uniform_vpls`] first hits only,
//! [`light_path_vpls`] every bounce).

use glam::Vec3;

use crate::color::luminance;
use crate::error::{Result, VplaceError};
use crate::rng::Rng;
use crate::scene::emitters::{cosine_direction, emitter_power, light_power, sample_emission};
use crate::scene::{Light, Scene};
use crate::vpl::Vpl;

/// Total power a light emits into the scene (RGB watts; see [`crate::scene::emitters`]).
#[must_use]
pub fn emitted_power(light: &Light, scene: &Scene) -> Vec3 {
    light_power(light, scene)
}

/// Checks a budget of `n` VPLs against the scene's emitters ([`Scene::emitters`]) and returns
/// each emitter's power with its luminance (the weight emitters are chosen by); the weights sum
/// to more than 0.
pub(crate) fn light_powers(scene: &Scene, n: usize) -> Result<(Vec<Vec3>, Vec<f32>)> {
    if n == 0 {
        return Err(VplaceError::OutOfRange {
            what: "n".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    if !scene.has_emitters() {
        return Err(VplaceError::Empty {
            what: "scene lights".into(),
            hint: "add a light (point, spot, area, sun or world) or an emissive material".into(),
        });
    }
    let powers: Vec<Vec3> = scene
        .emitters()
        .into_iter()
        .map(|e| emitter_power(e, scene))
        .collect();
    let weights: Vec<f32> = powers.iter().map(|&p| luminance(p)).collect();
    let total: f32 = weights.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Err(VplaceError::Invalid {
            what: "scene lights".into(),
            reason: "every light has zero power (and nothing else emits)".into(),
        });
    }
    Ok((powers, weights))
}

/// At most this many emission rays per requested VPL before giving up (rays that leave the
/// scene make no VPL).
pub const MAX_RAYS_PER_VPL: usize = 1000;

/// Keller's instant radiosity, first bounce only: `light_path_vpls(scene, n, seed, 1)`.
pub fn uniform_vpls(scene: &Scene, n: usize, seed: u64) -> Result<Vec<Vpl>> {
    light_path_vpls(scene, n, seed, 1)
}

/// Bounce cap for [`light_path_vpls`] when all bounces are wanted; Russian roulette ends most
/// paths long before it.
pub const MAX_BOUNCES: usize = 16;

/// Keller's instant radiosity: traces light paths from the emitters (each chosen with
/// probability proportional to its emitted luminance; [`sample_emission`] draws the rays of
/// every kind, the world's and the sun's from a disk outside the scene's bounding sphere)
/// until `n` VPLs exist. A path leaves a VPL
/// at each of its first `bounces` surface hits; the VPL carries the flux the surface reflects,
/// `f * albedo / paths`, where `f` is the flux the path brings to that hit and `paths` counts
/// every emission ray traced, including those that escaped. After a hit the path goes on in a
/// cosine-distributed direction about the normal (the Lambertian reflection) with probability
/// `q = min(1, luminance(albedo))`, carrying `f * albedo / q` (Russian roulette): an unbiased
/// estimate of the flux reflected at each bounce. With `bounces = 1` these are the first hits
/// only. The last path may be cut short when the `n`-th VPL is made (a bias of at most one
/// path's later bounces). Deterministic for `seed`.
///
/// Errors: `n == 0` or `bounces == 0`, no lights or no power, or rays that miss the geometry
/// (see [`MAX_RAYS_PER_VPL`]).
pub fn light_path_vpls(scene: &Scene, n: usize, seed: u64, bounces: usize) -> Result<Vec<Vpl>> {
    let (powers, weights) = light_powers(scene, n)?;
    if bounces == 0 {
        return Err(VplaceError::OutOfRange {
            what: "bounces".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    let total: f32 = weights.iter().sum();
    let mut cdf = Vec::with_capacity(weights.len());
    let mut acc = 0.0;
    for w in &weights {
        acc += w / total;
        cdf.push(acc);
    }
    let eps = scene.ray_epsilon();
    let offset = Vpl::SURFACE_OFFSET * scene.diagonal();
    let emitters = scene.emitters();
    let mut rng = Rng::new(seed, 0x5eed);
    // (position, normal, reflected flux of one path before dividing by the path count)
    let mut hits: Vec<(Vec3, Vec3, Vec3)> = Vec::with_capacity(n);
    let mut rays = 0usize;
    while hits.len() < n {
        if rays >= n * MAX_RAYS_PER_VPL {
            return Err(VplaceError::Invalid {
                what: "uniform VPLs".into(),
                reason: format!(
                    "only {} of {rays} light rays hit the geometry: are the lights outside the scene or facing away from it?",
                    hits.len()
                ),
            });
        }
        rays += 1;
        let u = rng.next_f32();
        let li = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
        let ray = sample_emission(emitters[li], scene, &mut || rng.next_f32());
        let (mut origin, mut dir) = (ray.origin, ray.direction);
        let mut carried = powers[li] / (weights[li] / total) * ray.weight;
        for bounce in 0..bounces {
            let Some(h) = scene.closest_hit(origin, dir, eps, f32::INFINITY) else {
                break;
            };
            let mut normal = scene.normal(h.triangle);
            if normal.dot(dir) > 0.0 {
                normal = -normal;
            }
            let p = origin + dir * h.t + normal * offset;
            let reflected = carried * scene.albedo_at(h.triangle, h.barycentrics);
            hits.push((p, normal, reflected));
            if hits.len() == n || bounce + 1 == bounces {
                break;
            }
            let q = luminance(reflected) / luminance(carried).max(f32::MIN_POSITIVE);
            let q = q.clamp(0.0, 1.0);
            if q.is_nan() || q <= 0.0 || rng.next_f32() >= q {
                break;
            }
            carried = reflected / q;
            origin = p;
            dir = cosine_direction(normal, rng.next_f32(), rng.next_f32());
        }
    }
    let inv_rays = 1.0 / rays as f32;
    Ok(hits
        .into_iter()
        .map(|(position, normal, f)| Vpl {
            position,
            normal,
            flux: f * inv_rays,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::closed_box;

    #[test]
    fn deterministic_and_on_surfaces() {
        let s = closed_box(vec![Light::point(Vec3::new(0., 0., 1.), Vec3::splat(10.))]);
        let a = uniform_vpls(&s, 200, 3).unwrap();
        let b = uniform_vpls(&s, 200, 3).unwrap();
        let c = uniform_vpls(&s, 200, 4).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        for v in &a {
            let p = v.position;
            let inside = p.x.abs() < 1.0 && p.y.abs() < 1.0 && p.z > 0.0 && p.z < 2.0;
            assert!(inside, "{p:?}");
            assert!((v.normal.length() - 1.0).abs() < 1e-4);
            // The normal points into the box, where the light came from.
            assert!(v.normal.dot(Vec3::new(0., 0., 1.) - p) > 0.0);
        }
    }

    #[test]
    fn closed_box_reflects_albedo_times_power() {
        // Every ray hits a closed box: total VPL flux = albedo * P exactly.
        for light in [
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
        ] {
            let s = closed_box(vec![light.clone()]);
            let v = uniform_vpls(&s, 500, 1).unwrap();
            let total: Vec3 = v.iter().map(|v| v.flux).sum();
            let expect = emitted_power(&light, &s) * 0.5;
            assert!(
                (total - expect).abs().max_element() < 1e-3 * expect.max_element(),
                "{total} {expect}"
            );
        }
    }

    #[test]
    fn light_paths_reflect_every_bounce() {
        // A closed box of albedo 0.5: the expected flux reflected over bounces 1..=k is
        // P * (0.5 + 0.25 + ... + 0.5^k).
        let light = Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.));
        let s = closed_box(vec![light.clone()]);
        let p = emitted_power(&light, &s);
        for (bounces, expect) in [(2, 0.75), (MAX_BOUNCES, 1.0 - 0.5f32.powi(16))] {
            let v = light_path_vpls(&s, 20_000, 4, bounces).unwrap();
            assert_eq!(v.len(), 20_000);
            let total: Vec3 = v.iter().map(|v| v.flux).sum();
            let ratio = total / p;
            assert!(
                (ratio - Vec3::splat(expect)).abs().max_element() < 0.03,
                "{bounces}: {ratio}"
            );
        }
        assert_eq!(
            light_path_vpls(&s, 50, 2, 1).unwrap(),
            uniform_vpls(&s, 50, 2).unwrap()
        );
        assert!(light_path_vpls(&s, 50, 2, 0).is_err());
    }

    #[test]
    fn later_bounces_reach_what_the_light_does_not() {
        // A downward area light never lights the ceiling directly; its second bounce does.
        let s = closed_box(vec![Light::area(
            Vec3::new(0., 0., 1.99),
            Vec3::NEG_Z,
            Vec3::X,
            false,
            0.4,
            0.2,
            Vec3::splat(4.),
        )]);
        let v = light_path_vpls(&s, 2000, 9, MAX_BOUNCES).unwrap();
        let ceiling = v.iter().filter(|v| v.position.z > 1.98).count();
        assert!(ceiling > 20, "{ceiling}");
        assert!(v
            .iter()
            .all(|v| v.flux.min_element() >= 0.0 && v.flux.is_finite()));
    }

    #[test]
    fn area_light_rays_leave_the_front_side() {
        let s = closed_box(vec![Light::area(
            Vec3::new(0., 0., 1.99),
            Vec3::NEG_Z,
            Vec3::X,
            false,
            0.4,
            0.2,
            Vec3::splat(4.),
        )]);
        let v = uniform_vpls(&s, 300, 9).unwrap();
        // A downward cosine emitter never reaches the ceiling.
        assert!(v.iter().all(|v| v.position.z < 1.98));
    }

    #[test]
    fn errors() {
        let s = closed_box(vec![]);
        assert!(matches!(
            uniform_vpls(&s, 10, 0),
            Err(VplaceError::Empty { .. })
        ));
        let s = closed_box(vec![Light::point(Vec3::new(0., 0., 1.), Vec3::ZERO)]);
        assert!(matches!(
            uniform_vpls(&s, 10, 0),
            Err(VplaceError::Invalid { .. })
        ));
        let s = closed_box(vec![Light::point(Vec3::new(0., 0., 1.), Vec3::ONE)]);
        assert!(uniform_vpls(&s, 0, 0).is_err());
        // A light outside, pointing away: no ray hits; a clear error, not a hang.
        let s = closed_box(vec![Light::spot(
            Vec3::new(0., 0., 50.),
            Vec3::Z,
            0.1,
            Vec3::ONE,
        )]);
        assert!(matches!(
            uniform_vpls(&s, 2, 0),
            Err(VplaceError::Invalid { .. })
        ));
    }
}
