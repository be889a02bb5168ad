//! The VPL evaluator: the indirect image of a VPL set over a captured G-buffer.
//!
//! Every covered pixel gets the sum over the VPLs of the shading term of [`crate::shade::shading`]
//! (`rho / pi * Phi * I(cos_e) * max(0, n . l) * F(r) * V`, `V` an any-hit shadow ray through the
//! scene BVH). This module is the scheduling: square pixel tiles run in parallel with rayon,
//! each with one traversal state reused by its shadow rays; each tile polls the cancel flag of
//! [`Progress`] and counts its rays. The layout iterations answer rays from the previous
//! evaluation's cache (`shadow_cache.rs`).

use glam::Vec3;
use obvhs::{cwbvh::Traversal, ray::Ray};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use crate::error::{check_finite, Result, VplaceError};
use crate::progress::Progress;
use crate::scene::{Scene, NO_HINT};
use crate::shade::shading::{Batch, Receiver, VplSoa};
use crate::shade::shadow_cache::{self, ShadowCache};
use crate::view::GBuffer;
use crate::vpl::{near_field_radii, Profile, Vpl};

/// Evaluator settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalParams {
    /// How VPLs radiate.
    pub profile: Profile,
    /// The set's near-field radius (metres), the smallest disk radius of a cosine VPL: each VPL's
    /// own is [`crate::vpl::near_field_radii`], between this and `MAX_RADIUS_FACTOR` times it.
    /// Must be `>= 0`; 0 makes every VPL a point (use only to compare with an unclamped
    /// renderer).
    pub radius: f32,
    /// Side of the square pixel tiles scheduled on the thread pool.
    pub tile: usize,
}

impl EvalParams {
    /// Preview quality: cosine profile, 1 cm clamp, 16-pixel tiles.
    pub const PREVIEW: Self = Self {
        profile: Profile::Cosine,
        radius: 0.01,
        tile: 16,
    };
}

impl Default for EvalParams {
    fn default() -> Self {
        Self::PREVIEW
    }
}

/// What an evaluation cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EvalStats {
    /// Shadow rays traced (pixel-VPL pairs with a non-zero unshadowed contribution).
    pub shadow_rays: u64,
    /// Pixel-VPL pairs considered.
    pub pairs: u64,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl EvalStats {
    /// Shadow rays per second.
    #[must_use]
    pub fn rays_per_second(&self) -> f64 {
        self.shadow_rays as f64 / self.seconds.max(1e-9)
    }
}

/// Checks a VPL list: finite, unit normals, non-negative flux.
pub fn validate_vpls(vpls: &[Vpl]) -> Result<()> {
    for (i, v) in vpls.iter().enumerate() {
        let flat = [
            v.position.to_array(),
            v.normal.to_array(),
            v.flux.to_array(),
        ]
        .concat();
        check_finite(&format!("vpls[{i}]"), &flat)?;
        if (v.normal.length() - 1.0).abs() > 1e-3 {
            return Err(VplaceError::Invalid {
                what: format!("vpls[{i}].normal"),
                reason: "must be unit length".into(),
            });
        }
        if v.flux.min_element() < 0.0 {
            return Err(VplaceError::OutOfRange {
                what: format!("vpls[{i}].flux"),
                value: format!("{:?}", v.flux.to_array()),
                expected: ">= 0 in every channel".into(),
            });
        }
    }
    Ok(())
}

/// Checks the distance clamp `radius`: finite and `>= 0`.
pub(crate) fn check_radius(radius: f32) -> Result<()> {
    if radius >= 0.0 && radius.is_finite() {
        Ok(())
    } else {
        Err(VplaceError::OutOfRange {
            what: "radius".into(),
            value: radius.to_string(),
            expected: ">= 0 and finite".into(),
        })
    }
}

