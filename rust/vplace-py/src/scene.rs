//! `Scene`, `Light`, `Progress`, uniform VPLs, the evaluator and the metrics.

use glam::Vec3;
use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use vplace_core::{
    evaluator, metrics,
    scene::{Light, LightKind, Scene},
    LUMINANCE,
};

use crate::arrays::{array, slice, Dim};
use crate::errors::run;

fn vec3(v: [f32; 3]) -> Vec3 {
    Vec3::from_array(v)
}

fn vec3s(s: &[f32]) -> Vec<Vec3> {
    s.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// A light of the scene (see DESIGN, Coordinates and units). Build with the static methods.
#[pyclass(name = "Light", module = "vplace._native", frozen)]
#[derive(Clone)]
pub struct PyLight {
    pub inner: Light,
}

#[pymethods]
impl PyLight {
    /// A POINT light (radius 0) of RGB power `power` watts.
    #[staticmethod]
    fn point(position: [f32; 3], power: [f32; 3]) -> Self {
        Self {
            inner: Light::point(vec3(position), vec3(power)),
        }
    }

    /// A SPOT light (blend 0) with cone half angle `half_angle` radians about `direction`.
    #[staticmethod]
    fn spot(position: [f32; 3], direction: [f32; 3], half_angle: f32, power: [f32; 3]) -> Self {
        Self {
            inner: Light::spot(vec3(position), vec3(direction), half_angle, vec3(power)),
        }
    }

    /// An AREA light emitting along `direction`; `size_x` along `tangent` (diameter of a disk).
    #[staticmethod]
    #[pyo3(signature = (position, direction, tangent, disk, size_x, size_y, power))]
    fn area(
        position: [f32; 3],
        direction: [f32; 3],
        tangent: [f32; 3],
        disk: bool,
        size_x: f32,
        size_y: f32,
        power: [f32; 3],
    ) -> Self {
        Self {
            inner: Light::area(
                vec3(position),
                vec3(direction),
                vec3(tangent),
                disk,
                size_x,
                size_y,
                vec3(power),
            ),
        }
    }

    /// A SUN travelling along `direction` with RGB irradiance `irradiance` W/m^2.
    #[staticmethod]
    fn sun(direction: [f32; 3], irradiance: [f32; 3]) -> Self {
        Self {
            inner: Light::sun(vec3(direction), vec3(irradiance)),
        }
    }

    /// `"point"`, `"spot"`, `"area"` or `"sun"`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.inner.kind {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Area { .. } => "area",
            LightKind::Sun => "sun",
        }
    }

    /// RGB power, watts (W/m^2 for a sun).
    #[getter]
    fn power(&self) -> [f32; 3] {
        self.inner.power.to_array()
    }

    fn __repr__(&self) -> String {
        format!(
            "Light.{}(power={:?})",
            self.kind(),
            self.inner.power.to_array()
        )
    }
}

/// Triangles, per-triangle materials and lights, with a BVH. Immutable once built.
#[pyclass(name = "Scene", module = "vplace._native", frozen)]
pub struct PyScene {
    pub inner: Arc<Scene>,
}

#[pymethods]
impl PyScene {
    /// Builds the scene. `vertices` float32 (V, 3), `triangles` uint32 (T, 3),
    /// `material_ids` uint32 (T,), `albedo` float32 (M, 3) in [0, 1], `lights` a list of Light.
    #[new]
    #[pyo3(signature = (vertices, triangles, material_ids, albedo, lights))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        material_ids: &Bound<'_, PyAny>,
        albedo: &Bound<'_, PyAny>,
        lights: Vec<Bound<'_, PyLight>>,
    ) -> PyResult<Self> {
        let v = array::<f32>(vertices, "vertices", &[Dim::Any, Dim::Is(3)], "float32")?;
        let t = array::<u32>(triangles, "triangles", &[Dim::Any, Dim::Is(3)], "uint32")?;
        let m = array::<u32>(material_ids, "material_ids", &[Dim::Any], "uint32")?;
        let a = array::<f32>(albedo, "albedo", &[Dim::Any, Dim::Is(3)], "float32")?;
        let verts = vec3s(slice(&v, "vertices")?);
        let tris: Vec<[u32; 3]> = slice(&t, "triangles")?
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let mats = slice(&m, "material_ids")?.to_vec();
        let alb = vec3s(slice(&a, "albedo")?);
        let lights: Vec<Light> = lights.iter().map(|l| l.get().inner).collect();
        let scene = run(py, move || Scene::build(&verts, &tris, &mats, &alb, lights))?;
        Ok(Self {
            inner: Arc::new(scene),
        })
    }

    /// Number of triangles.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.inner.triangle_count()
    }

    /// Number of lights.
    #[getter]
    fn light_count(&self) -> usize {
        self.inner.lights.len()
    }

    /// Number of zero-area triangles (kept; never hit).
    #[getter]
    fn degenerate_triangles(&self) -> usize {
        self.inner.degenerate_triangles
    }

    /// `(min, max)` corners of the geometry's bounds.
    #[getter]
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let (lo, hi) = self.inner.bounds();
        (lo.to_array(), hi.to_array())
    }

    /// Length of the bounds' diagonal, metres.
    #[getter]
    fn diagonal(&self) -> f32 {
        self.inner.diagonal()
    }

    /// The default near-field radius of the scene's VPLs, metres (`NEAR_FIELD_FRACTION` of
    /// the diagonal).
    #[getter]
    fn near_field_radius(&self) -> f32 {
        self.inner.near_field_radius()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(triangles={}, lights={})",
            self.inner.triangle_count(),
            self.inner.lights.len()
        )
    }
}

