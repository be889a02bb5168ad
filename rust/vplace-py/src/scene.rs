//! `Scene`, `Light`, `Progress`, uniform VPLs, the evaluator and the metrics.

use glam::{Mat3, Vec2, Vec3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use vplace_core::{
    metrics,
    scene::emitters::{emitter_power, Emitter, EnvironmentMap},
    scene::{Light, LightBounces, LightKind, Material, Scene, SceneInput},
    LUMINANCE,
};

use crate::arrays::{array, slice, Dim};
use crate::errors::{input_error, run, to_py, InternalError};
use crate::materials::{PyAlphaTest, PyTextureMap};

fn vec3(v: [f32; 3]) -> Vec3 {
    Vec3::from_array(v)
}

fn vec3s(s: &[f32]) -> Vec<Vec3> {
    s.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// A light of the scene, in Blender's units (see DESIGN, Coordinates and units, and the core's
/// `emitters` module). Build with the static methods; each checks its parameters.
#[pyclass(name = "Light", module = "vplace._native", frozen)]
#[derive(Clone)]
pub struct PyLight {
    pub inner: Light,
}

/// Python's spelling of a bool.
fn py_bool(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// The light, or an `InputError` naming the bad parameter.
fn checked_light(light: Light) -> PyResult<PyLight> {
    light.validate_as("light").map_err(to_py)?;
    Ok(PyLight { inner: light })
}

/// `(disk, square_or_round)` of an area light's `shape`: a bool (True: disk) or one of
/// Blender's names.
fn area_shape(shape: &Bound<'_, PyAny>) -> PyResult<(bool, bool)> {
    if let Ok(disk) = shape.extract::<bool>() {
        return Ok((disk, false));
    }
    let name: String = shape.extract().map_err(|_| {
        input_error("shape must be 'rectangle', 'square', 'disk', 'ellipse' or a bool (True: disk)")
    })?;
    match name.to_ascii_lowercase().as_str() {
        "rectangle" => Ok((false, false)),
        "square" => Ok((false, true)),
        "disk" => Ok((true, true)),
        "ellipse" => Ok((true, false)),
        other => Err(input_error(format!(
            "shape must be 'rectangle', 'square', 'disk' or 'ellipse', got {other:?}"
        ))),
    }
}

#[pymethods]
impl PyLight {
    /// A POINT light of RGB power `power` watts. `radius` is Blender's `shadow_soft_size`
    /// (metres): with `soft_falloff` (Blender's default) a disk of that radius facing the
    /// receiver, without it a sphere; 0 is a point.
    #[staticmethod]
    #[pyo3(signature = (position, power, radius=0.0, soft_falloff=true))]
    fn point(
        position: [f32; 3],
        power: [f32; 3],
        radius: f32,
        soft_falloff: bool,
    ) -> PyResult<Self> {
        checked_light(Light::point(vec3(position), vec3(power)).with_radius(radius, soft_falloff))
    }

    /// A SPOT light with cone half angle `half_angle` radians (half of Blender's `spot_size`)
    /// about `direction`, Blender's `spot_blend` `blend` in [0, 1], and the point light's
    /// `radius` and `soft_falloff`.
    #[staticmethod]
    #[pyo3(signature = (position, direction, half_angle, power, blend=0.0, radius=0.0, soft_falloff=true))]
    fn spot(
        position: [f32; 3],
        direction: [f32; 3],
        half_angle: f32,
        power: [f32; 3],
        blend: f32,
        radius: f32,
        soft_falloff: bool,
    ) -> PyResult<Self> {
        checked_light(
            Light::spot(vec3(position), vec3(direction), half_angle, vec3(power))
                .with_blend(blend)
                .with_radius(radius, soft_falloff),
        )
    }

    /// An AREA light (normalize on) emitting along `direction`; `size_x` along `tangent`.
    /// `shape` is 'rectangle', 'square', 'disk' or 'ellipse' (or a bool, True for a disk);
    /// a square or a disk takes `size_x` for both sizes. `spread` is Blender's spread angle
    /// in radians ([0, pi]; pi: a cosine emitter).
    #[staticmethod]
    #[pyo3(signature = (position, direction, tangent, shape, size_x, size_y, power, spread=std::f32::consts::PI))]
    #[allow(clippy::too_many_arguments)]
    fn area(
        position: [f32; 3],
        direction: [f32; 3],
        tangent: [f32; 3],
        shape: &Bound<'_, PyAny>,
        size_x: f32,
        size_y: f32,
        power: [f32; 3],
        spread: f32,
    ) -> PyResult<Self> {
        let (disk, same) = area_shape(shape)?;
        let size_y = if same { size_x } else { size_y };
        checked_light(
            Light::area(
                vec3(position),
                vec3(direction),
                vec3(tangent),
                disk,
                size_x,
                size_y,
                vec3(power),
            )
            .with_spread(spread),
        )
    }

    /// A SUN travelling along `direction` with RGB irradiance `irradiance` W/m^2 (Blender's
    /// strength) from a disk of directions of full angle `angle` radians (Blender's `angle`).
    #[staticmethod]
    #[pyo3(signature = (direction, irradiance, angle=0.0))]
    fn sun(direction: [f32; 3], irradiance: [f32; 3], angle: f32) -> PyResult<Self> {
        checked_light(Light::sun(vec3(direction), vec3(irradiance)).with_angle(angle))
    }

    /// The world: radiance `color * strength` (W/(m^2 sr), Blender's Background colour and
    /// strength) from every direction, times `image` where given: an equirectangular float32
    /// (H, W, 3) image, linear, row 0 at the top (+Z), Blender's Environment Texture
    /// convention. `rotation` (3 x 3, rows) takes world directions to image directions (a
    /// Mapping node's rotation matrix); None is the identity. The image is importance-sampled.
    #[staticmethod]
    #[pyo3(signature = (color=[1.0, 1.0, 1.0], strength=1.0, image=None, rotation=None))]
    fn world(
        py: Python<'_>,
        color: [f32; 3],
        strength: f32,
        image: Option<&Bound<'_, PyAny>>,
        rotation: Option<[[f32; 3]; 3]>,
    ) -> PyResult<Self> {
        let radiance = vec3(color) * strength;
        if !strength.is_finite() {
            return Err(input_error(format!(
                "strength must be finite, got {strength}"
            )));
        }
        let rotation =
            rotation.map_or(Mat3::IDENTITY, |r| Mat3::from_cols_array_2d(&r).transpose());
        let map = match image {
            None => {
                if rotation != Mat3::IDENTITY {
                    // Checked all the same: a bad rotation is a mistake even without an image.
                    EnvironmentMap::new(1, 1, &[1.0, 1.0, 1.0], rotation).map_err(to_py)?;
                }
                None
            }
            Some(img) => {
                let a = array::<f32>(img, "image", &[Dim::Any, Dim::Any, Dim::Is(3)], "float32")?;
                let (h, w) = (a.shape()[0], a.shape()[1]);
                let data = slice(&a, "image")?.to_vec();
                let m = run(py, move || EnvironmentMap::new(w, h, &data, rotation))?;
                Some(Arc::new(m))
            }
        };
        checked_light(Light::world(radiance, map))
    }

    /// `"point"`, `"spot"`, `"area"`, `"sun"` or `"world"`.
    #[getter]
    fn kind(&self) -> &'static str {
        Emitter::Light(&self.inner).name()
    }

    /// RGB power, watts (W/m^2 for a sun, radiance W/(m^2 sr) for the world).
    #[getter]
    fn power(&self) -> [f32; 3] {
        self.inner.power.to_array()
    }

    fn __repr__(&self) -> String {
        let params = match &self.inner.kind {
            LightKind::Point {
                radius,
                soft_falloff,
            } => format!("radius={radius}, soft_falloff={}", py_bool(*soft_falloff)),
            LightKind::Spot {
                half_angle,
                blend,
                radius,
                soft_falloff,
            } => format!(
                "half_angle={half_angle}, blend={blend}, radius={radius}, soft_falloff={}",
                py_bool(*soft_falloff)
            ),
            LightKind::Area {
                disk,
                size_x,
                size_y,
                spread,
            } => format!(
                "shape={:?}, size=({size_x}, {size_y}), spread={spread}",
                if *disk { "ellipse" } else { "rectangle" }
            ),
            LightKind::Sun { angle } => format!("angle={angle}"),
            LightKind::World { map } => match map {
                Some(m) => format!("image={}x{}", m.width(), m.height()),
                None => "image=None".into(),
            },
        };
        format!(
            "Light.{}(power={:?}, {params})",
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
    /// `material_ids` uint32 (T,), `albedo` float32 (M, 3) in [0, 1], `lights` a list of Light;
    /// `emission` float32 (M, 3), the radiance each material emits from both sides (W/(m^2 sr),
    /// Blender's emission colour times strength), or None for none.
    ///
    /// Textured and alpha-tested materials (all optional): `uvs` float32 (T, 3, 2), the UV of
    /// each triangle corner; `textures` a list of float32 (H, W, 3 or 4) linear images, row 0 at
    /// the top; `base_textures` one `TextureMap` or None per material (the albedo at a hit is
    /// `albedo + texture_tint * rgb`, clamped to [0, 1]); `texture_tint` float32 (M, 3), default
    /// ones; `alpha_tests` one `AlphaTest` or None per material.
    ///
    /// Glossy layers, which the light paths reflect off besides the albedo (optional): `gloss`
    /// float32 (M, 3), each material's layer's reflectance (its mean over incident directions;
    /// all zeros: no layer), plus `gloss_tint` float32 (M, 3) (default zeros) times the base
    /// texture's RGB, clamped to [0, 1]; `gloss_roughness` float32 (M,) in [0, 1] (Blender's
    /// roughness, default 0.5). The shading of views never reads them.
    ///
    /// `light_bounces` `(diffuse, glossy, total)`: the reflections the renderer the scene is
    /// scored against follows (Cycles' Light Paths > Max Bounces; diffuse and total in
    /// 1..=`MAX_BOUNCES`, glossy in 0..=`MAX_BOUNCES`; default `MAX_BOUNCES` each); light paths
    /// leave VPLs only within them.
    ///
    /// `eyes` float32 (N, 3), the cameras' positions (optional): the working scale (`scale`)
    /// is then that of the region seen from them, where that is much less than the bounds
    /// (`vplace_core::scene::region`); VPL sizes and ray offsets follow it. `looks` float32
    /// (N, 3), each eye's view direction (zero for none; optional): what it looks at sets its
    /// backdrop where that is nearer than what it sees all round.
    #[new]
    #[pyo3(signature = (
        vertices, triangles, material_ids, albedo, lights, *, emission = None,
        uvs = None, textures = None, base_textures = None, texture_tint = None, alpha_tests = None,
        gloss = None, gloss_tint = None, gloss_roughness = None, light_bounces = None,
        eyes = None, looks = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        material_ids: &Bound<'_, PyAny>,
        albedo: &Bound<'_, PyAny>,
        lights: Vec<Bound<'_, PyLight>>,
        emission: Option<&Bound<'_, PyAny>>,
        uvs: Option<&Bound<'_, PyAny>>,
        textures: Option<Vec<Bound<'_, PyAny>>>,
        base_textures: Option<Vec<Option<Bound<'_, PyTextureMap>>>>,
        texture_tint: Option<&Bound<'_, PyAny>>,
        alpha_tests: Option<Vec<Option<Bound<'_, PyAlphaTest>>>>,
        gloss: Option<&Bound<'_, PyAny>>,
        gloss_tint: Option<&Bound<'_, PyAny>>,
        gloss_roughness: Option<&Bound<'_, PyAny>>,
        light_bounces: Option<(usize, usize, usize)>,
        eyes: Option<&Bound<'_, PyAny>>,
        looks: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let points = |a: Option<&Bound<'_, PyAny>>, what: &str| -> PyResult<Vec<Vec3>> {
            match a {
                Some(e) => {
                    let e = array::<f32>(e, what, &[Dim::Any, Dim::Is(3)], "float32")?;
                    Ok(vec3s(slice(&e, what)?))
                }
                None => Ok(Vec::new()),
            }
        };
        let eyes = points(eyes, "eyes")?;
        let looks = points(looks, "looks")?;
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
        let emit = match emission {
            Some(e) => {
                let dims = [Dim::Is(alb.len()), Dim::Is(3)];
                let e = array::<f32>(e, "emission", &dims, "float32")?;
                vec3s(slice(&e, "emission")?)
            }
            None => vec![Vec3::ZERO; alb.len()],
        };
        let lights: Vec<Light> = lights.iter().map(|l| l.get().inner.clone()).collect();
        let surf = crate::materials::surfaces(uvs, textures)?;
        let materials: Vec<Material> = crate::materials::materials(
            alb,
            base_textures,
            texture_tint,
            alpha_tests,
            gloss,
            gloss_tint,
            gloss_roughness,
        )?
        .into_iter()
        .zip(&emit)
        .map(|(m, &e)| m.with_emission(e))
        .collect();
        let scene = run(py, move || {
            Scene::new(SceneInput {
                vertices: &verts,
                triangles: &tris,
                material_ids: &mats,
                materials: &materials,
                lights,
                uvs: surf.uvs.as_deref(),
                textures: surf.textures,
            })
            .and_then(|s| match light_bounces {
                Some((diffuse, glossy, total)) => s.with_light_bounces(LightBounces {
                    diffuse,
                    glossy,
                    total,
                }),
                None => Ok(s),
            })
            .and_then(|s| s.with_views(&eyes, &looks))
        })?;
        Ok(Self {
            inner: Arc::new(scene),
        })
    }

    /// True when every shadow ray is blocked in `other` exactly where it is here: the same
    /// triangles, textured and alpha-tested surfaces and ray offset; the lights may differ
    /// (the frames of a moving sun or lamp). `vplace.refit_frames` needs it of its frames.
    fn same_occluders(&self, other: &PyScene) -> bool {
        self.inner.same_occluders(&other.inner)
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

    /// Number of triangles whose material emits.
    #[getter]
    fn emissive_triangle_count(&self) -> usize {
        self.inner.emissive().len()
    }

    /// Every source of light with the power it emits into the scene: `(kind, [r, g, b])`, the
    /// lights in order then `"emissive triangles"` when any (watts; a sun's and the world's
    /// through the disk of the scene's bounding sphere).
    fn emitted_powers(&self) -> Vec<(&'static str, [f32; 3])> {
        self.inner
            .emitters()
            .into_iter()
            .map(|e| (e.name(), emitter_power(e, &self.inner).to_array()))
            .collect()
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

    /// Length of the bounds' diagonal, metres: the distance that takes a ray out of the scene.
    #[getter]
    fn diagonal(&self) -> f32 {
        self.inner.diagonal()
    }

    /// The working scale, metres: the diagonal of the region seen from the constructor's
    /// `eyes`, where that is much less than the bounds, else the bounds' diagonal. VPL sizes,
    /// their offsets and ray offsets are fractions of it.
    #[getter]
    fn scale(&self) -> f32 {
        self.inner.scale()
    }

    /// `(min, max)` corners of the region the cameras see where it sets the working scale
    /// (less than the bounds), else None.
    #[getter]
    fn region(&self) -> Option<([f32; 3], [f32; 3])> {
        self.inner
            .region()
            .map(|(lo, hi)| (lo.to_array(), hi.to_array()))
    }

    /// The default near-field radius of the scene's VPLs, metres (`NEAR_FIELD_FRACTION` of
    /// the working scale).
    #[getter]
    fn near_field_radius(&self) -> f32 {
        self.inner.near_field_radius()
    }

    /// `(diffuse, glossy, total)`: the reflections light paths stay within (`light_bounces` of
    /// the constructor).
    #[getter]
    fn light_bounces(&self) -> (usize, usize, usize) {
        let b = self.inner.light_bounces();
        (b.diffuse, b.glossy, b.total)
    }

    /// Number of textures.
    #[getter]
    fn texture_count(&self) -> usize {
        self.inner.texture_count()
    }

    /// True when some material is alpha-tested.
    #[getter]
    fn has_alpha_tests(&self) -> bool {
        self.inner.has_alpha_tests()
    }

    /// Closest hits of rays `origins` + t `directions` (float32 (N, 3) each; directions are
    /// normalized here), t in (`tmin`, inf), alpha-tested surfaces skipped where cut. Returns
    /// `(t, triangle, barycentrics)`: float32 (N,) (inf on a miss), int64 (N,) (-1 on a miss),
    /// float32 (N, 2) (the weights of the triangle's second and third vertex).
    #[pyo3(signature = (origins, directions, tmin = 0.0))]
    #[allow(clippy::type_complexity)]
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f32,
    ) -> PyResult<(
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<i64>>,
        Bound<'py, PyArray2<f32>>,
    )> {
        let (o, d) = ray_pairs(origins, directions, "directions")?;
        let scene = Arc::clone(&self.inner);
        let n = o.len();
        let hits = run(py, move || Ok(scene.closest_hits(&o, &d, tmin)))?;
        let t: Vec<f32> = hits
            .iter()
            .map(|h| h.map_or(f32::INFINITY, |h| h.t))
            .collect();
        let tri: Vec<i64> = hits
            .iter()
            .map(|h| h.map_or(-1, |h| i64::from(h.triangle)))
            .collect();
        let bary: Vec<f32> = hits
            .iter()
            .flat_map(|h| h.map_or([0.0, 0.0], |h| h.barycentrics.to_array()))
            .collect();
        let bary = numpy::ndarray::Array2::from_shape_vec((n, 2), bary)
            .map_err(|e| InternalError::new_err(e.to_string()))?
            .into_pyarray(py);
        Ok((t.into_pyarray(py), tri.into_pyarray(py), bary))
    }

    /// The albedo at barycentrics `barycentrics` (float32 (N, 2)) of triangles `triangles`
    /// (uint32 (N,)): the texture at the interpolated UV for a textured material. float32
    /// (N, 3).
    fn albedo_at<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        barycentrics: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.per_hit(py, triangles, barycentrics, Scene::albedo_at)
    }

    /// The glossy layer's reflectance at barycentrics `barycentrics` (float32 (N, 2)) of
    /// triangles `triangles` (uint32 (N,)), zeros where the material has none (see `Scene()`).
    /// float32 (N, 3).
    fn gloss_at<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        barycentrics: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.per_hit(py, triangles, barycentrics, |s, t, b| {
            s.gloss_at(t, b).map_or(Vec3::ZERO, |g| g.0)
        })
    }

    /// The unit geometric normal (the winding's side) of triangles `triangles` (uint32 (N,)),
    /// zeros for a degenerate triangle; `barycentrics` (float32 (N, 2)) as `albedo_at` takes
    /// them (the normal is the same at every point of a triangle). float32 (N, 3).
    fn normal_at<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        barycentrics: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.per_hit(py, triangles, barycentrics, |s, t, _| s.normal(t))
    }

    /// Whether something blocks the segment from each of `origins` to the matching `targets`
    /// (float32 (N, 3) each; an any-hit shadow ray, alpha-tested surfaces counting only where
    /// they are not cut). The caller offsets both ends off their surfaces. bool (N,).
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        targets: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let (a, b) = ray_pairs(origins, targets, "targets")?;
        let scene = Arc::clone(&self.inner);
        let out = run(py, move || Ok(scene.occluded_segments(&a, &b)))?;
        Ok(out.into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(triangles={}, lights={}, emissive_triangles={})",
            self.inner.triangle_count(),
            self.inner.lights.len(),
            self.inner.emissive().len()
        )
    }
}

