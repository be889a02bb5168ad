//! The layout (strata, allocation, iteration) over one or more views: `layout` and `Layout`.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::{
    layout::request::{lay_out, Iteration, LayoutRequest},
    layout::{Allocation, IndirectSource, Strata},
    view::View,
};

use crate::errors::{input_error, run};
use crate::fit::PyFit;
use crate::params::PyLayoutParams;
use crate::scene::{PyProgress, PyScene};
use crate::view::{views_of, PyView};
use crate::vpls::PyVplSet;

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
    iteration: Iteration,
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

    /// The factor the VPLs drawn from the pixels carry their emitters' flux by: the direct light
    /// the light paths' first hits say the seen surfaces receive over what the pixels'
    /// footprints give (1 where the two agree within the hits' noise;
    /// `vplace_core::layout::pixel_flux_scale`).
    #[getter]
    fn pixel_flux_scale(&self) -> f32 {
        self.strata.pixel_flux_scale
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

    /// Whether the iteration ran: `"ran"`, `"off"` (not asked for) or `"no indirect image in
    /// view <i>"` (asked for, but a view had no indirect image to compare with).
    #[getter]
    fn iteration(&self) -> String {
        match self.iteration {
            Iteration::Runs => "ran".to_owned(),
            Iteration::Off => "off".to_owned(),
            Iteration::NoIndirect { view } => format!("no indirect image in view {view}"),
        }
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

/// Lays out VPLs for `views` as `params` asks (see `vplace.layout`); the core resolves what
/// `params` leaves open and says whether the iteration ran (`Layout.iteration`).
#[pyfunction]
#[pyo3(signature = (scene, views, params = None, *, fit = None, progress = None))]
fn layout(
    py: Python<'_>,
    scene: &PyScene,
    views: Vec<Bound<'_, PyView>>,
    params: Option<&PyLayoutParams>,
    fit: Option<&PyFit>,
    progress: Option<&PyProgress>,
) -> PyResult<PyLayout> {
    if views.is_empty() {
        return Err(input_error("views: give at least one View"));
    }
    let request = params.map_or(LayoutRequest::DEFAULT, |p| p.inner);
    let views = views_of(&views);
    let model = fit.map(PyFit::cell_model).transpose()?.cloned();
    let s = Arc::clone(&scene.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let out = run(py, move || {
        let refs: Vec<&View> = views.iter().map(|v| v.as_ref()).collect();
        lay_out(&s, &refs, model.as_ref(), &request, prog.as_deref())
    })?;
    let eval = out.params.eval;
    Ok(PyLayout {
        vpls: PyVplSet::new_checked(out.vpls, eval.profile, eval.radius)?,
        strata: out.strata,
        allocation: out.allocation,
        errors: out.iterations.iter().map(|i| i.error).collect(),
        best: out.best,
        seconds: out.iterations.iter().map(|i| i.seconds).collect(),
        shadow_rays: out.iterations.iter().map(|i| i.shadow_rays).collect(),
        reused_rays: out.iterations.iter().map(|i| i.reused_rays).collect(),
        iteration: out.iteration,
    })
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLayout>()?;
    m.add_function(wrap_pyfunction!(layout, m)?)?;
    Ok(())
}
