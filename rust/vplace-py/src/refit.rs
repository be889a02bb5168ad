//! The optional refit of VPL powers against the views' indirect images: `refit` and `Refit`.

use numpy::PyArray1;
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::{
    layout::refit::{
        refit_frames as refit_frames_core, refit_with_coverage, RefitParams, Refitted,
    },
    view::View,
};

use crate::errors::{input_error, run};
use crate::params::PyRefitParams;
use crate::scene::{PyProgress, PyScene};
use crate::view::{views_of, PyView};
use crate::vpls::PyVplSet;

/// Refitted VPLs and what the refit achieved.
#[pyclass(name = "Refit", module = "vplace._native", frozen)]
pub struct PyRefit {
    vpls: PyVplSet,
    r: Refitted,
}

#[pymethods]
impl PyRefit {
    /// The refitted VPLs: the original flux times `scales`, same positions, profile and radius.
    #[getter]
    fn vpls(&self) -> PyVplSet {
        self.vpls.clone()
    }

    fn __len__(&self) -> usize {
        self.r.scales.len()
    }

    /// The scale of each VPL's flux, float64 (n,), `>= 0`.
    #[getter]
    fn scales<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.r.scales)
    }

    /// RMSE (linear RGB) of the VPL image against the targets on the covered strided pixels.
    #[getter]
    fn error_before(&self) -> f64 {
        self.r.error_before
    }

    /// The same after the refit; never above `error_before`.
    #[getter]
    fn error_after(&self) -> f64 {
        self.r.error_after
    }

    /// Power groups the scales were fitted for (one scale each; the VPL count with group 1).
    #[getter]
    fn groups(&self) -> usize {
        self.r.groups
    }

    /// Strided pixels of the coverage views that no captured view sees (0 without coverage).
    #[getter]
    fn unseen_pixels(&self) -> usize {
        self.r.unseen_pixels
    }

    /// The weight of each view's pixels in the refit (`RefitParams.balance_views`): the
    /// inverse of the view's mean indirect light, scaled so the targets keep their energy; all
    /// 1 with one view, views equally lit, or without the balance. `error_before` and
    /// `error_after` are of the weighted pixels.
    #[getter]
    fn view_weights(&self) -> Vec<f64> {
        self.r.view_weights.clone()
    }

    /// Covered pixels on the strided grids of every view.
    #[getter]
    fn pixels(&self) -> usize {
        self.r.pixels
    }

    /// Shadow rays traced.
    #[getter]
    fn shadow_rays(&self) -> u64 {
        self.r.shadow_rays
    }

    /// Block exchanges of the solver (0: the unconstrained optimum was already non-negative).
    #[getter]
    fn exchanges(&self) -> usize {
        self.r.exchanges
    }

    /// The ridge used (relative to `trace(A^T A) / n`).
    #[getter]
    fn ridge(&self) -> f64 {
        self.r.ridge
    }

    /// The ridge's cross-validation: `(ridge, held-out RMSE)` per ridge tried (empty when the
    /// ridge was given or the set is above `CV_MAX_VPLS`).
    #[getter]
    fn cv(&self) -> Vec<(f64, f64)> {
        self.r.cv.clone()
    }

    /// The same, pulling toward the captures' gain (empty without `free_gain`).
    #[getter]
    fn gain_cv(&self) -> Vec<(f64, f64)> {
        self.r.gain_cv.clone()
    }

    /// What the powers were pulled toward, as a multiple of the light-path powers: 1, or the
    /// captures' gain where the cross-validation took it.
    #[getter]
    fn gain(&self) -> f64 {
        self.r.gain
    }

    /// Wall time, seconds.
    #[getter]
    fn seconds(&self) -> f64 {
        self.r.seconds
    }

    fn __repr__(&self) -> String {
        format!(
            "Refit({} VPLs, RMSE {:.4e} -> {:.4e})",
            self.r.scales.len(),
            self.r.error_before,
            self.r.error_after
        )
    }
}

impl PyRefit {
    /// A core refit of `vpls` (whose profile and radius the refitted set keeps).
    fn of(r: Refitted, vpls: &PyVplSet) -> PyResult<Self> {
        Ok(Self {
            vpls: PyVplSet::new_checked(r.vpls.clone(), vpls.profile, vpls.radius)?,
            r,
        })
    }
}

