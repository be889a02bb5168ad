//! The layout (strata, allocation, iteration) over one or more views: `layout` and `Layout`.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::{
    layout::refine,
    layout::{Allocation, IndirectSource, LayoutParams, Strata},
    shade::evaluator::EvalParams,
    view::View,
    vpl,
};

use crate::errors::{input_error, run};
use crate::fit::PyFit;
use crate::scene::{PyProgress, PyScene};
use crate::view::{views_of, PyView};
use crate::vpls::{default_radius, parse_profile, PyVplSet};

/// A VPL layout for one or more views, and how it was reached.
#[pyclass(name = "Layout", module = "vplace._native", frozen)]
pub struct PyLayout {
    vpls: PyVplSet,
    strata: Strata,
    allocation: Allocation,
    errors: Vec<f64>,
    best: Option<usize>,
    seconds: Vec<f64>,
    shadow_rays: Vec<u64>,
    reused_rays: Vec<u64>,
}

impl PyLayout {
    /// One array per view of `channels` values per cell (`cell(k)` for stratum `k`), shaped
    /// (cells_y, cells_x) or (cells_y, cells_x, channels).
    fn per_view<'py, T: numpy::Element>(
        &self,
        py: Python<'py>,
        channels: usize,
        cell: impl Fn(usize) -> Vec<T>,
    ) -> PyResult<Vec<Bound<'py, PyAny>>> {
        self.strata
            .grids
            .iter()
            .map(|g| {
                let v: Vec<T> = (g.start..g.start + g.cells()).flat_map(&cell).collect();
                let a = PyArray1::from_vec(py, v);
                Ok(if channels == 1 {
                    a.reshape([g.cells_y, g.cells_x])?.into_any()
                } else {
                    a.reshape([g.cells_y, g.cells_x, channels])?.into_any()
                })
            })
            .collect()
    }
}

#[pymethods]
impl PyLayout {
    /// The VPLs.
    #[getter]
    fn vpls(&self) -> PyVplSet {
        self.vpls.clone()
    }

    fn __len__(&self) -> usize {
        self.vpls.vpls.len()
    }

    /// VPLs drawn from each cell, one int64 (cells_y, cells_x) array per view.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        self.per_view(py, 1, |k| vec![self.allocation.counts[k] as i64])
    }

    /// Reflected flux of each cell's candidates, one float32 (cells_y, cells_x, 3) array per view.
    #[getter]
    fn strata_flux<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        self.per_view(py, 3, |k| self.strata.flux[k].to_array().to_vec())
    }

    /// VPLs drawn from the off-screen strata.
    #[getter]
    fn offscreen_count(&self) -> usize {
        self.allocation.counts[self.strata.offscreen()..]
            .iter()
            .sum()
    }

    /// VPLs drawn jointly from the strata that hold flux but got no VPL of their own.
    #[getter]
    fn pool_count(&self) -> usize {
        self.allocation.pool_count
    }

    /// RMSE against the indirect images at each iteration (empty without iteration).
    #[getter]
    fn errors(&self) -> Vec<f64> {
        self.errors.clone()
    }

    /// The iteration the VPLs come from (the minimum of `errors`), or None.
    #[getter]
    fn best(&self) -> Option<usize> {
        self.best
    }

    /// The error of the returned layout, or None without iteration.
    #[getter]
    fn error(&self) -> Option<f64> {
        self.best.map(|b| self.errors[b])
    }

    /// Seconds of each iteration's evaluation.
    #[getter]
    fn seconds(&self) -> Vec<f64> {
        self.seconds.clone()
    }

    /// Shadow rays traced at each iteration.
    #[getter]
    fn shadow_rays(&self) -> Vec<u64> {
        self.shadow_rays.clone()
    }

    /// Pixel-VPL pairs at each iteration whose visibility came from the previous iteration (a
    /// VPL at the same position) instead of a shadow ray; the result is the same either way.
    #[getter]
    fn reused_rays(&self) -> Vec<u64> {
        self.reused_rays.clone()
    }

    /// Total RGB flux of the off-screen strata.
    #[getter]
    fn offscreen_flux(&self) -> [f32; 3] {
        self.strata.offscreen_flux().to_array()
    }

    /// View weight of each off-screen stratum, by increasing view efficiency, then the dark one.
    #[getter]
    fn offscreen_view_weight(&self) -> Vec<f64> {
        self.strata.view_weight[self.strata.offscreen()..].to_vec()
    }

    /// Candidate emitters in all strata.
    #[getter]
    fn candidates(&self) -> usize {
        self.strata.emitters.len()
    }

    /// Light-path hits dropped because a view sees them (its pixels stand for them).
    #[getter]
    fn light_hits_on_screen(&self) -> usize {
        self.strata.light_hits_on_screen
    }

    /// Pixel emitters dropped because an earlier view already holds their surface.
    #[getter]
    fn shared_pixels(&self) -> usize {
        self.strata.shared_pixels
    }

    /// Where each view's emitters got their indirect irradiance: `"captured"` (the view's
    /// `diffuse_indirect`), `"predicted"` (the fit's per-cell prediction) or `"none"`.
    #[getter]
    fn indirect_source(&self) -> Vec<&'static str> {
        self.strata
            .grids
            .iter()
            .map(|g| match g.source {
                IndirectSource::Captured => "captured",
                IndirectSource::Predicted => "predicted",
                IndirectSource::None => "none",
            })
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "Layout({} VPLs over {} view(s), best error {:?})",
            self.vpls.vpls.len(),
            self.strata.grids.len(),
            self.error()
        )
    }
}

