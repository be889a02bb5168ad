//! Keller's light paths: rays from every emitter by power, a VPL at each surface hit, the path
//! continued in a cosine direction with Russian roulette ([`uniform_vpls`] first hits only,
//! [`light_path_vpls`] every bounce).

use glam::Vec3;

use crate::color::luminance;
use crate::error::{Result, VplaceError};
use crate::rng::Rng;
use crate::scene::emitters::{
    cosine_direction, emitter_power, ggx_reflection, light_power, sample_emission,
};
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
/// paths long before it. (Defined with the scene's [`crate::scene::LightBounces`], which it
/// bounds.)
pub use crate::scene::MAX_BOUNCES;

/// Keller's instant radiosity: traces light paths from the emitters (each chosen with
/// probability proportional to its emitted luminance; [`sample_emission`] draws the rays of
/// every kind, the world's and the sun's from a disk outside the scene's bounding sphere)
/// until `n` VPLs exist. A path leaves a VPL
/// at each of its first `bounces` surface hits that are within the scene's
/// [`Scene::light_bounces`] (what the renderer it is scored against follows: a path that leaves
/// them ends); the VPL carries the flux the surface reflects,
/// `f * albedo / paths`, where `f` is the flux the path brings to that hit and `paths` counts
/// every emission ray traced, including those that escaped. The VPL is the diffuse part; where
/// the material has a glossy layer ([`Scene::gloss_at`]) its reflection goes on as the path,
/// not as a VPL. After a hit the path goes on with probability `q = min(1, luminance(albedo +
/// gloss))` (Russian roulette), off the diffuse part (a cosine-distributed direction about the
/// normal, carrying `f * albedo / (q p)`) or off the glossy layer (the mirror direction about a
/// GGX microfacet normal, kept above the surface, carrying `f * gloss / (q p)`), each picked with
/// `p` its share of the reflected luminance: an unbiased estimate of the flux reflected at each
/// bounce. With `bounces = 1` these are the first hits only. Light trapped inside a closed
/// emitter ([`crate::scene::emitters::EmissionRay::trapped`]) ends at its first hit: it counts
/// among the paths and leaves no VPL.
/// The last path may be cut short when the `n`-th VPL is made (a bias of at most one path's
/// later bounces). Deterministic for `seed`.
///
/// Errors: `n == 0` or `bounces == 0`, no lights or no power, or rays that miss the geometry
/// (see [`MAX_RAYS_PER_VPL`]).
pub fn light_path_vpls(scene: &Scene, n: usize, seed: u64, bounces: usize) -> Result<Vec<Vpl>> {
    Ok(light_path_hits(scene, n, seed, bounces)?
        .into_iter()
        .map(|h| h.vpl)
        .collect())
}

/// A hit of [`light_path_hits`]: its VPL and the flux that arrived there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightHit {
    /// The VPL the hit leaves ([`light_path_vpls`]; zero flux on a surface without a diffuse
    /// part).
    pub vpl: Vpl,
    /// The flux the path brought to the hit, RGB watts (over the paths, as the VPL's): the
    /// light the surface receives there, whatever it reflects.
    pub arriving: Vec3,
    /// The surface's diffuse albedo there (what the VPL reflects of `arriving`).
    pub albedo: Vec3,
    /// The reflectance of its glossy layer there (zero without one).
    pub gloss: Vec3,
    /// The path's surface hits before this one (0: the light came straight from an emitter).
    pub bounce: usize,
}

