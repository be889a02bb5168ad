//! `TextureMap`, `AlphaTest` and the checked conversion of a scene's textured materials (UVs,
//! textures, per-material maps) for `Scene`.

use glam::{Vec2, Vec3};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use vplace_core::{
    scene::texture::{linear_rgba, AlphaSource, AlphaTest, CodeTable, Texture, TextureRef, Wrap},
    scene::{Gloss, Material},
};

use crate::arrays::{array, slice, Dim};
use crate::errors::{input_error, run};

/// How a material reads one of the scene's textures: `uv' = uv * uv_scale + uv_offset`, then a
/// bilinear lookup with `wrap` ("repeat" or "extend") past the edges.
#[pyclass(name = "TextureMap", module = "vplace._native", frozen)]
#[derive(Clone)]
pub struct PyTextureMap {
    pub inner: TextureRef,
}

fn wrap_name(w: Wrap) -> &'static str {
    match w {
        Wrap::Repeat => "repeat",
        Wrap::Extend => "extend",
    }
}

#[pymethods]
impl PyTextureMap {
    #[new]
    #[pyo3(signature = (texture, *, uv_scale = (1.0, 1.0), uv_offset = (0.0, 0.0), wrap = "repeat"))]
    fn new(
        texture: u32,
        uv_scale: (f32, f32),
        uv_offset: (f32, f32),
        wrap: &str,
    ) -> PyResult<Self> {
        let wrap = match wrap {
            "repeat" => Wrap::Repeat,
            "extend" => Wrap::Extend,
            other => {
                return Err(input_error(format!(
                    "wrap must be \"repeat\" or \"extend\", got {other:?}"
                )))
            }
        };
        Ok(Self {
            inner: TextureRef {
                texture,
                uv_scale: Vec2::new(uv_scale.0, uv_scale.1),
                uv_offset: Vec2::new(uv_offset.0, uv_offset.1),
                wrap,
            },
        })
    }

    /// Index into the scene's textures.
    #[getter]
    fn texture(&self) -> u32 {
        self.inner.texture
    }

    /// `(scale_u, scale_v)`.
    #[getter]
    fn uv_scale(&self) -> (f32, f32) {
        self.inner.uv_scale.into()
    }

    /// `(offset_u, offset_v)`.
    #[getter]
    fn uv_offset(&self) -> (f32, f32) {
        self.inner.uv_offset.into()
    }

    /// `"repeat"` or `"extend"`.
    #[getter]
    fn wrap(&self) -> &'static str {
        wrap_name(self.inner.wrap)
    }

    fn __repr__(&self) -> String {
        let r = &self.inner;
        format!(
            "TextureMap({}, uv_scale={:?}, uv_offset={:?}, wrap={:?})",
            r.texture,
            r.uv_scale.to_array(),
            r.uv_offset.to_array(),
            wrap_name(r.wrap)
        )
    }
}

/// An alpha-tested surface: rays pass where `offset + scale * value < cutoff`, `value` the
/// texture's alpha channel (`source="alpha"`) or the luminance of its RGB
/// (`source="luminance"`) at the hit; without a texture the alpha is `offset`.
#[pyclass(name = "AlphaTest", module = "vplace._native", frozen)]
#[derive(Clone)]
pub struct PyAlphaTest {
    pub inner: AlphaTest,
}

#[pymethods]
impl PyAlphaTest {
    #[new]
    #[pyo3(signature = (offset, scale = 0.0, texture = None, *, source = "alpha", cutoff = 0.5))]
    fn new(
        offset: f32,
        scale: f32,
        texture: Option<Bound<'_, PyTextureMap>>,
        source: &str,
        cutoff: f32,
    ) -> PyResult<Self> {
        let source = match source {
            "alpha" => AlphaSource::Alpha,
            "luminance" => AlphaSource::Luminance,
            other => {
                return Err(input_error(format!(
                    "source must be \"alpha\" or \"luminance\", got {other:?}"
                )))
            }
        };
        Ok(Self {
            inner: AlphaTest {
                offset,
                scale,
                texture: texture.map(|t| t.get().inner),
                source,
                cutoff,
            },
        })
    }

    /// The alpha without a texture, or what the texture's value is added to.
    #[getter]
    fn offset(&self) -> f32 {
        self.inner.offset
    }

