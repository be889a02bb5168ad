//! The layout iteration (DESIGN, Layout): evaluate the layout, compare per cell with the
//! captured indirect image `I`, move budget toward cells with a high residual, repeat.
//!
//! Each iteration renders the VPL indirect image with [`evaluate`](crate::shade::evaluator::evaluate) on every `stride`-th pixel of
//! every view (rows and columns), measures the error (RMSE over the covered pixels of those
//! grids, RGB, linear, all views together) and the mean absolute luminance residual `r_k` of each
//! cell of each view. The shares move
//! toward the residual-guided target `t_k ∝ lum(F_k) * r_k` (the off-screen stratum gets the
//! flux-weighted mean residual): `q <- lerp(q, t, step)`. The loop stops when the error improves
//! by less than `tolerance` (relative to the best so far) or after `max_iterations` evaluations,
//! and returns the best layout seen: its error never exceeds the first one.
//!
//! A VPL drawn again at the same position (a stratum whose count did not change draws the same
//! emitters) gets its shadow-ray answers from the previous iteration instead of new rays
//! ([`crate::shade::evaluator`]'s shadow cache): the images and errors are bit for bit those of fresh
//! evaluations. On the layout benchmark about a third of the rays of iterations 2 and 3 are
//! reused.

use glam::Vec3;
use std::time::Instant;

use crate::color::luminance;
use crate::error::{Result, VplaceError};
use crate::layout::{
    allocate, blend, build_strata, draw, importance, shares, Allocation, Grid, LayoutParams, Strata,
};
use crate::progress::Progress;
use crate::scene::Scene;
use crate::shade::evaluator::{evaluate_cached, EvalParams};
use crate::shade::shadow_cache::ShadowCache;
use crate::view::{GBuffer, View};
use crate::vpl::Vpl;

/// Settings of the iteration. `Copy`, with named presets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterateParams {
    /// The layout (budget, alpha, cells, seed).
    pub layout: LayoutParams,
    /// The evaluator used to score each iteration.
    pub eval: EvalParams,
    /// Evaluate every `stride`-th pixel in x and y (`>= 1`; 4 is quarter resolution).
    pub stride: usize,
    /// At most this many evaluations (`>= 1`); 1 only scores the initial layout.
    pub max_iterations: usize,
    /// Stop when the error improves by less than this fraction of the best error (`>= 0`).
    pub tolerance: f64,
    /// How far each iteration moves the shares toward the residual target, in `[0, 1]`.
    pub step: f64,
}

impl IterateParams {
    /// Three iterations at quarter resolution, 1 % tolerance, half steps.
    pub const DEFAULT: Self = Self {
        layout: LayoutParams::DEFAULT,
        eval: EvalParams::PREVIEW,
        stride: 4,
        max_iterations: 3,
        tolerance: 0.01,
        step: 0.5,
    };
}

impl Default for IterateParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// One round of the iteration: one evaluated layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Round {
    /// RMSE of the VPL indirect image against `I` over the covered pixels of the strided grid.
    pub error: f64,
    /// Shadow rays the evaluation traced.
    pub shadow_rays: u64,
    /// Pixel-VPL pairs whose visibility was reused from the previous iteration (a VPL at the
    /// same position) instead of a new shadow ray; the image is the same either way.
    pub reused_rays: u64,
    /// Seconds the evaluation took.
    pub seconds: f64,
    /// The allocation that was evaluated.
    pub allocation: Allocation,
}

/// The result of [`iterate`].
#[derive(Debug, Clone, PartialEq)]
pub struct Iterated {
    /// The VPLs of the best iteration.
    pub vpls: Vec<Vpl>,
    /// Index of the best iteration in `iterations`.
    pub best: usize,
    /// Every iteration, in order.
    pub iterations: Vec<Round>,
    /// The strata the layouts were drawn from.
    pub strata: Strata,
}

impl Iterated {
    /// The error of the returned layout (the minimum over the iterations).
    #[must_use]
    pub fn error(&self) -> f64 {
        self.iterations[self.best].error
    }
}

/// The strided sub-image of a view: owned arrays plus the stratum index of each pixel's
/// full-resolution cell.
struct Strided {
    width: usize,
    height: usize,
    position: Vec<f32>,
    normal: Vec<f32>,
    albedo: Vec<f32>,
    covered: Vec<bool>,
    indirect: Vec<f32>,
    cell: Vec<usize>,
}

