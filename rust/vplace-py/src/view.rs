//! `View`: one captured view, checked once (`vplace_core::view`).

use glam::{Mat4, Vec3};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::view::{Camera, GBuffer, View, ViewInput};

use crate::arrays::{array, slice, Dim};
use crate::errors::run;

/// One captured view: the G-buffer, the lighting passes and the camera, checked once.
#[pyclass(name = "View", module = "vplace._native", frozen)]
pub struct PyView {
    pub inner: Arc<View>,
}

/// A float32 (H, W, C) or (H, W) numpy copy of `data`.
fn image<'py>(
    py: Python<'py>,
    data: &[f32],
    h: usize,
    w: usize,
    c: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let a = PyArray1::from_slice(py, data);
    Ok(if c == 1 {
        a.reshape([h, w])?.into_any()
    } else {
        a.reshape([h, w, c])?.into_any()
    })
}

#[pymethods]
impl PyView {
    /// Checks and copies the passes of one view (see `vplace.View`).
    #[new]
    #[pyo3(signature = (*, position, normal, albedo, covered, depth, direct, diffuse_direct,
        camera_position, world_to_clip, diffuse_indirect = None, indirect = None,
        specular = None, diffuse_color = None, name = "view"))]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        py: Python<'py>,
        position: &Bound<'py, PyAny>,
        normal: &Bound<'py, PyAny>,
        albedo: &Bound<'py, PyAny>,
        covered: &Bound<'py, PyAny>,
        depth: &Bound<'py, PyAny>,
        direct: &Bound<'py, PyAny>,
        diffuse_direct: &Bound<'py, PyAny>,
        camera_position: [f32; 3],
        world_to_clip: [[f32; 4]; 4],
        diffuse_indirect: Option<&Bound<'py, PyAny>>,
        indirect: Option<&Bound<'py, PyAny>>,
        specular: Option<&Bound<'py, PyAny>>,
        diffuse_color: Option<&Bound<'py, PyAny>>,
        name: &str,
    ) -> PyResult<Self> {
        let pos = array::<f32>(
            position,
            "position",
            &[Dim::Any, Dim::Any, Dim::Is(3)],
            "float32",
        )?;
        let (h, w) = (pos.shape()[0], pos.shape()[1]);
        let img3 = [Dim::Is(h), Dim::Is(w), Dim::Is(3)];
        let img1 = [Dim::Is(h), Dim::Is(w)];
        let nrm = array::<f32>(normal, "normal", &img3, "float32")?;
        let alb = array::<f32>(albedo, "albedo", &img3, "float32")?;
        let cov = array::<bool>(covered, "covered", &img1, "bool")?;
        let dep = array::<f32>(depth, "depth", &img1, "float32")?;
        let dir = array::<f32>(direct, "direct", &img3, "float32")?;
        let dd = array::<f32>(diffuse_direct, "diffuse_direct", &img3, "float32")?;
        let optional = |a: Option<&Bound<'py, PyAny>>, what: &str| {
            a.map(|a| array::<f32>(a, what, &img3, "float32"))
                .transpose()
        };
        let di = optional(diffuse_indirect, "diffuse_indirect")?;
        let ind = optional(indirect, "indirect")?;
        let spec = optional(specular, "specular")?;
        let diff = optional(diffuse_color, "diffuse_color")?;
        let input = ViewInput {
            name,
            gbuffer: GBuffer {
                width: w,
                height: h,
                position: slice(&pos, "position")?,
                normal: slice(&nrm, "normal")?,
                albedo: slice(&alb, "albedo")?,
                covered: slice(&cov, "covered")?,
            },
            depth: slice(&dep, "depth")?,
            direct: slice(&dir, "direct")?,
            diffuse_direct: slice(&dd, "diffuse_direct")?,
            diffuse_indirect: di
                .as_ref()
                .map(|a| slice(a, "diffuse_indirect"))
                .transpose()?,
            indirect: ind.as_ref().map(|a| slice(a, "indirect")).transpose()?,
            specular: spec.as_ref().map(|a| slice(a, "specular")).transpose()?,
            diffuse_color: diff
                .as_ref()
                .map(|a| slice(a, "diffuse_color"))
                .transpose()?,
            camera: Camera {
                position: Vec3::from_array(camera_position),
                // Rows as numpy and Blender write them.
                world_to_clip: Mat4::from_cols_array_2d(&world_to_clip).transpose(),
            },
        };
        let view = run(py, move || View::new(&input))?;
        Ok(Self {
            inner: Arc::new(view),
        })
    }

    /// The same view without its global-illumination passes (`diffuse_indirect`, `indirect`):
    /// what a view the model has not seen provides.
    fn without_indirect(&self) -> Self {
        Self {
            inner: Arc::new(self.inner.without_indirect()),
        }
    }

    /// The same view with only the covered pixels that `mask` ((H, W) bool) marks still
    /// covered: what `evaluate` then shades, the rest left black.
    fn restricted(&self, py: Python<'_>, mask: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (h, w) = (self.inner.height, self.inner.width);
        let checked = array::<bool>(mask, "mask", &[Dim::Is(h), Dim::Is(w)], "bool")?;
        let keep = slice(&checked, "mask")?.to_vec();
        let v = Arc::clone(&self.inner);
        let inner = run(py, move || v.restricted(&keep))?;
        Ok(Self {
            inner: Arc::new(inner),
        })
    }

    /// The view's name.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.name
    }

    /// Image width, pixels.
    #[getter]
    fn width(&self) -> usize {
        self.inner.width
    }

    /// Image height, pixels.
    #[getter]
    fn height(&self) -> usize {
        self.inner.height
    }

    /// Covered pixels masked because a lighting pass held NaN or inf there.
    #[getter]
    fn masked_pixels(&self) -> usize {
        self.inner.masked_pixels
    }

    /// True when the view has its indirect image (it can be fitted, iterated and refitted on).
    #[getter]
    fn has_indirect(&self) -> bool {
        self.inner.indirect.is_some()
    }

    /// Camera position, world space.
    #[getter]
    fn camera_position(&self) -> [f32; 3] {
        self.inner.camera.position.to_array()
    }

    /// World-to-clip matrix (4, 4) float32, row-major, as given to the constructor.
    #[getter]
    fn world_to_clip<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let rows = self.inner.camera.world_to_clip.transpose().to_cols_array();
        image(py, &rows, 4, 4, 1)
    }

    /// World position (H, W, 3), a copy.
    #[getter]
    fn position<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = &self.inner;
        image(py, &v.position, v.height, v.width, 3)
    }

    /// Shading normal (H, W, 3), a copy.
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = &self.inner;
        image(py, &v.normal, v.height, v.width, 3)
    }

    /// Diffuse albedo (H, W, 3), a copy.
    #[getter]
    fn albedo<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = &self.inner;
        image(py, &v.albedo, v.height, v.width, 3)
    }

    /// Covered pixels after masking (H, W) bool, a copy.
    #[getter]
    fn covered<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let v = &self.inner;
        Ok(PyArray1::from_slice(py, &v.covered)
            .reshape([v.height, v.width])?
            .into_any())
    }

    /// The target indirect image (H, W, 3), or None.
    #[getter]
    fn indirect<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let v = &self.inner;
        v.indirect
            .as_deref()
            .map(|a| image(py, a, v.height, v.width, 3))
            .transpose()
    }

    fn __repr__(&self) -> String {
        let v = &self.inner;
        format!(
            "View({:?}, {}x{}, {} covered pixels{})",
            v.name,
            v.width,
            v.height,
            v.covered_count(),
            if v.indirect.is_some() {
                ", with indirect"
            } else {
                ""
            }
        )
    }
}

/// The core views of a list of `View`s (at least one).
pub fn views_of(views: &[Bound<'_, PyView>]) -> Vec<Arc<View>> {
    views.iter().map(|v| Arc::clone(&v.get().inner)).collect()
}

/// Registers `View`.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyView>()
}
