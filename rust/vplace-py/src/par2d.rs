//! `Scene2D`: analytic 2D direct lighting (PAR, the exact sweep, Monte Carlo).

use std::sync::Arc;

use glam::DVec2;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use vplace_core::par2d::{Bounds2, Method, Scene2d};

use crate::arrays::{array, slice, Dim};
use crate::errors::{input_error, run};
use crate::scene::PyProgress;

fn parse_method(method: &str, rays: u32, seed: u64) -> PyResult<Method> {
    match method {
        "par" => Ok(Method::Par),
        "exact" => Ok(Method::Exact),
        "monte_carlo" => Ok(Method::MonteCarlo { rays, seed }),
        other => Err(input_error(format!(
            "method must be \"par\", \"exact\" or \"monte_carlo\", got {other:?}"
        ))),
    }
}

/// Convex polygons, each a light (emission not all zero) or an occluder (emission zero).
/// `vertices` float64 (V, 2), all polygons one after another; `counts` the number of vertices
/// of each polygon (summing to V); `emission` float64 (P, 3), `>= 0`. Immutable once built.
#[pyclass(name = "Scene2D", module = "vplace._native", frozen)]
pub struct PyScene2d {
    inner: Arc<Scene2d>,
}

#[pymethods]
impl PyScene2d {
    #[new]
    #[pyo3(signature = (vertices, counts, emission))]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        counts: Vec<usize>,
        emission: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let v = array::<f64>(vertices, "vertices", &[Dim::Any, Dim::Is(2)], "float64")?;
        let e = array::<f64>(emission, "emission", &[Dim::Any, Dim::Is(3)], "float64")?;
        let v = slice(&v, "vertices")?.to_vec();
        let e = slice(&e, "emission")?.to_vec();
        let scene = run(py, move || Scene2d::from_flat(&v, &counts, &e))?;
        Ok(Self {
            inner: Arc::new(scene),
        })
    }

    /// Number of polygons.
    #[getter]
    fn polygon_count(&self) -> usize {
        self.inner.len()
    }

    /// Number of lights.
    #[getter]
    fn light_count(&self) -> usize {
        self.inner.light_count()
    }

    /// The cleaned vertices (counter-clockwise, float64 (n, 2)) of polygon `index`.
    fn polygon<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyAny>> {
        let polys = self.inner.polygons();
        let p = polys.get(index).ok_or_else(|| {
            input_error(format!(
                "polygon index {index} is out of bounds for {} polygons",
                polys.len()
            ))
        })?;
        let flat: Vec<f64> = p.vertices().iter().flat_map(|v| [v.x, v.y]).collect();
        let n = p.vertices().len();
        Ok(PyArray1::from_vec(py, flat).reshape([n, 2])?.into_any())
    }

    /// Fluence / 2 pi at `points` float64 (N, 2); returns float64 (N, 3).
    #[pyo3(signature = (points, method = "exact", rays = 1024, seed = 0, progress = None))]
    fn irradiance<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        method: &str,
        rays: u32,
        seed: u64,
        progress: Option<&PyProgress>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let method = parse_method(method, rays, seed)?;
        let a = array::<f64>(points, "points", &[Dim::Any, Dim::Is(2)], "float64")?;
        let n = a.shape()[0];
        let pts: Vec<DVec2> = slice(&a, "points")?
            .chunks_exact(2)
            .map(|c| DVec2::new(c[0], c[1]))
            .collect();
        let s = Arc::clone(&self.inner);
        let prog = progress.map(|p| Arc::clone(&p.inner));
        let out = run(py, move || s.irradiance(&pts, method, prog.as_deref()))?;
        let flat: Vec<f64> = out.into_iter().flatten().collect();
        Ok(PyArray1::from_vec(py, flat).reshape([n, 3])?.into_any())
    }

    /// A (height, width, 3) float64 light map of `bounds` = (xmin, ymin, xmax, ymax), row 0 at
    /// the top (largest y), pixel centres sampled.
    #[pyo3(signature = (bounds, width, height, method = "exact", rays = 1024, seed = 0, progress = None))]
    #[allow(clippy::too_many_arguments)]
    fn light_map<'py>(
        &self,
        py: Python<'py>,
        bounds: [f64; 4],
        width: usize,
        height: usize,
        method: &str,
        rays: u32,
        seed: u64,
        progress: Option<&PyProgress>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let method = parse_method(method, rays, seed)?;
        let b = Bounds2 {
            min: DVec2::new(bounds[0], bounds[1]),
            max: DVec2::new(bounds[2], bounds[3]),
        };
        let s = Arc::clone(&self.inner);
        let prog = progress.map(|p| Arc::clone(&p.inner));
        let img = run(py, move || {
            s.light_map(b, width, height, method, prog.as_deref())
        })?;
        Ok(PyArray1::from_vec(py, img)
            .reshape([height, width, 3])?
            .into_any())
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene2D(polygons={}, lights={})",
            self.inner.len(),
            self.inner.light_count()
        )
    }
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene2d>()?;
    Ok(())
}