    /// Multiplies the texture's value.
    #[getter]
    fn scale(&self) -> f32 {
        self.inner.scale
    }

    /// The texture the alpha is read from, or None.
    #[getter]
    fn texture(&self) -> Option<PyTextureMap> {
        self.inner.texture.map(|inner| PyTextureMap { inner })
    }

    /// `"alpha"` or `"luminance"`.
    #[getter]
    fn source(&self) -> &'static str {
        match self.inner.source {
            AlphaSource::Alpha => "alpha",
            AlphaSource::Luminance => "luminance",
        }
    }

    /// Rays pass where the alpha is below this.
    #[getter]
    fn cutoff(&self) -> f32 {
        self.inner.cutoff
    }

    fn __repr__(&self) -> String {
        format!(
            "AlphaTest({}, {}, texture={}, source={:?}, cutoff={})",
            self.inner.offset,
            self.inner.scale,
            self.texture().map_or("None".into(), |t| t.__repr__()),
            self.source(),
            self.inner.cutoff
        )
    }
}

/// The optional material inputs of `Scene`, checked and converted.
pub struct Surfaces {
    pub uvs: Option<Vec<[Vec2; 3]>>,
    pub textures: Vec<Texture>,
}

/// Checks `uvs` (float32 (T, 3, 2)) and `textures` (float32 (H, W, 3 or 4) each) and converts
/// them; the core checks the rest (finiteness, lengths against the triangles).
pub fn surfaces(
    uvs: Option<&Bound<'_, PyAny>>,
    textures: Option<Vec<Bound<'_, PyAny>>>,
) -> PyResult<Surfaces> {
    let uvs = match uvs {
        None => None,
        Some(u) => {
            let a = array::<f32>(u, "uvs", &[Dim::Any, Dim::Is(3), Dim::Is(2)], "float32")?;
            let corners = slice(&a, "uvs")?
                .chunks_exact(6)
                .map(|c| {
                    [
                        Vec2::new(c[0], c[1]),
                        Vec2::new(c[2], c[3]),
                        Vec2::new(c[4], c[5]),
                    ]
                })
                .collect();
            Some(corners)
        }
    };
    let mut out = Vec::new();
    for (i, t) in textures.unwrap_or_default().iter().enumerate() {
        let name = format!("textures[{i}]");
        let a = array::<f32>(t, &name, &[Dim::Any, Dim::Any, Dim::Any], "float32")?;
        let shape = a.shape().to_vec();
        if shape[2] != 3 && shape[2] != 4 {
            return Err(input_error(format!(
                "{name} must have shape (H, W, 3) or (H, W, 4), got {shape:?}"
            )));
        }
        let texture = Texture::new(&name, shape[1], shape[0], shape[2], slice(&a, &name)?)
            .map_err(crate::errors::to_py)?;
        out.push(texture);
    }
    Ok(Surfaces { uvs, textures: out })
}