/// Progress and cancellation of a long call. Pass it in, poll `done` / `total` from another
/// thread, call `cancel()` to stop the call (it then raises CancelledError).
#[pyclass(name = "Progress", module = "vplace._native", frozen)]
#[derive(Default)]
pub struct PyProgress {
    pub inner: Arc<vplace_core::Progress>,
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

/// Two float32 (N, 3) arrays of the same N, finite, as points.
fn ray_pairs(
    origins: &Bound<'_, PyAny>,
    other: &Bound<'_, PyAny>,
    other_name: &str,
) -> PyResult<(Vec<Vec3>, Vec<Vec3>)> {
    let o = array::<f32>(origins, "origins", &[Dim::Any, Dim::Is(3)], "float32")?;
    let n = o.shape()[0];
    let d = array::<f32>(other, other_name, &[Dim::Is(n), Dim::Is(3)], "float32")?;
    let (o, d) = (slice(&o, "origins")?, slice(&d, other_name)?);
    for (name, values) in [("origins", o), (other_name, d)] {
        if let Some(i) = values.iter().position(|x| !x.is_finite()) {
            return Err(input_error(format!(
                "{name} holds a non-finite value at index {i}"
            )));
        }
    }
    Ok((vec3s(o), vec3s(d)))
}

fn pair<'py>(
    image: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
) -> PyResult<(Vec<f32>, Vec<f32>)> {
    let (r, h, w) = rgb(reference, "reference")?;
    let i = like(image, "image", h, w)?;
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

/// RMSE against the noise-free truth of which `truth` and `other` are two independent renders:
/// the root of `mean((image - truth) (image_other - other))`, clamped at 0 (all float32
/// (H, W, 3) of one shape). `image_other`: `image` where it is independent of both renders,
/// else the same image built on `other`'s passes.
#[pyfunction]
fn rmse_noise_free(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    truth: &Bound<'_, PyAny>,
    image_other: &Bound<'_, PyAny>,
    other: &Bound<'_, PyAny>,
) -> PyResult<f64> {
    let (t, h, w) = rgb(truth, "truth")?;
    let (i, io, o) = (
        like(image, "image", h, w)?,
        like(image_other, "image_other", h, w)?,
        like(other, "other", h, w)?,
    );
    let (i, t) = (slice(&i, "image")?, slice(&t, "truth")?);
    let (io, o) = (slice(&io, "image_other")?, slice(&o, "other")?);
    run(py, move || metrics::rmse_noise_free(i, t, io, o))
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

/// Checks a float32 (H, W, 3) image of any size; returns it with its H and W.
fn rgb<'a>(
    image: &'a Bound<'_, PyAny>,
    what: &str,
) -> PyResult<(numpy::PyReadonlyArrayDyn<'a, f32>, usize, usize)> {
    let a = array::<f32>(image, what, &[Dim::Any, Dim::Any, Dim::Is(3)], "float32")?;
    let (h, w) = (a.shape()[0], a.shape()[1]);
    Ok((a, h, w))
}

/// Checks a float32 (H, W, 3) image of the reference's shape and returns its values.
fn like<'a>(
    image: &'a Bound<'_, PyAny>,
    what: &str,
    h: usize,
    w: usize,
) -> PyResult<numpy::PyReadonlyArrayDyn<'a, f32>> {
    let dims = [Dim::Is(h), Dim::Is(w), Dim::Is(3)];
    array::<f32>(image, what, &dims, "float32")
}

