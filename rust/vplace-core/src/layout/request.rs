//! One layout call as the user asks for it: [`LayoutRequest`] (every setting, with the
//! defaults of the add-on and the `vplace.layout` function) and [`lay_out`], which resolves what
//! the request leaves open (the cell size from the fit, the light paths' bounces from
//! `multi_bounce`, the near-field radius from the scene, whether the iteration can run) and runs
//! the layout, with or without the iteration.

use crate::error::Result;
use crate::fit::features::CellModel;
use crate::layout::iterate::{iterate, IterateParams};
use crate::layout::{layout, Allocation, LayoutParams, Strata, LIGHT_RAYS};
use crate::progress::Progress;
use crate::scene::Scene;
use crate::shade::evaluator::EvalParams;
use crate::view::View;
use crate::vpl::{Profile, Vpl, MAX_BOUNCES};

/// Every setting of one layout call. `Copy`, with named presets; `None` fields are resolved by
/// [`LayoutRequest::resolve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayoutRequest {
    /// VPL budget `N`, `>= 1`.
    pub budget: usize,
    /// Blend between the uniform (0) and the regression-guided (1) allocation, in `[0, 1]`.
    pub alpha: f32,
    /// Cell size in pixels (`>= 1`); `None`: the fit's cell size, or 16 without a fit.
    pub cell_px: Option<usize>,
    /// Light rays hitting geometry traced for the off-screen strata (0: none).
    pub light_rays: usize,
    /// Surface hits per light path; `None`: [`MAX_BOUNCES`] with `multi_bounce`, else 1.
    pub bounces: Option<usize>,
    /// Seed of the light rays and the draws.
    pub seed: u64,
    /// Pixel emitters reflect all the light their surface receives, not only the direct light.
    pub multi_bounce: bool,
    /// The iteration evaluates every `stride`-th pixel in x and y (`>= 1`).
    pub stride: usize,
    /// At most this many evaluations of the iteration (`>= 1`).
    pub iterations: usize,
    /// The iteration stops when the error improves by less than this fraction of the best.
    pub tolerance: f64,
    /// How far each iteration moves the shares toward the residual target, in `[0, 1]`.
    pub step: f64,
    /// Iterate against the views' indirect images (runs only when every view has one; see
    /// [`Iteration`]).
    pub iterate: bool,
    /// How the VPLs radiate.
    pub profile: Profile,
    /// Near-field radius of the VPLs, metres; `None`: [`Scene::near_field_radius`].
    pub radius: Option<f32>,
    /// Side of the evaluator's square pixel tiles.
    pub tile: usize,
}

impl LayoutRequest {
    /// 256 VPLs, fully guided, cells of the fit (16 px without one), [`LIGHT_RAYS`] light-path
    /// hits of every bounce, multi-bounce pixel emitters, three iterations at stride 4, cosine
    /// VPLs with the scene's near-field radius.
    pub const DEFAULT: Self = Self {
        budget: 256,
        alpha: 1.0,
        cell_px: None,
        light_rays: LIGHT_RAYS,
        bounces: None,
        seed: 0,
        multi_bounce: true,
        stride: 4,
        iterations: 3,
        tolerance: 0.01,
        step: 0.5,
        iterate: true,
        profile: Profile::Cosine,
        radius: None,
        tile: 16,
    };

    /// [`Self::DEFAULT`] without the iteration: one allocation, no evaluation.
    pub const SINGLE_PASS: Self = Self {
        iterate: false,
        ..Self::DEFAULT
    };

    /// The settings of the layout and the iteration for `scene`, `views` and the fit `model`:
    /// the cell size of the fit (16 without one) unless given, every bounce of the light paths
    /// with `multi_bounce` (one without) unless given, the scene's near-field radius unless
    /// given, and whether the iteration runs.
    #[must_use]
    pub fn resolve(
        &self,
        scene: &Scene,
        views: &[&View],
        model: Option<&CellModel>,
    ) -> (IterateParams, Iteration) {
        let params = IterateParams {
            layout: LayoutParams {
                budget: self.budget,
                alpha: self.alpha,
                cell_px: self
                    .cell_px
                    .unwrap_or_else(|| model.map_or(16, |m| m.cell_px)),
                light_rays: self.light_rays,
                seed: self.seed,
                // Multi-bounce layouts trace every bounce of the off-screen light paths too.
                bounces: self
                    .bounces
                    .unwrap_or(if self.multi_bounce { MAX_BOUNCES } else { 1 }),
                multi_bounce: self.multi_bounce,
            },
            eval: EvalParams {
                profile: self.profile,
                radius: self.radius.unwrap_or_else(|| scene.near_field_radius()),
                tile: self.tile,
            },
            stride: self.stride,
            max_iterations: self.iterations,
            tolerance: self.tolerance,
            step: self.step,
        };
        let iteration = if !self.iterate {
            Iteration::Off
        } else if let Some(v) = views.iter().position(|v| v.indirect.is_none()) {
            Iteration::NoIndirect { view: v }
        } else {
            Iteration::Runs
        };
        (params, iteration)
    }
}