/// Checks near-field radii given per VPL ([`evaluate_with_radii`]): one for each of `n` VPLs,
/// each finite and `>= 0`.
pub fn check_radii(radii: &[f32], n: usize) -> Result<()> {
    if radii.len() != n {
        return Err(VplaceError::Invalid {
            what: "radii".into(),
            reason: format!("{} radii for {n} VPLs", radii.len()),
        });
    }
    match radii.iter().position(|r| !(*r >= 0.0 && r.is_finite())) {
        Some(j) => Err(VplaceError::OutOfRange {
            what: format!("radii[{j}]"),
            value: radii[j].to_string(),
            expected: ">= 0 and finite".into(),
        }),
        None => Ok(()),
    }
}

/// Renders the indirect radiance of `vpls` at every covered pixel of `gbuffer` (`H x W x 3`).
pub fn evaluate(
    scene: &Scene,
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    params: &EvalParams,
    progress: Option<&Progress>,
) -> Result<(Vec<f32>, EvalStats)> {
    evaluate_with(
        scene,
        gbuffer,
        vpls,
        None,
        params,
        progress,
        None,
        |state, ray, hint| scene.occluded_ray_hinted(state, ray, hint),
    )
}

/// [`evaluate`] (or, with `brute_force`, [`evaluate_brute_force`]) with each VPL's near-field
/// radius given, `radii[j]` for VPL `j` (finite, `>= 0`), instead of computed from the set's
/// spacing ([`crate::vpl::near_field_radii`]). For lights whose disk sizes are not those of
/// their own set: keyed lights between two captured frames, whose sizes Blender interpolates
/// from each frame's set (`vplace.temporal.at_frame`). `params.radius` is still checked but
/// not used.
pub fn evaluate_with_radii(
    scene: &Scene,
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    radii: &[f32],
    params: &EvalParams,
    progress: Option<&Progress>,
    brute_force: bool,
) -> Result<(Vec<f32>, EvalStats)> {
    evaluate_with(
        scene,
        gbuffer,
        vpls,
        Some(radii),
        params,
        progress,
        None,
        |state, ray, hint| {
            if brute_force {
                scene.occluded_ray_brute_force(ray)
            } else {
                scene.occluded_ray_hinted(state, ray, hint)
            }
        },
    )
}

/// [`evaluate`] with shadow rays that test every triangle instead of the BVH
/// ([`Scene::occluded_brute_force`]): the same image, a baseline for benchmarks.
pub fn evaluate_brute_force(
    scene: &Scene,
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    params: &EvalParams,
    progress: Option<&Progress>,
) -> Result<(Vec<f32>, EvalStats)> {
    evaluate_with(
        scene,
        gbuffer,
        vpls,
        None,
        params,
        progress,
        None,
        |_, ray, _| scene.occluded_ray_brute_force(ray),
    )
}

/// [`evaluate`] that answers the shadow rays of VPLs already evaluated at the same positions from
/// `cache` and stores this evaluation's answers there. `stats.shadow_rays` counts the rays traced;
/// `cache.reused` the pairs answered from the cache.
pub(crate) fn evaluate_cached(
    scene: &Scene,
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    params: &EvalParams,
    progress: Option<&Progress>,
    cache: &mut ShadowCache,
) -> Result<(Vec<f32>, EvalStats)> {
    evaluate_with(
        scene,
        gbuffer,
        vpls,
        None,
        params,
        progress,
        Some(cache),
        |state, ray, hint| scene.occluded_ray_hinted(state, ray, hint),
    )
}

/// What one tile of [`evaluate_with`] hands back: `(pixel, radiance)` of its covered pixels,
/// and per pixel its `known` then its `visible` shadow-cache words.
type Tile = (Vec<(usize, Vec3)>, Vec<u64>);