/// SSIM of `image` against `reference`, both float32 (H, W, 3) linear HDR, on the display
/// luminance (exposure 1, clamp to [0, 1], sRGB), Gaussian window 11, sigma 1.5, K1 0.01,
/// K2 0.03. H and W must be at least 11.
#[pyfunction]
fn ssim(py: Python<'_>, image: &Bound<'_, PyAny>, reference: &Bound<'_, PyAny>) -> PyResult<f64> {
    let (r, h, w) = rgb(reference, "reference")?;
    let i = like(image, "image", h, w)?;
    let (a, b) = (slice(&i, "image")?, slice(&r, "reference")?);
    run(py, move || metrics::ssim(a, b, w, h))
}

/// SSIM of `image` against the noise-free image of which `truth` and `other` are two
/// independent renders (two seeds), estimated from products across the two renders (as
/// `ssim`'s settings; all float32 (H, W, 3), H and W at least 11). It reads low where the
/// renders are noisy on flat surfaces: by about .003 where they score .85 against each other,
/// .02 at .62, .06 at .47 (ARCHITECTURE, "SSIM against the noise-free truth").
#[pyfunction]
fn ssim_noise_free(
    py: Python<'_>,
    image: &Bound<'_, PyAny>,
    truth: &Bound<'_, PyAny>,
    other: &Bound<'_, PyAny>,
) -> PyResult<f64> {
    let (t, h, w) = rgb(truth, "truth")?;
    let (i, o) = (like(image, "image", h, w)?, like(other, "other", h, w)?);
    let (i, t, o) = (
        slice(&i, "image")?,
        slice(&t, "truth")?,
        slice(&o, "other")?,
    );
    run(py, move || metrics::ssim_noise_free(i, t, o, w, h))
}