/// The hits of [`light_path_vpls`] (the same, in the same order, for the same arguments), each
/// with the flux that arrived there.
pub fn light_path_hits(
    scene: &Scene,
    n: usize,
    seed: u64,
    bounces: usize,
) -> Result<Vec<LightHit>> {
    let (powers, weights) = light_powers(scene, n)?;
    if bounces == 0 {
        return Err(VplaceError::OutOfRange {
            what: "bounces".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    let limits = scene.light_bounces();
    let bounces = bounces.min(limits.total);
    let total: f32 = weights.iter().sum();
    let mut cdf = Vec::with_capacity(weights.len());
    let mut acc = 0.0;
    for w in &weights {
        acc += w / total;
        cdf.push(acc);
    }
    let eps = scene.ray_epsilon();
    let offset = Vpl::SURFACE_OFFSET * scene.scale();
    let emitters = scene.emitters();
    let mut rng = Rng::new(seed, 0x5eed);
    // (position, normal, arriving flux of one path before dividing by the path count, albedo,
    // gloss, bounce)
    let mut hits: Vec<(Vec3, Vec3, Vec3, Vec3, Vec3, usize)> = Vec::with_capacity(n);
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
        // How the path went on at hits 2.. (diffusely, glossily): what `limits` counts.
        let (mut diffuse_between, mut glossy_between) = (0, 0);
        for bounce in 0..bounces {
            let Some(h) = scene.closest_hit(origin, dir, eps, f32::INFINITY) else {
                break;
            };
            if bounce == 0 && ray.trapped(scene, h.triangle) {
                break;
            }
            if !limits.admit(bounce + 1, diffuse_between, glossy_between) {
                break;
            }
            let mut normal = scene.normal(h.triangle);
            if normal.dot(dir) > 0.0 {
                normal = -normal;
            }
            let p = origin + dir * h.t + normal * offset;
            let albedo = scene.albedo_at(h.triangle, h.barycentrics);
            let (gloss, roughness) = scene
                .gloss_at(h.triangle, h.barycentrics)
                .unwrap_or((Vec3::ZERO, 1.0));
            hits.push((p, normal, carried, albedo, gloss, bounce));
            if hits.len() == n || bounce + 1 == bounces {
                break;
            }
            // The path goes on off the diffuse part or, where the material has one, off its
            // glossy layer, each chosen by its share of the reflected luminance.
            let (diffuse, glossy) = (luminance(carried * albedo), luminance(carried * gloss));
            // A path whose next hit is outside the limits either way ends here.
            let on = usize::from(bounce > 0);
            let next = bounce + 2;
            let by_diffuse =
                diffuse > 0.0 && limits.admit(next, diffuse_between + on, glossy_between);
            let by_glossy =
                glossy > 0.0 && limits.admit(next, diffuse_between, glossy_between + on);
            if !by_diffuse && !by_glossy {
                break;
            }
            let q = (diffuse + glossy) / luminance(carried).max(f32::MIN_POSITIVE);
            let q = q.clamp(0.0, 1.0);
            if q.is_nan() || q <= 0.0 || rng.next_f32() >= q {
                break;
            }
            // (A material without a glossy layer draws no number for the pick.)
            let pick_glossy = glossy > 0.0 && rng.next_f32() * (diffuse + glossy) < glossy;
            let (u1, u2) = (rng.next_f32(), rng.next_f32());
            if bounce > 0 {
                if pick_glossy {
                    glossy_between += 1;
                } else {
                    diffuse_between += 1;
                }
            }
            if pick_glossy {
                let alpha = (roughness * roughness).max(1e-3);
                carried = carried * gloss * ((diffuse + glossy) / (q * glossy));
                dir = ggx_reflection(dir, normal, alpha, u1, u2);
            } else {
                carried = carried * albedo * ((diffuse + glossy) / (q * diffuse));
                dir = cosine_direction(normal, u1, u2);
            }
            origin = p;
        }
    }
    let inv_rays = 1.0 / rays as f32;
    Ok(hits
        .into_iter()
        .map(|(position, normal, f, albedo, gloss, bounce)| LightHit {
            vpl: Vpl {
                position,
                normal,
                flux: f * albedo * inv_rays,
            },
            arriving: f * inv_rays,
            albedo,
            gloss,
            bounce,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LightBounces, Material, SceneInput};
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
    fn light_trapped_inside_a_closed_emitter_leaves_no_vpl() {
        // An emissive cube (normals out, as Blender's) in the box of albedo 0.5: half its
        // power leaves the outer faces and reaches the box; the half its faces emit inward
        // never leaves it. So every VPL lies outside the cube, and the first bounce carries
        // 0.5 x half the power (with the inward half as VPLs, 0.8 x the other half more).
        let (scene, c, h) = crate::test_util::emissive_cube_in_box();
        let vpls = light_path_vpls(&scene, 4000, 5, MAX_BOUNCES).unwrap();
        crate::test_util::assert_none_inside(&vpls, c, h);
        let first: Vec3 = uniform_vpls(&scene, 20_000, 5)
            .unwrap()
            .iter()
            .map(|v| v.flux)
            .sum();
        let want = scene.emissive().power() * 0.5 * 0.5;
        assert!(
            (first - want).abs().max_element() < 0.03 * want.max_element(),
            "{first} {want}"
        );
    }

    #[test]
    fn light_paths_go_on_off_the_glossy_layer() {
        // A closed box of albedo 0.3 with a glossy layer of 0.2, a mirror or a rough one (light
        // a microfacet bounce sends below the surface is kept): over two bounces the VPLs carry
        // 0.3 P + 0.3 (0.3 + 0.2) P = 0.45 P; the albedo alone would give 0.39 P. The first
        // bounce's VPLs carry the diffuse part only.
        let light = Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.));
        let build = |m: Material| crate::test_util::box_of(m, vec![light.clone()]);
        let diffuse = Material::diffuse(Vec3::splat(0.3));
        let total = |s: &Scene, bounces| -> Vec3 {
            let vpls = light_path_vpls(s, 40_000, 3, bounces).unwrap();
            vpls.iter().map(|v| v.flux).sum()
        };
        let power = emitted_power(&light, &build(diffuse));
        let mut cases = vec![(build(diffuse), 0.39)];
        for roughness in [0.0, 1.0] {
            let glossy = build(diffuse.with_gloss(Vec3::splat(0.2), Vec3::ZERO, roughness));
            let first = total(&glossy, 1);
            let want = power * 0.3;
            assert!((first - want).abs().max_element() < 1e-3 * want.max_element());
            cases.push((glossy, 0.45));
        }
        for (scene, share) in &cases {
            let got = total(scene, 2);
            let want = power * *share;
            assert!(
                (got - want).abs().max_element() < 0.02 * want.max_element(),
                "{got} {want}"
            );
        }
    }

    #[test]
    fn a_mirror_sends_the_path_on_in_the_mirror_direction() {
        // A spot over a mirror floor (albedo 0, a sharp glossy layer of 1) in the box of albedo
        // 0.5: the first hits are on the floor and carry nothing; the light they send on
        // leaves from the spot's mirror image (0, 0, -1.9) and lands on the ceiling (z = 2)
        // within 3.9 / 1.9 of the lit floor's radius. A diffuse floor would light the walls
        // too.
        let (v, t) = crate::test_util::box_geometry(&[]);
        let mut ids = vec![1; t.len()];
        ids[..2].fill(0); // the floor
        let mirror = Material::diffuse(Vec3::ZERO).with_gloss(Vec3::ONE, Vec3::ZERO, 0.0);
        let walls = Material::diffuse(Vec3::splat(0.5));
        let spot = Light::spot(Vec3::new(0., 0., 1.9), Vec3::NEG_Z, 0.15, Vec3::splat(10.));
        let s = Scene::new(SceneInput {
            vertices: &v,
            triangles: &t,
            material_ids: &ids,
            materials: &[mirror, walls],
            lights: vec![spot],
            ..Default::default()
        })
        .unwrap();
        let first = light_path_vpls(&s, 2_000, 5, 1).unwrap();
        let lit = first
            .iter()
            .map(|v| v.position.truncate().length())
            .fold(0.0f32, f32::max);
        assert!(first
            .iter()
            .all(|v| v.flux == Vec3::ZERO && v.position.z < 0.1));
        let second: Vec<_> = light_path_vpls(&s, 4_000, 5, 2)
            .unwrap()
            .into_iter()
            .filter(|v| v.flux.max_element() > 0.0)
            .collect();
        assert!(second.len() > 1_000, "{}", second.len());
        // GGX's long tail sends a few a little wider, even at the smallest width.
        let reach = lit * 3.9 / 1.9 * 1.02 + 1e-3;
        let inside = second
            .iter()
            .filter(|v| v.position.z > 1.9 && v.position.truncate().length() <= reach)
            .count();
        assert!(
            inside as f32 > 0.98 * second.len() as f32,
            "{inside} of {}",
            second.len()
        );
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
    fn light_paths_stop_at_the_scenes_bounce_limit() {
        // The scene's renderer follows 3 diffuse reflections: asking for every bounce gives
        // bounces 1..=3 (P * (0.5 + 0.25 + 0.125) in a closed diffuse box of albedo 0.5), the
        // same paths as asking for 3; fewer stay fewer. Without limits, every bounce (the test
        // above).
        let light = Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.));
        let diffuse = |d: usize| LightBounces {
            diffuse: d,
            ..LightBounces::ALL
        };
        let s = closed_box(vec![light.clone()])
            .with_light_bounces(diffuse(3))
            .unwrap();
        assert_eq!(s.light_bounces(), diffuse(3));
        let p = emitted_power(&light, &s);
        let every = light_path_vpls(&s, 20_000, 4, MAX_BOUNCES).unwrap();
        let total: Vec3 = every.iter().map(|v| v.flux).sum();
        assert!(
            (total / p - Vec3::splat(0.875)).abs().max_element() < 0.03,
            "{}",
            total / p
        );
        assert_eq!(every, light_path_vpls(&s, 20_000, 4, 3).unwrap());
        let two: Vec3 = light_path_vpls(&s, 20_000, 4, 2)
            .unwrap()
            .iter()
            .map(|v| v.flux)
            .sum();
        assert!((two / p - Vec3::splat(0.75)).abs().max_element() < 0.03);
        // The total caps it too.
        let s1 = closed_box(vec![light.clone()])
            .with_light_bounces(LightBounces {
                total: 1,
                ..LightBounces::ALL
            })
            .unwrap();
        assert_eq!(
            light_path_vpls(&s1, 500, 4, MAX_BOUNCES).unwrap(),
            uniform_vpls(&s1, 500, 4).unwrap()
        );
        assert_eq!(
            closed_box(vec![light.clone()]).light_bounces(),
            LightBounces::ALL
        );
        for bad in [
            diffuse(0),
            diffuse(MAX_BOUNCES + 1),
            LightBounces {
                glossy: MAX_BOUNCES + 1,
                ..LightBounces::ALL
            },
            LightBounces {
                total: 0,
                ..LightBounces::ALL
            },
        ] {
            assert!(closed_box(vec![light.clone()])
                .with_light_bounces(bad)
                .is_err());
        }
    }

    #[test]
    fn glossy_reflections_count_apart_from_diffuse_ones() {
        // A camera path that reflects glossily between the VPL and the first hit spends a
        // glossy bounce, not a diffuse one (Cycles counts them apart): with Diffuse 2, a VPL
        // at the third hit is within the limits when the path went on glossily at the second.
        let b = LightBounces {
            diffuse: 2,
            glossy: 1,
            total: 12,
        };
        assert!(b.admit(1, 0, 0) && b.admit(2, 0, 0));
        assert!(!b.admit(3, 1, 0), "a third diffuse reflection");
        assert!(b.admit(3, 0, 1), "a glossy reflection at hit 2");
        assert!(!b.admit(4, 0, 2), "a second glossy one");
        assert!(!b.admit(0, 0, 0));
        assert!(!LightBounces { total: 2, ..b }.admit(3, 0, 1));
        // In a closed box of albedo 0.3 with a glossy layer of 0.2 and Diffuse 2, the VPLs
        // carry 0.3 P at hit 1, 0.3 x 0.5 P at hit 2 (the first hit reflects either way) and,
        // with glossy bounces, 0.3 x 0.5 x 0.2^(k-2) P at hit k >= 3 (the path went on
        // glossily at every hit between): 0.4875 P in all, against 0.45 P without.
        let light = Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.));
        let material =
            Material::diffuse(Vec3::splat(0.3)).with_gloss(Vec3::splat(0.2), Vec3::ZERO, 0.5);
        let total = |glossy: usize| -> Vec3 {
            let s = crate::test_util::box_of(material, vec![light.clone()])
                .with_light_bounces(LightBounces { glossy, ..b })
                .unwrap();
            let p = emitted_power(&light, &s);
            let vpls = light_path_vpls(&s, 40_000, 3, MAX_BOUNCES).unwrap();
            vpls.iter().map(|v| v.flux).sum::<Vec3>() / p
        };
        for (glossy, want) in [(0, 0.45), (4, 0.4875)] {
            let got = total(glossy);
            assert!(
                (got - Vec3::splat(want)).abs().max_element() < 0.02 * want,
                "{glossy}: {got} {want}"
            );
        }
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