/// The core materials: `albedo` (M x RGB) with the optional per-material `base_textures`,
/// `texture_tint` (float32 (M, 3)), `alpha_tests` (each a list of M entries, None for
/// none) and the glossy layers: `gloss` float32 (M, 3) with its `gloss_tint` (float32 (M, 3),
/// default 0) and `gloss_roughness` (float32 (M,), default 0.5); a material whose reflectance
/// and tint are all 0 has none.
pub fn materials(
    albedo: Vec<Vec3>,
    base_textures: Option<Vec<Option<Bound<'_, PyTextureMap>>>>,
    texture_tint: Option<&Bound<'_, PyAny>>,
    alpha_tests: Option<Vec<Option<Bound<'_, PyAlphaTest>>>>,
    gloss: Option<&Bound<'_, PyAny>>,
    gloss_tint: Option<&Bound<'_, PyAny>>,
    gloss_roughness: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<Material>> {
    let m = albedo.len();
    let check_len = |name: &str, len: usize| {
        if len == m {
            Ok(())
        } else {
            Err(input_error(format!(
                "{name} must have one entry per material ({m}, the rows of albedo), got {len}"
            )))
        }
    };
    let rows = |arr: Option<&Bound<'_, PyAny>>, name: &str, default: Vec3| -> PyResult<_> {
        let Some(t) = arr else {
            return Ok(vec![default; m]);
        };
        let a = array::<f32>(t, name, &[Dim::Is(m), Dim::Is(3)], "float32")?;
        Ok(slice(&a, name)?
            .chunks_exact(3)
            .map(Vec3::from_slice)
            .collect::<Vec<_>>())
    };
    let tint = rows(texture_tint, "texture_tint", Vec3::ONE)?;
    if gloss.is_none() && (gloss_tint.is_some() || gloss_roughness.is_some()) {
        return Err(input_error(
            "gloss_tint and gloss_roughness need gloss (the layer's reflectance)",
        ));
    }
    let layers = match gloss {
        None => vec![None; m],
        Some(g) => {
            let constant = rows(Some(g), "gloss", Vec3::ZERO)?;
            let tints = rows(gloss_tint, "gloss_tint", Vec3::ZERO)?;
            let rough = match gloss_roughness {
                None => vec![0.5; m],
                Some(r) => {
                    let a = array::<f32>(r, "gloss_roughness", &[Dim::Is(m)], "float32")?;
                    slice(&a, "gloss_roughness")?.to_vec()
                }
            };
            constant
                .into_iter()
                .zip(tints)
                .zip(rough)
                .map(|((constant, tint), roughness)| {
                    (constant != Vec3::ZERO || tint != Vec3::ZERO).then_some(Gloss {
                        constant,
                        tint,
                        roughness,
                    })
                })
                .collect()
        }
    };
    let maps = base_textures.unwrap_or_else(|| vec![None; m]);
    check_len("base_textures", maps.len())?;
    let alphas = alpha_tests.unwrap_or_else(|| vec![None; m]);
    check_len("alpha_tests", alphas.len())?;
    Ok(albedo
        .into_iter()
        .zip(maps)
        .zip(alphas)
        .zip(tint)
        .zip(layers)
        .map(|((((a, map), alpha), tint), gloss)| Material {
            texture: map.map(|t| t.get().inner),
            texture_tint: tint,
            alpha_test: alpha.map(|t| t.get().inner),
            gloss,
            ..Material::diffuse(a)
        })
        .collect())
}

/// An image as Blender's `Image.pixels` holds it, float32 `(height, width, channels)` with row
/// 0 at the bottom, as linear RGBA float32 `(height, width, 4)` with row 0 at the top, and the
/// mean of its texels (RGBA, float64 sums). `table`: float32 `(256,)`, the linear value of each
/// 8-bit code, for a byte image in a non-linear space (each RGB value `v` reads
/// `table[round(v * 255)]`); None keeps RGB. Alpha is the last channel where `alpha` and there
/// are 2 or 4 channels, else 1. `name` names the image in errors.
#[pyfunction]
#[pyo3(signature = (pixels, *, table=None, alpha=false, name="image"))]
fn linear_image<'py>(
    py: Python<'py>,
    pixels: &Bound<'py, PyAny>,
    table: Option<&Bound<'py, PyAny>>,
    alpha: bool,
    name: &str,
) -> PyResult<(Bound<'py, PyAny>, [f64; 4])> {
    let px = array::<f32>(pixels, "pixels", &[Dim::Any, Dim::Any, Dim::Any], "float32")?;
    let (height, width, channels) = {
        let s = px.shape();
        (s[0], s[1], s[2])
    };
    let values = slice(&px, "pixels")?.to_vec();
    let codes: Option<CodeTable> = match table {
        Some(t) => {
            let t = array::<f32>(t, "table", &[Dim::Is(256)], "float32")?;
            let mut codes = [0.0f32; 256];
            codes.copy_from_slice(slice(&t, "table")?);
            Some(codes)
        }
        None => None,
    };
    let what = name.to_owned();
    let (out, mean) = run(py, move || {
        linear_rgba(
            &what,
            width,
            height,
            channels,
            &values,
            codes.as_ref(),
            alpha,
        )
    })?;
    let image = PyArray1::from_vec(py, out).reshape([height, width, 4])?;
    Ok((image.into_any(), mean))
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTextureMap>()?;
    m.add_class::<PyAlphaTest>()?;
    m.add_function(wrap_pyfunction!(linear_image, m)?)?;
    Ok(())
}