/// The SSIM that the noise-free image would score against the render `truth`, estimated with
/// `other`, an independent render of it: the ceiling `truth`'s noise puts on every score
/// against it (float32 (H, W, 3) each).
#[pyfunction]
fn ssim_ceiling(
    py: Python<'_>,
    truth: &Bound<'_, PyAny>,
    other: &Bound<'_, PyAny>,
) -> PyResult<f64> {
    let (t, h, w) = rgb(truth, "truth")?;
    let o = like(other, "other", h, w)?;
    let (t, o) = (slice(&t, "truth")?, slice(&o, "other")?);
    run(py, move || metrics::ssim_ceiling(t, o, w, h))
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLight>()?;
    m.add_class::<PyScene>()?;
    m.add_class::<PyProgress>()?;
    m.add_function(wrap_pyfunction!(rmse, m)?)?;
    m.add_function(wrap_pyfunction!(relative_mse, m)?)?;
    m.add_function(wrap_pyfunction!(ssim, m)?)?;
    m.add_function(wrap_pyfunction!(ssim_noise_free, m)?)?;
    m.add_function(wrap_pyfunction!(ssim_ceiling, m)?)?;
    m.add_function(wrap_pyfunction!(rmse_noise_free, m)?)?;
    m.add("LUMINANCE", LUMINANCE.to_array())?;
    m.add(
        "NEAR_FIELD_FRACTION",
        vplace_core::scene::NEAR_FIELD_FRACTION,
    )?;
    m.add("REGION_MARGIN", vplace_core::scene::region::REGION_MARGIN)?;
    m.add("MAX_RADIUS_FACTOR", vplace_core::vpl::MAX_RADIUS_FACTOR)?;
    m.add("DISK_PATCHES", vplace_core::vpl::DISK_PATCHES)?;
    m.add("SPACING_NEIGHBOURS", vplace_core::vpl::SPACING_NEIGHBOURS)?;
    Ok(())
}

