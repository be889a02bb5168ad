//! The settings of each stage as Python classes: `LayoutParams`, `FitParams`, `RefitParams`,
//! each a frozen wrapper of the core's `Copy` settings struct. A keyword left out takes the
//! core's default (`LayoutRequest::DEFAULT`, `ViewFitParams::DEFAULT`, `RefitParams::DEFAULT`);
//! the named presets are class attributes.

use pyo3::prelude::*;
use vplace_core::{
    fit::features::ViewFitParams, fit::regression::FitParams, layout::refit::RefitParams,
    layout::request::LayoutRequest,
};

use crate::vpls::{parse_profile, profile_name};

/// Settings of `vplace.layout` (see `LayoutRequest` in the core).
#[pyclass(name = "LayoutParams", module = "vplace._native", frozen)]
#[derive(Clone, Copy)]
pub struct PyLayoutParams {
    pub inner: LayoutRequest,
}

#[pymethods]
impl PyLayoutParams {
    #[new]
    #[pyo3(signature = (*, budget = None, alpha = None, cell_px = None, light_rays = None,
        bounces = None, seed = None, multi_bounce = None, stride = None, iterations = None,
        tolerance = None, step = None, iterate = None, profile = None, radius = None,
        tile = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        budget: Option<usize>,
        alpha: Option<f32>,
        cell_px: Option<usize>,
        light_rays: Option<usize>,
        bounces: Option<usize>,
        seed: Option<u64>,
        multi_bounce: Option<bool>,
        stride: Option<usize>,
        iterations: Option<usize>,
        tolerance: Option<f64>,
        step: Option<f64>,
        iterate: Option<bool>,
        profile: Option<&str>,
        radius: Option<f32>,
        tile: Option<usize>,
    ) -> PyResult<Self> {
        let d = LayoutRequest::DEFAULT;
        let profile = profile.map(parse_profile).transpose()?;
        Ok(Self {
            inner: LayoutRequest {
                budget: budget.unwrap_or(d.budget),
                alpha: alpha.unwrap_or(d.alpha),
                cell_px: cell_px.or(d.cell_px),
                light_rays: light_rays.unwrap_or(d.light_rays),
                bounces: bounces.or(d.bounces),
                seed: seed.unwrap_or(d.seed),
                multi_bounce: multi_bounce.unwrap_or(d.multi_bounce),
                stride: stride.unwrap_or(d.stride),
                iterations: iterations.unwrap_or(d.iterations),
                tolerance: tolerance.unwrap_or(d.tolerance),
                step: step.unwrap_or(d.step),
                iterate: iterate.unwrap_or(d.iterate),
                profile: profile.unwrap_or(d.profile),
                radius: radius.or(d.radius),
                tile: tile.unwrap_or(d.tile),
            },
        })
    }

    /// The default: 256 VPLs, fully guided, every bounce, three iterations at stride 4.
    #[classattr]
    #[allow(non_snake_case)]
    fn DEFAULT() -> Self {
        Self {
            inner: LayoutRequest::DEFAULT,
        }
    }

    /// The default without the iteration.
    #[classattr]
    #[allow(non_snake_case)]
    fn SINGLE_PASS() -> Self {
        Self {
            inner: LayoutRequest::SINGLE_PASS,
        }
    }

    /// VPL budget `N`.
    #[getter]
    fn budget(&self) -> usize {
        self.inner.budget
    }
    /// Blend between the uniform (0) and the regression-guided (1) allocation.
    #[getter]
    fn alpha(&self) -> f32 {
        self.inner.alpha
    }
    /// Cell size in pixels; None: the fit's (16 without a fit).
    #[getter]
    fn cell_px(&self) -> Option<usize> {
        self.inner.cell_px
    }
    /// Light rays of the off-screen strata.
    #[getter]
    fn light_rays(&self) -> usize {
        self.inner.light_rays
    }
    /// Surface hits per light path; None: every bounce with `multi_bounce`, else 1.
    #[getter]
    fn bounces(&self) -> Option<usize> {
        self.inner.bounces
    }
    /// Seed of the light rays and the draws.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed
    }
    /// Pixel emitters reflect all the light their surface receives.
    #[getter]
    fn multi_bounce(&self) -> bool {
        self.inner.multi_bounce
    }
    /// The iteration evaluates every `stride`-th pixel.
    #[getter]
    fn stride(&self) -> usize {
        self.inner.stride
    }
    /// At most this many evaluations of the iteration.
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    /// Relative error improvement below which the iteration stops.
    #[getter]
    fn tolerance(&self) -> f64 {
        self.inner.tolerance
    }
    /// How far each iteration moves the shares toward the residual target.
    #[getter]
    fn step(&self) -> f64 {
        self.inner.step
    }
    /// Iterate against the views' indirect images (when every view has one).
    #[getter]
    fn iterate(&self) -> bool {
        self.inner.iterate
    }
    /// `"cosine"` or `"omni"`.
    #[getter]
    fn profile(&self) -> &'static str {
        profile_name(self.inner.profile)
    }
    /// Near-field radius, metres; None: the scene's.
    #[getter]
    fn radius(&self) -> Option<f32> {
        self.inner.radius
    }
    /// Side of the evaluator's pixel tiles.
    #[getter]
    fn tile(&self) -> usize {
        self.inner.tile
    }

    fn __repr__(&self) -> String {
        let r = &self.inner;
        format!(
            "LayoutParams(budget={}, alpha={:?}, cell_px={}, light_rays={}, bounces={}, \
             seed={}, multi_bounce={}, stride={}, iterations={}, tolerance={:?}, step={:?}, \
             iterate={}, profile={:?}, radius={}, tile={})",
            r.budget,
            r.alpha,
            py_option(r.cell_px),
            r.light_rays,
            py_option(r.bounces),
            r.seed,
            py_bool(r.multi_bounce),
            r.stride,
            r.iterations,
            r.tolerance,
            r.step,
            py_bool(r.iterate),
            profile_name(r.profile),
            py_option(r.radius.map(|x| format!("{x:?}"))),
            r.tile
        )
    }
}