impl Strided {
    /// Every `stride`-th pixel of `view` (which has its indirect image), rows and columns; the
    /// cells of `grid`.
    fn new(view: &View, indirect: &[f32], stride: usize, cell_px: usize, grid: &Grid) -> Self {
        let (w, h) = (view.width.div_ceil(stride), view.height.div_ceil(stride));
        let mut s = Self {
            width: w,
            height: h,
            position: Vec::with_capacity(3 * w * h),
            normal: Vec::with_capacity(3 * w * h),
            albedo: Vec::with_capacity(3 * w * h),
            covered: Vec::with_capacity(w * h),
            indirect: Vec::with_capacity(3 * w * h),
            cell: Vec::with_capacity(w * h),
        };
        for y in (0..view.height).step_by(stride) {
            for x in (0..view.width).step_by(stride) {
                let p = y * view.width + x;
                let rgb = 3 * p..3 * p + 3;
                s.position.extend_from_slice(&view.position[rgb.clone()]);
                s.normal.extend_from_slice(&view.normal[rgb.clone()]);
                s.albedo.extend_from_slice(&view.albedo[rgb.clone()]);
                s.indirect.extend_from_slice(&indirect[rgb]);
                s.covered.push(view.covered[p]);
                s.cell
                    .push(grid.start + (y / cell_px) * grid.cells_x + x / cell_px);
            }
        }
        s
    }

    fn gbuffer(&self) -> GBuffer<'_> {
        GBuffer {
            width: self.width,
            height: self.height,
            position: &self.position,
            normal: &self.normal,
            albedo: &self.albedo,
            covered: &self.covered,
        }
    }
}

/// The indirect image of each view, or an error naming the first view without one.
pub(crate) fn targets<'a>(views: &[&'a View]) -> Result<Vec<&'a [f32]>> {
    views
        .iter()
        .map(|v| {
            v.indirect.as_deref().ok_or_else(|| VplaceError::Invalid {
                what: format!("view {:?}", v.name),
                reason: "it has no indirect image to compare the VPLs with".into(),
            })
        })
        .collect()
}

/// Lays out VPLs for `views` and refines the allocation against their indirect images (each
/// view needs one). `predicted` holds the fit's per-cell `dL` of each view, or is `None` for
/// the uniform start.
pub fn iterate(
    scene: &Scene,
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &IterateParams,
    progress: Option<&Progress>,
) -> Result<Iterated> {
    iterate_with(scene, views, predicted, params, progress, true)
}