/// The argument checks of [`evaluate_with`].
fn check_eval_input(
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    radii: Option<&[f32]>,
    params: &EvalParams,
) -> Result<()> {
    gbuffer.validate()?;
    validate_vpls(vpls)?;
    check_radius(params.radius)?;
    if let Some(radii) = radii {
        check_radii(radii, vpls.len())?;
    }
    if params.tile == 0 {
        return Err(VplaceError::OutOfRange {
            what: "tile".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    Ok(())
}

/// The image (`H x W x 3`) and the shadow-cache bit rows (`known`, `visible`) of the tiles.
fn assemble(
    results: Vec<Option<Tile>>,
    w: usize,
    h: usize,
    words: usize,
) -> (Vec<f32>, Vec<u64>, Vec<u64>) {
    let mut image = vec![0.0f32; w * h * 3];
    let (mut known, mut visible) = (vec![0u64; w * h * words], vec![0u64; w * h * words]);
    for (tile, bits) in results.into_iter().flatten() {
        for (i, (p, c)) in tile.into_iter().enumerate() {
            image[3 * p..3 * p + 3].copy_from_slice(&c.to_array());
            if words > 0 {
                let row = &bits[2 * words * i..2 * words * (i + 1)];
                known[words * p..words * (p + 1)].copy_from_slice(&row[..words]);
                visible[words * p..words * (p + 1)].copy_from_slice(&row[words..]);
            }
        }
    }
    (image, known, visible)
}

/// The evaluation: tiles of pixels in parallel, each pixel shaded by every VPL through the
/// shading module with one traversal state per tile; `occluded` answers a shadow ray with it.
/// `radii`: each VPL's near-field radius, else those of the set's spacing.
#[allow(clippy::too_many_arguments)]
fn evaluate_with(
    scene: &Scene,
    gbuffer: &GBuffer,
    vpls: &[Vpl],
    radii: Option<&[f32]>,
    params: &EvalParams,
    progress: Option<&Progress>,
    cache: Option<&mut ShadowCache>,
    occluded: impl Fn(&mut Traversal, &Ray, &mut u32) -> bool + Sync,
) -> Result<(Vec<f32>, EvalStats)> {
    check_eval_input(gbuffer, vpls, radii, params)?;
    let start = Instant::now();
    let (w, h, t) = (gbuffer.width, gbuffer.height, params.tile);
    let tiles: Vec<(usize, usize)> = (0..h.div_ceil(t))
        .flat_map(|ty| (0..w.div_ceil(t)).map(move |tx| (tx * t, ty * t)))
        .collect();
    if let Some(p) = progress {
        p.total.store(tiles.len(), Ordering::Relaxed);
        p.done.store(0, Ordering::Relaxed);
    }
    let soa = match radii {
        Some(radii) => VplSoa::new(vpls, radii),
        None => VplSoa::new(vpls, &near_field_radii(vpls, params.radius)),
    };
    // With a cache: the answers it holds for these VPLs, and the size of this evaluation's bit
    // rows (per pixel, `known` then `visible`).
    let reuse = cache.as_deref().and_then(|c| c.reuse(vpls, w, h));
    let words = if cache.is_some() {
        shadow_cache::words_for(vpls.len())
    } else {
        0
    };
    let rays = AtomicU64::new(0);
    let reused = AtomicU64::new(0);
    let eps = scene.ray_epsilon();
    let cancelled = || progress.is_some_and(|p| p.cancel.load(Ordering::Relaxed));
    let results: Vec<Option<Tile>> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            if cancelled() {
                return None;
            }
            let mut out = Vec::with_capacity(t * t);
            // Per pixel of `out`: its `known` then its `visible` words.
            let mut bits = Vec::with_capacity(2 * words * t * t);
            let mut tile_rays = 0u64;
            let mut tile_reused = 0u64;
            let mut state = scene.shadow_state();
            let mut batch = Batch::new(soa.len());
            // Per VPL, the triangle that last blocked its ray in this tile.
            let mut hints = vec![NO_HINT; soa.len()];
            for y in y0..(y0 + t).min(h) {
                for x in x0..(x0 + t).min(w) {
                    let p = y * w + x;
                    if !gbuffer.covered[p] {
                        continue;
                    }
                    let recv = Receiver::of_pixel(gbuffer, p, eps);
                    batch.prepare(&soa, &recv, params.profile);
                    let row = bits.len();
                    bits.resize(row + 2 * words, 0);
                    let (known, visible) = bits[row..].split_at_mut(words);
                    let mut sum = Vec3::ZERO;
                    for (j, c) in batch.unshadowed(&soa) {
                        let lit = if let Some(lit) = reuse.as_ref().and_then(|r| r.lookup(p, j)) {
                            tile_reused += 1;
                            lit
                        } else {
                            tile_rays += 1;
                            !batch.occluded(j, |ray| occluded(&mut state, ray, &mut hints[j]))
                        };
                        if words > 0 {
                            shadow_cache::record(known, visible, j, lit);
                        }
                        if lit {
                            sum += c;
                        }
                    }
                    out.push((p, recv.brdf * sum));
                }
            }
            rays.fetch_add(tile_rays, Ordering::Relaxed);
            reused.fetch_add(tile_reused, Ordering::Relaxed);
            if let Some(pr) = progress {
                pr.done.fetch_add(1, Ordering::Relaxed);
            }
            Some((out, bits))
        })
        .collect();
    if cancelled() {
        return Err(VplaceError::Cancelled);
    }
    let (image, known, visible) = assemble(results, w, h, words);
    if let Some(cache) = cache {
        *cache = ShadowCache::new(vpls, w, h, known, visible, reused.into_inner());
    }
    let covered = gbuffer.covered.iter().filter(|&&c| c).count() as u64;
    Ok((
        image,
        EvalStats {
            shadow_rays: rays.into_inner(),
            pairs: covered * vpls.len() as u64,
            seconds: start.elapsed().as_secs_f64(),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{
        box_with, closed_box, floor_gbuffer, inward_point, reference_image, reference_incident,
        shading_cases, BLOCKER,
    };
    use std::f32::consts::PI;

    /// The arrays of [`floor_gbuffer`]: position, normal, albedo, covered.
    fn floor(w: usize) -> (Vec<f32>, Vec<f32>, Vec<f32>, Vec<bool>) {
        let g = floor_gbuffer(w);
        (g.position, g.normal, g.albedo, g.covered)
    }

    #[test]
    fn single_vpl_matches_the_formula() {
        let scene = closed_box(vec![]);
        let (pos, normal, albedo, covered) = floor(8);
        let g = GBuffer {
            width: 8,
            height: 8,
            position: &pos,
            normal: &normal,
            albedo: &albedo,
            covered: &covered,
        };
        let vpl = Vpl {
            position: Vec3::new(0.0, 0.0, 1.5),
            normal: Vec3::NEG_Z,
            flux: Vec3::new(1.0, 2.0, 3.0),
        };
        for profile in [Profile::Cosine, Profile::Omni] {
            let params = EvalParams {
                profile,
                radius: 0.0,
                tile: 3,
            };
            let (img, stats) = evaluate(&scene, &g, &[vpl], &params, None).unwrap();
            assert_eq!(stats.shadow_rays, 64);
            for p in 0..64 {
                let x = Vec3::new(pos[3 * p], pos[3 * p + 1], 0.0);
                let d = vpl.position - x;
                let r2 = d.length_squared();
                let cos = d.z / r2.sqrt();
                let i = match profile {
                    Profile::Cosine => cos / PI,
                    Profile::Omni => 0.5 / PI,
                };
                let expect = 0.5 / PI * vpl.flux * i * cos / r2;
                let got = Vec3::from_slice(&img[3 * p..3 * p + 3]);
                assert!(
                    (got - expect).abs().max_element() < 1e-6 * expect.max_element().max(1.0),
                    "{got} {expect}"
                );
            }
        }
    }

    #[test]
    fn shadows_back_faces_near_field_and_cancel() {
        let scene = closed_box(vec![]);
        let (pos, normal, albedo, covered) = floor(4);
        let g = GBuffer {
            width: 4,
            height: 4,
            position: &pos,
            normal: &normal,
            albedo: &albedo,
            covered: &covered,
        };
        // Above the ceiling: occluded everywhere.
        let above = Vpl {
            position: Vec3::new(0.0, 0.0, 2.5),
            normal: Vec3::NEG_Z,
            flux: Vec3::ONE,
        };
        let (img, _) = evaluate(&scene, &g, &[above], &EvalParams::PREVIEW, None).unwrap();
        assert!(img.iter().all(|&v| v == 0.0));
        let (img, _) =
            evaluate_brute_force(&scene, &g, &[above], &EvalParams::PREVIEW, None).unwrap();
        assert!(img.iter().all(|&v| v == 0.0));
        let inside = Vpl {
            position: Vec3::new(0.3, 0.1, 1.2),
            normal: Vec3::NEG_Z,
            flux: Vec3::ONE,
        };
        let (a, sa) = evaluate(&scene, &g, &[inside], &EvalParams::PREVIEW, None).unwrap();
        let (b, sb) =
            evaluate_brute_force(&scene, &g, &[inside], &EvalParams::PREVIEW, None).unwrap();
        assert_eq!(a, b);
        assert_eq!(sa.shadow_rays, sb.shadow_rays);
        assert!(a.iter().any(|&v| v > 0.0));
        // Facing up (away from the floor): the cosine profile gives nothing, no ray traced.
        let up = Vpl {
            position: Vec3::new(0.0, 0.0, 1.0),
            normal: Vec3::Z,
            flux: Vec3::ONE,
        };
        let (img, stats) = evaluate(&scene, &g, &[up], &EvalParams::PREVIEW, None).unwrap();
        assert!(img.iter().all(|&v| v == 0.0));
        assert_eq!(stats.shadow_rays, 0);
        // The disk of a cosine VPL sitting on a receiver bounds its light: at most
        // `albedo / pi / (pi R^2)` per unit flux, reached on the axis.
        let near = Vpl {
            position: Vec3::new(pos[0], pos[1], 1e-4),
            normal: Vec3::NEG_Z,
            flux: Vec3::ONE,
        };
        let params = EvalParams {
            profile: Profile::Cosine,
            radius: 0.1,
            tile: 16,
        };
        let (img, _) = evaluate(&scene, &g, &[near], &params, None).unwrap();
        let bound = 0.5 / PI / (PI * 0.01);
        assert!(
            img[0] <= bound * (1.0 + 1e-5) && img[0] > 0.99 * bound,
            "{}",
            img[0]
        );
        let progress = Progress::default();
        progress.cancel.store(true, Ordering::Relaxed);
        assert_eq!(
            evaluate(&scene, &g, &[up], &EvalParams::PREVIEW, Some(&progress)).unwrap_err(),
            VplaceError::Cancelled
        );
    }

    /// The evaluator's image is bit for bit the brute-force reference's (a plain scalar loop
    /// over pixels x VPLs with shadow rays against every triangle), and it traces one ray per
    /// pair the reference traces, on the degenerate cases of [`shading_cases`]: zero and short
    /// normals, a VPL at a receiver (`r = 0`), VPLs behind receivers, receivers behind a cosine
    /// VPL, a VPL without flux, pairs blocked by the blocker. With and without the shadow
    /// cache, for both profiles and several near-field radii.
    #[test]
    fn evaluate_matches_the_brute_force_reference() {
        let (scene, arrays, vpls) = shading_cases();
        let g = arrays.gbuffer();
        let (mut any_blocked, mut any_r0) = (false, false);
        for profile in [Profile::Cosine, Profile::Omni] {
            for radius in [0.0, 0.05, 0.4] {
                let (expect, rays) = reference_image(&scene, &g, &vpls, profile, radius);
                for tile in [1, 5, 16] {
                    let params = EvalParams {
                        profile,
                        radius,
                        tile,
                    };
                    let (img, stats) = evaluate(&scene, &g, &vpls, &params, None).unwrap();
                    assert_eq!(img, expect, "{profile:?} radius {radius} tile {tile}");
                    assert_eq!(stats.shadow_rays, rays);
                    let mut cache = ShadowCache::default();
                    for _ in 0..2 {
                        let (img, stats) =
                            evaluate_cached(&scene, &g, &vpls, &params, None, &mut cache).unwrap();
                        assert_eq!(img, expect);
                        assert_eq!(stats.shadow_rays + cache.reused, rays);
                    }
                    assert_eq!(cache.reused, rays);
                }
                // The cases are really there: blocked pairs, and a pair at r = 0.
                for p in (0..144).filter(|&p| g.covered[p]) {
                    let x = GBuffer::vec3(g.position, p);
                    let n = GBuffer::vec3(g.normal, p).normalize_or_zero();
                    for v in &vpls {
                        let shadowed = reference_incident(Some(&scene), x, n, v, profile, radius);
                        let open = reference_incident(None, x, n, v, profile, radius);
                        any_blocked |= shadowed != open;
                        any_r0 |= v.position == x;
                    }
                }
            }
        }
        assert!(any_blocked && any_r0);
        // Every pixel with a normal and at least one facing VPL is lit; the zero normal is dark.
        let (img, _) = evaluate(&scene, &g, &vpls, &EvalParams::PREVIEW, None).unwrap();
        assert_eq!(&img[3 * 14..3 * 14 + 3], &[0.0; 3]);
        assert!(img[3 * 27] > 0.0 && img[3 * 40] > 0.0);
    }

    #[test]
    fn given_radii_shade_each_vpl_with_its_own_disk() {
        let (scene, arrays, vpls) = shading_cases();
        let g = arrays.gbuffer();
        let params = EvalParams {
            radius: 0.05,
            ..EvalParams::PREVIEW
        };
        // The spacing's own radii given: the same image, with the BVH and brute force.
        let spacing = near_field_radii(&vpls, params.radius);
        let (expect, _) = evaluate(&scene, &g, &vpls, &params, None).unwrap();
        for brute in [false, true] {
            let (img, _) =
                evaluate_with_radii(&scene, &g, &vpls, &spacing, &params, None, brute).unwrap();
            assert_eq!(img, expect, "brute force {brute}");
        }
        // Other radii: each VPL's disk as given, not `params.radius`'s (against the reference
        // of the set at that radius).
        for r in [0.0f32, 0.4] {
            let radii = near_field_radii(&vpls, r);
            let (img, _) =
                evaluate_with_radii(&scene, &g, &vpls, &radii, &params, None, false).unwrap();
            let (want, _) = reference_image(&scene, &g, &vpls, Profile::Cosine, r);
            assert_eq!(img, want, "radius {r}");
        }
        // One radius per VPL, finite and >= 0.
        let short = vec![0.1; vpls.len() - 1];
        assert!(matches!(
            evaluate_with_radii(&scene, &g, &vpls, &short, &params, None, false),
            Err(VplaceError::Invalid { .. })
        ));
        for bad in [-0.1, f32::NAN, f32::INFINITY] {
            let mut radii = spacing.clone();
            radii[1] = bad;
            assert!(matches!(
                evaluate_with_radii(&scene, &g, &vpls, &radii, &params, None, false),
                Err(VplaceError::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn bad_input() {
        let scene = closed_box(vec![]);
        let (mut pos, normal, albedo, covered) = floor(4);
        let g = GBuffer {
            width: 4,
            height: 4,
            position: &pos,
            normal: &normal,
            albedo: &albedo[..9],
            covered: &covered,
        };
        assert!(matches!(
            evaluate(&scene, &g, &[], &EvalParams::PREVIEW, None),
            Err(VplaceError::Shape { .. })
        ));
        pos[4] = f32::NAN;
        let g = GBuffer {
            width: 4,
            height: 4,
            position: &pos,
            normal: &normal,
            albedo: &albedo,
            covered: &covered,
        };
        assert!(matches!(
            evaluate(&scene, &g, &[], &EvalParams::PREVIEW, None),
            Err(VplaceError::NonFinite { index: 3, .. })
        ));
        let mut cov = covered.clone();
        cov[1] = false;
        let g = GBuffer { covered: &cov, ..g };
        assert!(evaluate(&scene, &g, &[], &EvalParams::PREVIEW, None).is_ok());
        let bad = Vpl {
            position: Vec3::ZERO,
            normal: Vec3::ZERO,
            flux: Vec3::ONE,
        };
        assert!(evaluate(&scene, &g, &[bad], &EvalParams::PREVIEW, None).is_err());
    }

    #[test]
    fn cached_shadow_rays_give_the_same_image() {
        let scene = box_with(vec![], &[BLOCKER]);
        let (pos, normal, albedo, mut covered) = floor(12);
        covered[5] = false;
        let g = GBuffer {
            width: 12,
            height: 12,
            position: &pos,
            normal: &normal,
            albedo: &albedo,
            covered: &covered,
        };
        let mut rng = crate::rng::Rng::new(4, 0);
        // VPLs on the ceiling and walls, all facing into the box.
        let mut vpl = || {
            let (position, normal) = inward_point(&mut rng);
            Vpl {
                position,
                normal,
                flux: Vec3::new(1.0 + rng.next_f32(), 0.5, 2.0 * rng.next_f32()),
            }
        };
        let first: Vec<Vpl> = (0..150).map(|_| vpl()).collect();
        // The next set: some VPLs kept (other flux, other order, duplicated), some new.
        let mut second: Vec<Vpl> = (0..40).map(|_| vpl()).collect();
        for (i, v) in first.iter().enumerate().step_by(3) {
            second.push(Vpl {
                flux: v.flux * (0.5 + i as f32 / 100.0),
                ..*v
            });
        }
        second.push(second[45]);
        second.swap(3, 60);
        let kept = second.len() - 40;
        for profile in [Profile::Cosine, Profile::Omni] {
            let params = EvalParams {
                profile,
                radius: 0.05,
                tile: 5,
            };
            let mut cache = ShadowCache::default();
            let (a, sa) = evaluate_cached(&scene, &g, &first, &params, None, &mut cache).unwrap();
            let (a0, sa0) = evaluate(&scene, &g, &first, &params, None).unwrap();
            assert_eq!(a, a0);
            assert_eq!(sa.shadow_rays, sa0.shadow_rays);
            assert_eq!(cache.reused, 0);
            let (b, sb) = evaluate_cached(&scene, &g, &second, &params, None, &mut cache).unwrap();
            let (b0, sb0) = evaluate(&scene, &g, &second, &params, None).unwrap();
            assert_eq!(b, b0);
            assert_eq!(sb.shadow_rays + cache.reused, sb0.shadow_rays);
            // Every ray of a kept VPL is reused, and the blocker makes some of them dark.
            assert!(cache.reused > (kept as u64) * 100, "{}", cache.reused);
            assert!(sb.shadow_rays > 0);
            let (lit, _) = evaluate(&scene, &g, &second, &params, None).unwrap();
            let open = closed_box(vec![]);
            let (unblocked, _) = evaluate(&open, &g, &second, &params, None).unwrap();
            assert!(lit.iter().zip(&unblocked).any(|(a, b)| a < b));
            // A cache of another G-buffer size is ignored.
            let sub = GBuffer {
                width: 6,
                height: 24,
                ..g
            };
            let (c, sc) =
                evaluate_cached(&scene, &sub, &second, &params, None, &mut cache).unwrap();
            let (c0, sc0) = evaluate(&scene, &sub, &second, &params, None).unwrap();
            assert_eq!((c, sc.shadow_rays, cache.reused), (c0, sc0.shadow_rays, 0));
        }
    }
}
