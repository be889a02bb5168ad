//! `direct_light`: the direct-light estimator over a view (Cycles' DiffDir without Blender).

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::shade::direct::{self, DirectParams};

use crate::errors::run;
use crate::scene::{PyProgress, PyScene};
use crate::view::PyView;

/// The direct irradiance over pi at every covered pixel of `view` from every light source of
/// `scene` (lights, world, emissive triangles), with shadow rays: float32 (H, W, 3), what
/// Cycles' `Diffuse Direct` pass holds on a diffuse surface (0 on uncovered pixels).
/// `samples` per pixel and emitter for the sampled kinds (area lights, radii, sun angles, the
/// world, emissive triangles; the exact kinds take one ray); deterministic for `seed`.
#[pyfunction]
#[pyo3(signature = (scene, view, *, samples=64, seed=0, progress=None))]
fn direct_light<'py>(
    py: Python<'py>,
    scene: &PyScene,
    view: &PyView,
    samples: usize,
    seed: u64,
    progress: Option<&PyProgress>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = Arc::clone(&scene.inner);
    let v = Arc::clone(&view.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let (h, w) = (v.height, v.width);
    let params = DirectParams { samples, seed };
    let (image, _) = run(py, move || {
        direct::direct_light(&s, &v.gbuffer(), &params, prog.as_deref())
    })?;
    Ok(PyArray1::from_vec(py, image).reshape([h, w, 3])?.into_any())
}

/// Registers this file's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(direct_light, m)?)?;
    m.add("MAX_DIRECT_SAMPLES", direct::MAX_SAMPLES)?;
    Ok(())
}