/// [`iterate`], with (`reuse`) or without the reuse of shadow rays between iterations.
fn iterate_with(
    scene: &Scene,
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &IterateParams,
    progress: Option<&Progress>,
    reuse: bool,
) -> Result<Iterated> {
    let indirect = targets(views)?;
    for (what, value, ok) in [
        ("stride", params.stride as f64, params.stride >= 1),
        (
            "max_iterations",
            params.max_iterations as f64,
            params.max_iterations >= 1,
        ),
        ("tolerance", params.tolerance, params.tolerance >= 0.0),
        ("step", params.step, (0.0..=1.0).contains(&params.step)),
    ] {
        if !ok {
            return Err(VplaceError::OutOfRange {
                what: what.into(),
                value: value.to_string(),
                expected: "stride >= 1, max_iterations >= 1, tolerance >= 0, step in [0, 1]".into(),
            });
        }
    }
    let strata = build_strata(scene, views, predicted, &params.layout)?;
    let lp = &params.layout;
    let subs: Vec<Strided> = views
        .iter()
        .zip(&indirect)
        .zip(&strata.grids)
        .map(|((v, ind), g)| Strided::new(v, ind, params.stride, lp.cell_px, g))
        .collect();
    let covered = subs
        .iter()
        .map(|s| s.covered.iter().filter(|&&c| c).count())
        .sum::<usize>()
        .max(1) as f64;
    let cells = strata.offscreen();
    let lum = strata.luminance();
    let mut q = shares(&strata, predicted, lp.alpha)?;
    let mut iterations: Vec<Round> = Vec::new();
    let mut best_vpls = Vec::new();
    let mut best = 0;
    let mut caches: Vec<ShadowCache> = subs.iter().map(|_| ShadowCache::default()).collect();
    loop {
        let allocation = allocate(&strata, &q, lp.budget)?;
        let vpls = draw(&strata, &allocation, lp.seed);
        let start = Instant::now();
        let mut sq = 0.0f64;
        let mut residual = vec![0.0f64; cells];
        let mut pixels = vec![0u32; cells];
        let (mut rays, mut reused) = (0, 0);
        for (sub, cache) in subs.iter().zip(&mut caches) {
            if !reuse {
                *cache = ShadowCache::default();
            }
            let (image, stats) =
                evaluate_cached(scene, &sub.gbuffer(), &vpls, &params.eval, progress, cache)?;
            rays += stats.shadow_rays;
            reused += cache.reused;
            for (p, _) in sub.covered.iter().enumerate().filter(|(_, &c)| c) {
                let e = Vec3::from_slice(&image[3 * p..]);
                let i = Vec3::from_slice(&sub.indirect[3 * p..]);
                let d = e - i;
                sq += f64::from(d.dot(d));
                residual[sub.cell[p]] += f64::from(luminance(d).abs());
                pixels[sub.cell[p]] += 1;
            }
        }
        let error = (sq / (3.0 * covered)).sqrt();
        let n = iterations.len();
        let improved = n == 0 || error < iterations[best].error;
        let gain = if n == 0 {
            f64::INFINITY
        } else {
            iterations[best].error - error
        };
        iterations.push(Round {
            error,
            shadow_rays: rays,
            reused_rays: reused,
            seconds: start.elapsed().as_secs_f64(),
            allocation,
        });
        if improved {
            best = n;
            best_vpls = vpls;
        }
        if iterations.len() >= params.max_iterations
            || (n > 0 && gain < params.tolerance * iterations[best].error)
        {
            break;
        }
        for (r, &c) in residual.iter_mut().zip(&pixels) {
            if c > 0 {
                *r /= f64::from(c);
            }
        }
        let target = importance(&lum, &residual, &strata.view_weight);
        q = blend(&q, &target, params.step);
    }
    Ok(Iterated {
        vpls: best_vpls,
        best,
        iterations,
        strata,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;
    use crate::shade::evaluator::evaluate;
    use crate::test_util::{closed_box, FloorView};

    const LIGHT: Vec3 = Vec3::new(0.3, -0.2, 1.0);

    /// A reference indirect image: the floor lit by many uniform VPLs.
    fn reference(scene: &Scene, fv: &FloorView) -> Vec<f32> {
        let vpls = crate::vpl::uniform_vpls(scene, 4000, 77).unwrap();
        evaluate(
            scene,
            &fv.view().gbuffer(),
            &vpls,
            &EvalParams::PREVIEW,
            None,
        )
        .unwrap()
        .0
    }

    #[test]
    fn returns_the_best_iteration_and_never_worse_than_the_first() {
        let scene = closed_box(vec![Light::point(LIGHT, Vec3::splat(20.0))]);
        let fv = FloorView::new(32, LIGHT, 20.0);
        let indirect = reference(&scene, &fv);
        for (alpha, stride, step, seed) in [(0.0, 2, 0.5, 1), (1.0, 1, 1.0, 2), (0.5, 4, 0.3, 3)] {
            let params = IterateParams {
                layout: LayoutParams {
                    budget: 24,
                    alpha,
                    cell_px: 8,
                    light_rays: 400,
                    seed,
                    ..LayoutParams::DEFAULT
                },
                stride,
                max_iterations: 5,
                tolerance: 0.0,
                step,
                ..IterateParams::DEFAULT
            };
            let pred: Vec<f64> = (0..16).map(|c| (c % 4) as f64).collect();
            let v = fv.view_with(Some(&indirect));
            let r = iterate(&scene, &[&v], Some(&[pred]), &params, None).unwrap();
            assert!(!r.iterations.is_empty() && r.iterations.len() <= 5);
            let min = r
                .iterations
                .iter()
                .map(|i| i.error)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(r.error(), min);
            assert!(r.error() <= r.iterations[0].error);
            assert_eq!(r.vpls.len(), 24);
            // The returned VPLs are those of the best allocation.
            let again = draw(&r.strata, &r.iterations[r.best].allocation, seed);
            assert_eq!(again, r.vpls);
            for it in &r.iterations {
                assert_eq!(
                    it.allocation.counts.iter().sum::<usize>() + it.allocation.pool_count,
                    24
                );
            }
        }
    }

    #[test]
    fn stops_on_tolerance_and_cap() {
        let scene = closed_box(vec![Light::point(LIGHT, Vec3::splat(20.0))]);
        let fv = FloorView::new(16, LIGHT, 20.0);
        let v = fv.view_with(Some(&reference(&scene, &fv)));
        let base = IterateParams {
            layout: LayoutParams {
                budget: 16,
                cell_px: 4,
                light_rays: 200,
                ..LayoutParams::DEFAULT
            },
            ..IterateParams::DEFAULT
        };
        // A huge tolerance stops after the second evaluation.
        let p = IterateParams {
            tolerance: 1e9,
            max_iterations: 10,
            ..base
        };
        let r = iterate(&scene, &[&v], None, &p, None).unwrap();
        assert_eq!(r.iterations.len(), 2);
        let p = IterateParams {
            max_iterations: 1,
            ..base
        };
        let r = iterate(&scene, &[&v], None, &p, None).unwrap();
        assert_eq!(r.iterations.len(), 1);
        assert_eq!(r.best, 0);
        // Step 0: the allocation never moves, the error is constant: stops at the second.
        let p = IterateParams {
            step: 0.0,
            max_iterations: 10,
            ..base
        };
        let r = iterate(&scene, &[&v], None, &p, None).unwrap();
        assert_eq!(r.iterations.len(), 2);
        assert_eq!(r.iterations[0].error, r.iterations[1].error);
    }

    #[test]
    fn bad_input() {
        let scene = closed_box(vec![Light::point(LIGHT, Vec3::splat(20.0))]);
        let fv = FloorView::new(8, LIGHT, 20.0);
        let indirect = vec![0.0; 8 * 8 * 3];
        let v = fv.view_with(Some(&indirect));
        let ok = IterateParams::DEFAULT;
        assert!(matches!(
            iterate(&scene, &[&fv.view()], None, &ok, None),
            Err(VplaceError::Invalid { .. })
        ));
        assert!(matches!(
            iterate(&scene, &[], None, &ok, None),
            Err(VplaceError::Empty { .. })
        ));
        for p in [
            IterateParams { stride: 0, ..ok },
            IterateParams {
                max_iterations: 0,
                ..ok
            },
            IterateParams {
                tolerance: -1.0,
                ..ok
            },
            IterateParams { step: 2.0, ..ok },
        ] {
            assert!(matches!(
                iterate(&scene, &[&v], None, &p, None),
                Err(VplaceError::OutOfRange { .. })
            ));
        }
    }

    #[test]
    fn reused_shadow_rays_give_the_same_layout() {
        use crate::test_util::{box_with, BLOCKER};
        let scene = box_with(vec![Light::point(LIGHT, Vec3::splat(20.0))], &[BLOCKER]);
        let fv = FloorView::new(32, LIGHT, 20.0);
        let v = fv.view_with(Some(&reference(&scene, &fv)));
        let (mut reused, mut partial) = (0, false);
        for (alpha, stride, seed, budget) in [(1.0, 2, 1, 40), (0.5, 1, 7, 64), (0.0, 3, 3, 17)] {
            let params = IterateParams {
                layout: LayoutParams {
                    budget,
                    alpha,
                    cell_px: 8,
                    light_rays: 400,
                    seed,
                    ..LayoutParams::DEFAULT
                },
                stride,
                max_iterations: 4,
                tolerance: 0.0,
                step: 0.7,
                ..IterateParams::DEFAULT
            };
            let pred: Vec<f64> = (0..16).map(|c| ((c * 7) % 5) as f64).collect();
            let run = |reuse| {
                iterate_with(
                    &scene,
                    &[&v],
                    Some(std::slice::from_ref(&pred)),
                    &params,
                    None,
                    reuse,
                )
                .unwrap()
            };
            let (a, b) = (run(true), run(false));
            assert_eq!(a.vpls, b.vpls);
            assert_eq!(a.best, b.best);
            assert_eq!(a.iterations.len(), b.iterations.len());
            for (x, y) in a.iterations.iter().zip(&b.iterations) {
                assert_eq!(x.error.to_bits(), y.error.to_bits());
                assert_eq!(x.allocation, y.allocation);
                assert_eq!(x.shadow_rays + x.reused_rays, y.shadow_rays);
                assert_eq!(y.reused_rays, 0);
            }
            assert_eq!(a.iterations[0].reused_rays, 0);
            reused += a.iterations.iter().map(|i| i.reused_rays).sum::<u64>();
            partial |= a
                .iterations
                .iter()
                .any(|i| i.reused_rays > 0 && i.shadow_rays > 0);
            // Deterministic for a seed (all but the timings).
            let again = run(true);
            assert_eq!(
                (&again.vpls, again.best, &again.strata),
                (&a.vpls, a.best, &a.strata)
            );
            for (x, y) in again.iterations.iter().zip(&a.iterations) {
                assert_eq!(
                    Round {
                        seconds: 0.0,
                        ..x.clone()
                    },
                    Round {
                        seconds: 0.0,
                        ..y.clone()
                    }
                );
            }
        }
        assert!(reused > 0 && partial);
    }
}