/// Progress and cancellation of a long call. Pass it in, poll `done` / `total` from another
/// thread, call `cancel()` to stop the call (it then raises CancelledError).
#[pyclass(name = "Progress", module = "vplace._native", frozen)]
#[derive(Default)]
pub struct PyProgress {
    pub inner: Arc<evaluator::Progress>,
}

#[pymethods]
impl PyProgress {
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// Work items finished.
    #[getter]
    fn done(&self) -> usize {
        self.inner.done.load(Ordering::Relaxed)
    }

    /// Work items in all (0 until the work starts).
    #[getter]
    fn total(&self) -> usize {
        self.inner.total.load(Ordering::Relaxed)
    }

    /// Asks the running call to stop.
    fn cancel(&self) {
        self.inner.cancel.store(true, Ordering::Relaxed);
    }

    /// True once `cancel()` was called.
    #[getter]
    fn cancelled(&self) -> bool {
        self.inner.cancel.load(Ordering::Relaxed)
    }
}

fn pair<'py>(
    image: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
) -> PyResult<(Vec<f32>, Vec<f32>)> {
    let r = array::<f32>(
        reference,
        "reference",
        &[Dim::Any, Dim::Any, Dim::Is(3)],
        "float32",
    )?;
    let dims: Vec<Dim> = r.shape().iter().map(|&s| Dim::Is(s)).collect();
    let i = array::<f32>(image, "image", &dims, "float32")?;
    Ok((
        slice(&i, "image")?.to_vec(),
        slice(&r, "reference")?.to_vec(),
    ))
}

/// Root mean squared error of `image` against `reference`, both float32 (H, W, 3), linear HDR.
#[pyfunction]
fn rmse(py: Python<'_>, image: &Bound<'_, PyAny>, reference: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (a, b) = pair(image, reference)?;
    run(py, move || metrics::rmse(&a, &b))
}

/// Relative MSE `mean((a - b)^2 / (b^2 + 0.01))` of `image` against `reference`, (H, W, 3).
#[pyfunction]
fn relative_mse(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    reference: &Bound<'_, PyAny>,
) -> PyResult<f64> {
    let (a, b) = pair(image, reference)?;
    run(py, move || metrics::relative_mse(&a, &b))
}

/// SSIM of `image` against `reference`, both float32 (H, W, 3) linear HDR, on the display
/// luminance (exposure 1, clamp to [0, 1], sRGB), Gaussian window 11, sigma 1.5, K1 0.01,
/// K2 0.03. H and W must be at least 11.
#[pyfunction]
fn ssim(py: Python<'_>, image: &Bound<'_, PyAny>, reference: &Bound<'_, PyAny>) -> PyResult<f64> {
    let r = array::<f32>(
        reference,
        "reference",
        &[Dim::Any, Dim::Any, Dim::Is(3)],
        "float32",
    )?;
    let (h, w) = (r.shape()[0], r.shape()[1]);
    let i = array::<f32>(
        image,
        "image",
        &[Dim::Is(h), Dim::Is(w), Dim::Is(3)],
        "float32",
    )?;
    let (a, b) = (slice(&i, "image")?, slice(&r, "reference")?);
    run(py, move || metrics::ssim(a, b, w, h))
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLight>()?;
    m.add_class::<PyScene>()?;
    m.add_class::<PyProgress>()?;
    m.add_function(wrap_pyfunction!(rmse, m)?)?;
    m.add_function(wrap_pyfunction!(relative_mse, m)?)?;
    m.add_function(wrap_pyfunction!(ssim, m)?)?;
    m.add("LUMINANCE", LUMINANCE.to_array())?;
    m.add(
        "NEAR_FIELD_FRACTION",
        vplace_core::shading::NEAR_FIELD_FRACTION,
    )?;
    Ok(())
}
