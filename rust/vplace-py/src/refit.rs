//! The optional refit of VPL powers against the indirect image.

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;
use vplace_core::refit::{refit as refit_vpls, RefitParams};

use crate::arrays::{array, slice, GBufferArrays};
use crate::errors::run;
use crate::scene::{parse_profile, read_vpls, vpls_to_dict, PyProgress, PyScene};

/// Non-negative least squares on the VPL powers against `indirect` (float32 (H, W, 3), the
/// indirect image `gi - direct`) over the covered pixels of every `stride`-th row and column,
/// pulled toward scale 1 by `ridge` (relative to the mean diagonal of `A^T A`; the default is
/// `RefitParams::DEFAULT.ridge`, written out for the text signature). Returns a dict:
/// `position`, `normal`, `flux` (refitted) float32 (n, 3), `scales` float64 (n,),
/// `error_before`, `error_after` (RMSE, linear RGB, on the strided pixels), `pixels`,
/// `shadow_rays`, `exchanges`, `seconds`.
#[pyfunction]
#[pyo3(signature = (scene, position, normal, albedo, covered, vpl_position, vpl_normal, vpl_flux,
    indirect, *, stride = 4, ridge = 0.1, profile = "cosine",
    r_min = 0.01, progress = None))]
#[allow(clippy::too_many_arguments)]
fn refit<'py>(
    py: Python<'py>,
    scene: &PyScene,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    vpl_position: &Bound<'py, PyAny>,
    vpl_normal: &Bound<'py, PyAny>,
    vpl_flux: &Bound<'py, PyAny>,
    indirect: &Bound<'py, PyAny>,
    stride: usize,
    ridge: f64,
    profile: &str,
    r_min: f32,
    progress: Option<&PyProgress>,
) -> PyResult<Bound<'py, PyDict>> {
    let profile = parse_profile(profile)?;
    let arrays = GBufferArrays::read(position, normal, albedo, covered)?;
    let vpls = read_vpls(vpl_position, vpl_normal, vpl_flux)?;
    let ind = array::<f32>(indirect, "indirect", &arrays.img3(), "float32")?;
    let target = slice(&ind, "indirect")?;
    let g = arrays.gbuffer()?;
    let params = RefitParams {
        profile,
        r_min,
        stride,
        ridge,
    };
    let s = Arc::clone(&scene.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let r = run(py, move || {
        refit_vpls(&s, &g, &vpls, target, &params, prog.as_deref())
    })?;
    let d = vpls_to_dict(py, &r.vpls)?;
    d.set_item("scales", PyArray1::from_vec(py, r.scales))?;
    d.set_item("error_before", r.error_before)?;
    d.set_item("error_after", r.error_after)?;
    d.set_item("pixels", r.pixels)?;
    d.set_item("shadow_rays", r.shadow_rays)?;
    d.set_item("exchanges", r.exchanges)?;
    d.set_item("seconds", r.seconds)?;
    Ok(d)
}

/// Registers this file's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(refit, m)?)?;
    Ok(())
}
