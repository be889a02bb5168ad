//! `Scene`, `Light`, `Progress`, uniform VPLs, the evaluator and the metrics.

use glam::Vec3;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use vplace_core::{
    evaluator::{self, EvalParams},
    metrics,
    scene::{Light, LightKind, Scene},
    vpl::{self, Profile, Vpl},
};

use crate::arrays::{array, slice, Dim, GBufferArrays};
use crate::errors::{input_error, run};

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

pub fn parse_profile(profile: &str) -> PyResult<Profile> {
    match profile {
        "cosine" => Ok(Profile::Cosine),
        "omni" => Ok(Profile::Omni),
        other => Err(input_error(format!(
            "profile must be 'cosine' or 'omni', got {other:?}"
        ))),
    }
}

pub fn vpls_to_dict<'py>(py: Python<'py>, vpls: &[Vpl]) -> PyResult<Bound<'py, PyDict>> {
    let n = vpls.len();
    let flat =
        |f: fn(&Vpl) -> Vec3| -> Vec<f32> { vpls.iter().flat_map(|v| f(v).to_array()).collect() };
    let d = PyDict::new(py);
    d.set_item(
        "position",
        PyArray1::from_vec(py, flat(|v| v.position)).reshape([n, 3])?,
    )?;
    d.set_item(
        "normal",
        PyArray1::from_vec(py, flat(|v| v.normal)).reshape([n, 3])?,
    )?;
    d.set_item(
        "flux",
        PyArray1::from_vec(py, flat(|v| v.flux)).reshape([n, 3])?,
    )?;
    Ok(d)
}

/// Keller's instant radiosity: `n` VPLs from light paths of the scene's lights, a VPL at each
/// of a path's first `bounces` surface hits (1: first hits only; Russian roulette ends paths).
/// Returns a dict of float32 arrays `position`, `normal`, `flux`, each (n, 3).
#[pyfunction]
#[pyo3(signature = (scene, n, seed = 0, bounces = 1))]
fn uniform_vpls<'py>(
    py: Python<'py>,
    scene: &PyScene,
    n: usize,
    seed: u64,
    bounces: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let s = Arc::clone(&scene.inner);
    let vpls = run(py, move || vpl::light_path_vpls(&s, n, seed, bounces))?;
    vpls_to_dict(py, &vpls)
}

/// Reads a VPL set given as three (N, 3) float32 arrays.
pub fn read_vpls(
    position: &Bound<'_, PyAny>,
    normal: &Bound<'_, PyAny>,
    flux: &Bound<'_, PyAny>,
) -> PyResult<Vec<Vpl>> {
    let p = array::<f32>(position, "vpl_position", &[Dim::Any, Dim::Is(3)], "float32")?;
    let n = p.shape()[0];
    let nn = array::<f32>(normal, "vpl_normal", &[Dim::Is(n), Dim::Is(3)], "float32")?;
    let f = array::<f32>(flux, "vpl_flux", &[Dim::Is(n), Dim::Is(3)], "float32")?;
    let (p, nn, f) = (
        slice(&p, "vpl_position")?,
        slice(&nn, "vpl_normal")?,
        slice(&f, "vpl_flux")?,
    );
    Ok((0..n)
        .map(|i| Vpl {
            position: Vec3::from_slice(&p[3 * i..]),
            normal: Vec3::from_slice(&nn[3 * i..]),
            flux: Vec3::from_slice(&f[3 * i..]),
        })
        .collect())
}

/// The indirect image (H, W, 3) float32 of a VPL set over a G-buffer, and a stats dict
/// (`shadow_rays`, `pairs`, `seconds`, `rays_per_second`). `brute_force` traces shadow rays
/// against every triangle instead of the BVH (same image; a benchmark baseline).
#[pyfunction]
#[pyo3(signature = (scene, position, normal, albedo, covered, vpl_position, vpl_normal, vpl_flux,
    profile = "cosine", r_min = 0.01, tile = 16, progress = None, brute_force = false))]
#[allow(clippy::too_many_arguments)]
fn evaluate<'py>(
    py: Python<'py>,
    scene: &PyScene,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    vpl_position: &Bound<'py, PyAny>,
    vpl_normal: &Bound<'py, PyAny>,
    vpl_flux: &Bound<'py, PyAny>,
    profile: &str,
    r_min: f32,
    tile: usize,
    progress: Option<&PyProgress>,
    brute_force: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let profile = parse_profile(profile)?;
    let arrays = GBufferArrays::read(position, normal, albedo, covered)?;
    let (h, w) = (arrays.height, arrays.width);
    let vpls = read_vpls(vpl_position, vpl_normal, vpl_flux)?;
    let g = arrays.gbuffer()?;
    let params = EvalParams {
        profile,
        r_min,
        tile,
    };
    let s = Arc::clone(&scene.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let (image, stats) = run(py, move || {
        if brute_force {
            evaluator::evaluate_brute_force(&s, &g, &vpls, &params, prog.as_deref())
        } else {
            evaluator::evaluate(&s, &g, &vpls, &params, prog.as_deref())
        }
    })?;
    let out = PyArray1::from_vec(py, image).reshape([h, w, 3])?.into_any();
    let d = PyDict::new(py);
    d.set_item("shadow_rays", stats.shadow_rays)?;
    d.set_item("pairs", stats.pairs)?;
    d.set_item("seconds", stats.seconds)?;
    d.set_item("rays_per_second", stats.rays_per_second())?;
    Ok((out, d))
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

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLight>()?;
    m.add_class::<PyScene>()?;
    m.add_class::<PyProgress>()?;
    m.add_function(wrap_pyfunction!(uniform_vpls, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(rmse, m)?)?;
    m.add_function(wrap_pyfunction!(relative_mse, m)?)?;
    m.add("VPL_SURFACE_OFFSET", vpl::Vpl::SURFACE_OFFSET)?;
    m.add("MAX_BOUNCES", vpl::MAX_BOUNCES)?;
    Ok(())
}