/// Settings of `vplace.fit` and `vplace.fit_design` (see `ViewFitParams` and `FitParams` in
/// the core; `fit_design` reads only the regression's).
#[pyclass(name = "FitParams", module = "vplace._native", frozen)]
#[derive(Clone, Copy)]
pub struct PyFitParams {
    pub inner: ViewFitParams,
}

#[pymethods]
impl PyFitParams {
    #[new]
    #[pyo3(signature = (*, cell_px = None, surface_only = None, folds = None, select = None,
        min_cv_gain = None, collinear_rtol = None, rank_rtol = None, ridge_above = None,
        seed = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        cell_px: Option<usize>,
        surface_only: Option<bool>,
        folds: Option<usize>,
        select: Option<bool>,
        min_cv_gain: Option<f64>,
        collinear_rtol: Option<f64>,
        rank_rtol: Option<f64>,
        ridge_above: Option<f64>,
        seed: Option<u64>,
    ) -> Self {
        let d = ViewFitParams::DEFAULT;
        let r = d.regression;
        Self {
            inner: ViewFitParams {
                cell_px: cell_px.unwrap_or(d.cell_px),
                surface_only: surface_only.unwrap_or(d.surface_only),
                regression: FitParams {
                    folds: folds.unwrap_or(r.folds),
                    select: select.unwrap_or(r.select),
                    min_cv_gain: min_cv_gain.unwrap_or(r.min_cv_gain),
                    collinear_rtol: collinear_rtol.unwrap_or(r.collinear_rtol),
                    rank_rtol: rank_rtol.or(r.rank_rtol),
                    ridge_above: ridge_above.unwrap_or(r.ridge_above),
                    seed: seed.unwrap_or(r.seed),
                },
            },
        }
    }

    /// The default: 16-pixel cells, surface features, selection by CV, ridge above 1e6.
    #[classattr]
    #[allow(non_snake_case)]
    fn DEFAULT() -> Self {
        Self {
            inner: ViewFitParams::DEFAULT,
        }
    }

    /// Every feature, plain OLS: what `numpy.linalg.lstsq` fits.
    #[classattr]
    #[allow(non_snake_case)]
    fn PLAIN_OLS() -> Self {
        Self {
            inner: ViewFitParams::PLAIN_OLS,
        }
    }

    /// Cell size in pixels.
    #[getter]
    fn cell_px(&self) -> usize {
        self.inner.cell_px
    }
    /// Fit only the features of the surface.
    #[getter]
    fn surface_only(&self) -> bool {
        self.inner.surface_only
    }
    /// Cross-validation folds (0: no CV).
    #[getter]
    fn folds(&self) -> usize {
        self.inner.regression.folds
    }
    /// Drop features that do not raise the CV R^2.
    #[getter]
    fn select(&self) -> bool {
        self.inner.regression.select
    }
    /// The CV R^2 a feature must add to stay.
    #[getter]
    fn min_cv_gain(&self) -> f64 {
        self.inner.regression.min_cv_gain
    }
    /// Relative residual below which a column is collinear (0: no check).
    #[getter]
    fn collinear_rtol(&self) -> f64 {
        self.inner.regression.collinear_rtol
    }
    /// Relative singular value cut-off; None: `max(n, p + 1) * eps`.
    #[getter]
    fn rank_rtol(&self) -> Option<f64> {
        self.inner.regression.rank_rtol
    }
    /// Condition number above which the ridge fallback is used.
    #[getter]
    fn ridge_above(&self) -> f64 {
        self.inner.regression.ridge_above
    }
    /// Seed of the fold assignment.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.regression.seed
    }

    fn __repr__(&self) -> String {
        let (v, r) = (&self.inner, &self.inner.regression);
        format!(
            "FitParams(cell_px={}, surface_only={}, folds={}, select={}, min_cv_gain={:?}, \
             collinear_rtol={:?}, rank_rtol={}, ridge_above={:?}, seed={})",
            v.cell_px,
            py_bool(v.surface_only),
            r.folds,
            py_bool(r.select),
            r.min_cv_gain,
            r.collinear_rtol,
            py_option(r.rank_rtol.map(|x| format!("{x:?}"))),
            r.ridge_above,
            r.seed
        )
    }
}