/// The refit's settings for `vpls`: `params` (or the defaults) with the set's profile and
/// radius.
fn refit_params(vpls: &PyVplSet, params: Option<&PyRefitParams>) -> RefitParams {
    RefitParams {
        profile: vpls.profile,
        radius: vpls.radius,
        ..params.map_or(RefitParams::DEFAULT, |p| p.inner)
    }
}

/// Non-negative least squares on the VPL powers against every view's indirect image, each VPL
/// also held by its light on what the `coverage` views show and no view sees (see
/// `vplace.refit`).
#[pyfunction]
#[pyo3(signature = (scene, views, vpls, params = None, *, coverage = None, progress = None))]
fn refit(
    py: Python<'_>,
    scene: &PyScene,
    views: Vec<Bound<'_, PyView>>,
    vpls: &PyVplSet,
    params: Option<&PyRefitParams>,
    coverage: Option<Vec<Bound<'_, PyView>>>,
    progress: Option<&PyProgress>,
) -> PyResult<PyRefit> {
    if views.is_empty() {
        return Err(input_error("views: give at least one View"));
    }
    vpls.check_no_given_radii("refit")?;
    let views = views_of(&views);
    let coverage = views_of(&coverage.unwrap_or_default());
    let params = refit_params(vpls, params);
    let s = Arc::clone(&scene.inner);
    let set = Arc::clone(&vpls.vpls);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let r = run(py, move || {
        let refs: Vec<&View> = views.iter().map(|v| v.as_ref()).collect();
        let cover: Vec<&View> = coverage.iter().map(|v| v.as_ref()).collect();
        refit_with_coverage(&s, &refs, &cover, &set, &params, prog.as_deref())
    })?;
    PyRefit::of(r, vpls)
}

/// The refit of the same VPLs on several frames whose light alone differs (see
/// `vplace.refit_frames`): the shadow rays traced once for all frames.
#[pyfunction]
#[pyo3(signature = (scenes, frames, vpls, params = None, *, coverage = None, progress = None))]
fn refit_frames(
    py: Python<'_>,
    scenes: Vec<PyRef<'_, PyScene>>,
    frames: Vec<Vec<Bound<'_, PyView>>>,
    vpls: &PyVplSet,
    params: Option<&PyRefitParams>,
    coverage: Option<Vec<Bound<'_, PyView>>>,
    progress: Option<&PyProgress>,
) -> PyResult<Vec<PyRefit>> {
    if frames.is_empty() {
        return Err(input_error("frames: give at least one frame's views"));
    }
    if scenes.len() != frames.len() {
        return Err(input_error(format!(
            "scenes: one per frame of views, got {} scenes for {} frames",
            scenes.len(),
            frames.len()
        )));
    }
    if let Some(f) = frames.iter().position(Vec::is_empty) {
        return Err(input_error(format!(
            "frames: frame {f} has no view; give at least one View a frame"
        )));
    }
    vpls.check_no_given_radii("refit_frames")?;
    let frames: Vec<_> = frames.iter().map(|f| views_of(f)).collect();
    let coverage = views_of(&coverage.unwrap_or_default());
    let params = refit_params(vpls, params);
    let scenes: Vec<_> = scenes.iter().map(|s| Arc::clone(&s.inner)).collect();
    let set = Arc::clone(&vpls.vpls);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let refits = run(py, move || {
        let scene_refs: Vec<_> = scenes.iter().map(|s| s.as_ref()).collect();
        let view_refs: Vec<Vec<&View>> = frames
            .iter()
            .map(|f| f.iter().map(|v| v.as_ref()).collect())
            .collect();
        let frame_refs: Vec<&[&View]> = view_refs.iter().map(Vec::as_slice).collect();
        let cover: Vec<&View> = coverage.iter().map(|v| v.as_ref()).collect();
        refit_frames_core(
            &scene_refs,
            &frame_refs,
            &cover,
            &set,
            &params,
            prog.as_deref(),
        )
    })?;
    refits.into_iter().map(|r| PyRefit::of(r, vpls)).collect()
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRefit>()?;
    m.add_function(wrap_pyfunction!(refit, m)?)?;
    m.add_function(wrap_pyfunction!(refit_frames, m)?)?;
    Ok(())
}