impl PyScene {
    /// `at` (the albedo or the reflectance) at each of `triangles`' `barycentrics`, checked.
    fn per_hit<'py>(
        &self,
        py: Python<'py>,
        triangles: &Bound<'py, PyAny>,
        barycentrics: &Bound<'py, PyAny>,
        at: fn(&Scene, u32, Vec2) -> Vec3,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let t = array::<u32>(triangles, "triangles", &[Dim::Any], "uint32")?;
        let n = t.shape()[0];
        let b = array::<f32>(
            barycentrics,
            "barycentrics",
            &[Dim::Is(n), Dim::Is(2)],
            "float32",
        )?;
        let (t, b) = (slice(&t, "triangles")?, slice(&b, "barycentrics")?);
        let count = self.inner.triangle_count();
        if let Some(&bad) = t.iter().find(|&&i| i as usize >= count) {
            return Err(input_error(format!(
                "triangles: index {bad} is out of bounds for {count} triangles"
            )));
        }
        if let Some(i) = b.iter().position(|x| !x.is_finite()) {
            return Err(input_error(format!(
                "barycentrics holds a non-finite value at index {i}"
            )));
        }
        let out: Vec<f32> = t
            .iter()
            .zip(b.chunks_exact(2))
            .flat_map(|(&t, b)| at(&self.inner, t, Vec2::new(b[0], b[1])).to_array())
            .collect();
        Ok(numpy::ndarray::Array2::from_shape_vec((n, 3), out)
            .map_err(|e| input_error(e.to_string()))?
            .into_pyarray(py))
    }
}