/// Settings of `vplace.refit` (see `RefitParams` in the core; the profile and the near-field
/// radius are the VPL set's own).
#[pyclass(name = "RefitParams", module = "vplace._native", frozen)]
#[derive(Clone, Copy)]
pub struct PyRefitParams {
    pub inner: RefitParams,
}

#[pymethods]
impl PyRefitParams {
    /// `ridge` given: that ridge, not selected; None: chosen by cross-validation, leaving out
    /// whole views when there are three or more and `leave_out_views` (default True), else
    /// blocks of pixels. `free_gain` (default True): the cross-validation also tries pulling
    /// the powers toward the captures' gain instead of the light-path powers. `group` (default
    /// `REFIT_GROUP`, 1): VPLs per power group, one scale per group of neighbouring VPLs; 1:
    /// one scale per VPL. `unseen_weight` (default `UNSEEN_WEIGHT`, 1): the weight of the
    /// coverage views' pixels no capture sees (`refit(..., coverage=...)`), per coverage view
    /// relative to one captured view; 0 turns it off. `balance_views` (default True): each
    /// view's pixels weigh by the inverse of its light (`Refit.view_weights`), so that a dim
    /// view's relative error counts as a bright one's. `max_scale` (default `inf`, no bound):
    /// the largest scale, times the larger of 1 and what the scales are pulled toward, solved
    /// as a bound in the refit (`>= 1`).
    #[new]
    #[pyo3(signature = (*, stride = None, ridge = None, leave_out_views = None, free_gain = None,
        group = None, unseen_weight = None, balance_views = None, max_scale = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        stride: Option<usize>,
        ridge: Option<f64>,
        leave_out_views: Option<bool>,
        free_gain: Option<bool>,
        group: Option<usize>,
        unseen_weight: Option<f64>,
        balance_views: Option<bool>,
        max_scale: Option<f64>,
    ) -> Self {
        let d = RefitParams::DEFAULT;
        Self {
            inner: RefitParams {
                stride: stride.unwrap_or(d.stride),
                ridge: ridge.unwrap_or(d.ridge),
                select_ridge: ridge.is_none(),
                leave_out_views: leave_out_views.unwrap_or(d.leave_out_views),
                free_gain: free_gain.unwrap_or(d.free_gain),
                group: group.unwrap_or(d.group),
                unseen_weight: unseen_weight.unwrap_or(d.unseen_weight),
                balance_views: balance_views.unwrap_or(d.balance_views),
                max_scale: max_scale.unwrap_or(d.max_scale),
                ..d
            },
        }
    }

    /// The default: stride 4, the ridge chosen by cross-validation (0.1 above `CV_MAX_VPLS`).
    #[classattr]
    #[allow(non_snake_case)]
    fn DEFAULT() -> Self {
        Self {
            inner: RefitParams::DEFAULT,
        }
    }

    /// Fit on every `stride`-th pixel in x and y.
    #[getter]
    fn stride(&self) -> usize {
        self.inner.stride
    }
    /// Weight of the pull toward scale 1, relative to `trace(A^T A) / n`.
    #[getter]
    fn ridge(&self) -> f64 {
        self.inner.ridge
    }
    /// Whether the ridge is chosen by cross-validation (`ridge` applies above `CV_MAX_VPLS`).
    #[getter]
    fn select_ridge(&self) -> bool {
        self.inner.select_ridge
    }

    /// Whether the cross-validation leaves out whole views (with three or more).
    #[getter]
    fn leave_out_views(&self) -> bool {
        self.inner.leave_out_views
    }

    /// Whether the cross-validation also tries pulling toward the captures' gain.
    #[getter]
    fn free_gain(&self) -> bool {
        self.inner.free_gain
    }

    /// VPLs per power group (1: one scale per VPL).
    #[getter]
    fn group(&self) -> usize {
        self.inner.group
    }

    /// Weight of the coverage views' pixels no capture sees, per view relative to a capture.
    #[getter]
    fn unseen_weight(&self) -> f64 {
        self.inner.unseen_weight
    }

    /// Whether each view's pixels weigh by the inverse of its light.
    #[getter]
    fn balance_views(&self) -> bool {
        self.inner.balance_views
    }

    /// The largest scale, times the larger of 1 and the pull (`inf`: no bound).
    #[getter]
    fn max_scale(&self) -> f64 {
        self.inner.max_scale
    }

    fn __repr__(&self) -> String {
        format!(
            "RefitParams(stride={}, ridge={:?}, select_ridge={}, leave_out_views={}, free_gain={}, \
             group={}, unseen_weight={:?}, balance_views={}, max_scale={})",
            self.inner.stride,
            self.inner.ridge,
            py_bool(self.inner.select_ridge),
            py_bool(self.inner.leave_out_views),
            py_bool(self.inner.free_gain),
            self.inner.group,
            self.inner.unseen_weight,
            py_bool(self.inner.balance_views),
            py_float(self.inner.max_scale)
        )
    }
}

/// A float as Python's `repr` writes it where it differs from Rust's `{:?}` (`inf`).
fn py_float(v: f64) -> String {
    if v.is_infinite() {
        (if v > 0.0 { "inf" } else { "-inf" }).into()
    } else {
        format!("{v:?}")
    }
}

/// `True` / `False`, as Python writes them.
fn py_bool(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// The value, or `None`, as Python writes them.
fn py_option<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(|| "None".to_owned(), |v| v.to_string())
}

/// Registers this file's classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLayoutParams>()?;
    m.add_class::<PyFitParams>()?;
    m.add_class::<PyRefitParams>()?;
    Ok(())
}