impl Default for LayoutRequest {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Whether a layout call iterates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Iteration {
    /// It iterates against every view's indirect image.
    Runs,
    /// The request turned it off.
    Off,
    /// It was asked for, but view `view` (the first such) has no indirect image to compare
    /// with: the layout is the single pass.
    NoIndirect {
        /// Index of the view in the call's list.
        view: usize,
    },
}

/// What [`lay_out`] returns.
#[derive(Debug, Clone, PartialEq)]
pub struct LaidOut {
    /// The VPLs (of the best iteration when it ran).
    pub vpls: Vec<Vpl>,
    /// The strata the VPLs were drawn from.
    pub strata: Strata,
    /// The allocation of the returned VPLs.
    pub allocation: Allocation,
    /// The resolved settings.
    pub params: IterateParams,
    /// Whether the iteration ran, and why not.
    pub iteration: Iteration,
    /// The iterations (empty unless [`Iteration::Runs`]), and the best one's index.
    pub iterations: Vec<crate::layout::iterate::Round>,
    /// Index of the returned iteration in `iterations`.
    pub best: Option<usize>,
}

/// Lays out VPLs for `views` as `request` asks ([`LayoutRequest::resolve`]), guided by the fit
/// `model`'s prediction of every view when given.
pub fn lay_out(
    scene: &Scene,
    views: &[&View],
    model: Option<&CellModel>,
    request: &LayoutRequest,
    progress: Option<&Progress>,
) -> Result<LaidOut> {
    let (params, iteration) = request.resolve(scene, views, model);
    let predicted = model
        .map(|m| {
            views
                .iter()
                .map(|v| m.predict_view(v))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()?;
    if iteration == Iteration::Runs {
        let r = iterate(scene, views, predicted.as_deref(), &params, progress)?;
        Ok(LaidOut {
            allocation: r.iterations[r.best].allocation.clone(),
            vpls: r.vpls,
            strata: r.strata,
            params,
            iteration,
            iterations: r.iterations,
            best: Some(r.best),
        })
    } else {
        let (vpls, allocation, strata) =
            layout(scene, views, predicted.as_deref(), &params.layout)?;
        Ok(LaidOut {
            vpls,
            strata,
            allocation,
            params,
            iteration,
            iterations: Vec::new(),
            best: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;
    use crate::test_util::{closed_box, FloorView};
    use glam::Vec3;

    const LIGHT: Vec3 = Vec3::new(0.3, -0.2, 1.0);

    #[test]
    fn resolve_fills_what_the_request_leaves_open() {
        let scene = closed_box(vec![Light::point(LIGHT, Vec3::splat(20.0))]);
        let fv = FloorView::new(8, LIGHT, 20.0);
        let lit = fv.view_with(Some(&vec![0.0; 8 * 8 * 3]));
        let unlit = fv.view();
        let (p, it) = LayoutRequest::DEFAULT.resolve(&scene, &[&lit], None);
        assert_eq!(it, Iteration::Runs);
        assert_eq!((p.layout.cell_px, p.layout.bounces), (16, MAX_BOUNCES));
        assert_eq!(p.eval.radius, scene.near_field_radius());
        let single = LayoutRequest {
            multi_bounce: false,
            radius: Some(0.5),
            cell_px: Some(4),
            ..LayoutRequest::DEFAULT
        };
        let (p, _) = single.resolve(&scene, &[&lit], None);
        assert_eq!(
            (p.layout.cell_px, p.layout.bounces, p.eval.radius),
            (4, 1, 0.5)
        );
        let (_, it) = LayoutRequest::DEFAULT.resolve(&scene, &[&lit, &unlit], None);
        assert_eq!(it, Iteration::NoIndirect { view: 1 });
        let (_, it) = LayoutRequest::SINGLE_PASS.resolve(&scene, &[&lit], None);
        assert_eq!(it, Iteration::Off);
    }
}