/// Lays out `budget` VPLs for `views` (see `vplace.layout`).
#[pyfunction]
#[pyo3(signature = (scene, views, *, fit = None, budget = 256, alpha = 1.0, cell_px = None,
    iterate = true, light_rays = 4096, bounces = None, seed = 0, stride = 4,
    iterations = 3, tolerance = 0.01, step = 0.5, profile = "cosine", radius = None,
    multi_bounce = true, tile = 16, progress = None))]
#[allow(clippy::too_many_arguments)]
fn layout(
    py: Python<'_>,
    scene: &PyScene,
    views: Vec<Bound<'_, PyView>>,
    fit: Option<&PyFit>,
    budget: usize,
    alpha: f32,
    cell_px: Option<usize>,
    iterate: bool,
    light_rays: usize,
    bounces: Option<usize>,
    seed: u64,
    stride: usize,
    iterations: usize,
    tolerance: f64,
    step: f64,
    profile: &str,
    radius: Option<f32>,
    multi_bounce: bool,
    tile: usize,
    progress: Option<&PyProgress>,
) -> PyResult<PyLayout> {
    let profile = parse_profile(profile)?;
    if views.is_empty() {
        return Err(input_error("views: give at least one View"));
    }
    let views = views_of(&views);
    let model = fit.map(PyFit::cell_model).transpose()?.cloned();
    let cell_px = cell_px.unwrap_or_else(|| model.as_ref().map_or(16, |m| m.cell_px));
    let radius = default_radius(scene, radius);
    let params = refine::RefineParams {
        layout: LayoutParams {
            budget,
            alpha,
            cell_px,
            light_rays,
            seed,
            // Multi-bounce layouts trace every bounce of the off-screen light paths too.
            bounces: bounces.unwrap_or(if multi_bounce { vpl::MAX_BOUNCES } else { 1 }),
            multi_bounce,
        },
        eval: EvalParams {
            profile,
            radius,
            tile,
        },
        stride,
        max_iterations: iterations,
        tolerance,
        step,
    };
    let s = Arc::clone(&scene.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let iterate = iterate && views.iter().all(|v| v.indirect.is_some());
    let out = run(py, move || {
        let refs: Vec<&View> = views.iter().map(|v| v.as_ref()).collect();
        let predicted = model
            .as_ref()
            .map(|m| {
                refs.iter()
                    .map(|v| m.predict_view(v))
                    .collect::<Result<Vec<_>, _>>()
            })
            .transpose()?;
        if iterate {
            let r = refine::refine(&s, &refs, predicted.as_deref(), &params, prog.as_deref())?;
            let best = r.iterations[r.best].allocation.clone();
            Ok(PyLayoutParts {
                vpls: r.vpls,
                strata: r.strata,
                allocation: best,
                errors: r.iterations.iter().map(|i| i.error).collect(),
                best: Some(r.best),
                seconds: r.iterations.iter().map(|i| i.seconds).collect(),
                shadow_rays: r.iterations.iter().map(|i| i.shadow_rays).collect(),
                reused_rays: r.iterations.iter().map(|i| i.reused_rays).collect(),
            })
        } else {
            let (vpls, allocation, strata) =
                vplace_core::layout::layout(&s, &refs, predicted.as_deref(), &params.layout)?;
            Ok(PyLayoutParts {
                vpls,
                strata,
                allocation,
                errors: Vec::new(),
                best: None,
                seconds: Vec::new(),
                shadow_rays: Vec::new(),
                reused_rays: Vec::new(),
            })
        }
    })?;
    Ok(PyLayout {
        vpls: PyVplSet::new_checked(out.vpls, profile, radius)?,
        strata: out.strata,
        allocation: out.allocation,
        errors: out.errors,
        best: out.best,
        seconds: out.seconds,
        shadow_rays: out.shadow_rays,
        reused_rays: out.reused_rays,
    })
}

/// What the GIL-free part of `layout` hands back.
struct PyLayoutParts {
    vpls: Vec<vpl::Vpl>,
    strata: Strata,
    allocation: Allocation,
    errors: Vec<f64>,
    best: Option<usize>,
    seconds: Vec<f64>,
    shadow_rays: Vec<u64>,
    reused_rays: Vec<u64>,
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLayout>()?;
    m.add_function(wrap_pyfunction!(layout, m)?)?;
    Ok(())
}
