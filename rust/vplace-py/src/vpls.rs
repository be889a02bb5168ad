//! `VplSet` (the lights as they will be written), the uniform and RSM layouts, the evaluator.

use glam::Vec3;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use std::sync::Arc;
use vplace_core::{
    layout::rsm,
    shade::evaluator::{self, check_radii, validate_vpls, EvalParams, EvalStats},
    shade::near_field,
    vpl::{self, near_field_radii, Profile, Vpl},
};

use crate::arrays::{array, slice, Dim};
use crate::errors::{input_error, run, to_py};
use crate::scene::{PyProgress, PyScene};
use crate::view::PyView;

/// Parses a profile name.
pub fn parse_profile(profile: &str) -> PyResult<Profile> {
    match profile {
        "cosine" => Ok(Profile::Cosine),
        "omni" => Ok(Profile::Omni),
        other => Err(input_error(format!(
            "profile must be 'cosine' or 'omni', got {other:?}"
        ))),
    }
}

pub fn profile_name(p: Profile) -> &'static str {
    match p {
        Profile::Cosine => "cosine",
        Profile::Omni => "omni",
    }
}

/// A set of VPLs with how they radiate: exactly the lights the write-back creates and the
/// evaluator renders.
#[pyclass(name = "VplSet", module = "vplace._native", frozen)]
#[derive(Clone)]
pub struct PyVplSet {
    pub vpls: Arc<Vec<Vpl>>,
    pub profile: Profile,
    pub radius: f32,
    /// Each VPL's near-field radius when given (`VplSet(..., radii=...)`), else `None`: those
    /// of the set's spacing.
    pub given_radii: Option<Arc<Vec<f32>>>,
    /// Whether the set's light includes the near-field gather (`VplSet.near_field`): what
    /// `evaluate` adds by default, and what the write-back has EEVEE's fast GI add.
    pub near_field: bool,
}

impl PyVplSet {
    /// Checks the VPLs and the radius.
    pub fn new_checked(vpls: Vec<Vpl>, profile: Profile, radius: f32) -> PyResult<Self> {
        validate_vpls(&vpls).map_err(crate::errors::to_py)?;
        if !(radius >= 0.0 && radius.is_finite()) {
            return Err(input_error(format!(
                "radius must be finite and >= 0, got {radius}"
            )));
        }
        Ok(Self {
            vpls: Arc::new(vpls),
            profile,
            radius,
            given_radii: None,
            near_field: false,
        })
    }

    /// This set with each VPL's near-field radius given (cosine VPLs only; one finite radius
    /// `>= 0` per VPL).
    pub fn with_given_radii(mut self, radii: Vec<f32>) -> PyResult<Self> {
        if self.profile != Profile::Cosine {
            return Err(input_error(
                "radii: only cosine VPLs (disks) have near-field radii; omni VPLs are points",
            ));
        }
        check_radii(&radii, self.vpls.len()).map_err(to_py)?;
        self.given_radii = Some(Arc::new(radii));
        Ok(self)
    }

    /// An error for an operation that computes the radii from the set's spacing itself (the
    /// refit, the layout): it would not shade the lights with the radii given.
    pub fn check_no_given_radii(&self, what: &str) -> PyResult<()> {
        match self.given_radii {
            Some(_) => Err(input_error(format!(
                "{what} takes a VplSet whose radii follow its spacing; this one has radii given \
                 (VplSet(..., radii=...)): only evaluate() shades with them"
            ))),
            None => Ok(()),
        }
    }

    /// The evaluator's settings for this set.
    pub fn eval_params(&self, tile: usize) -> EvalParams {
        EvalParams {
            profile: self.profile,
            radius: self.radius,
            tile,
        }
    }

    fn column<'py>(&self, py: Python<'py>, f: fn(&Vpl) -> Vec3) -> PyResult<Bound<'py, PyAny>> {
        let flat: Vec<f32> = self.vpls.iter().flat_map(|v| f(v).to_array()).collect();
        Ok(PyArray1::from_vec(py, flat)
            .reshape([self.vpls.len(), 3])?
            .into_any())
    }
}

/// Reads three (N, 3) float32 arrays as VPLs.
fn read_vpls(
    position: &Bound<'_, PyAny>,
    normal: &Bound<'_, PyAny>,
    flux: &Bound<'_, PyAny>,
) -> PyResult<Vec<Vpl>> {
    let p = array::<f32>(position, "position", &[Dim::Any, Dim::Is(3)], "float32")?;
    let n = p.shape()[0];
    let nn = array::<f32>(normal, "normal", &[Dim::Is(n), Dim::Is(3)], "float32")?;
    let f = array::<f32>(flux, "flux", &[Dim::Is(n), Dim::Is(3)], "float32")?;
    let (p, nn, f) = (
        slice(&p, "position")?,
        slice(&nn, "normal")?,
        slice(&f, "flux")?,
    );
    Ok((0..n)
        .map(|i| Vpl {
            position: Vec3::from_slice(&p[3 * i..]),
            normal: Vec3::from_slice(&nn[3 * i..]),
            flux: Vec3::from_slice(&f[3 * i..]),
        })
        .collect())
}

#[pymethods]
impl PyVplSet {
    /// VPLs from float32 (N, 3) arrays: positions, unit normals, reflected flux (RGB watts);
    /// `radii`, float32 (N,): each cosine VPL's near-field radius instead of its spacing's.
    #[new]
    #[pyo3(signature = (position, normal, flux, *, profile = "cosine", radius = 0.0, radii = None))]
    fn new(
        position: &Bound<'_, PyAny>,
        normal: &Bound<'_, PyAny>,
        flux: &Bound<'_, PyAny>,
        profile: &str,
        radius: f32,
        radii: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let profile = parse_profile(profile)?;
        let set = Self::new_checked(read_vpls(position, normal, flux)?, profile, radius)?;
        match radii {
            None => Ok(set),
            Some(r) => {
                let n = set.vpls.len();
                let r = array::<f32>(r, "radii", &[Dim::Is(n)], "float32")?;
                let r = slice(&r, "radii")?.to_vec();
                set.with_given_radii(r)
            }
        }
    }

    /// The same VPLs with another flux (float32 (N, 3)).
    fn with_flux(&self, flux: &Bound<'_, PyAny>) -> PyResult<Self> {
        let n = self.vpls.len();
        let f = array::<f32>(flux, "flux", &[Dim::Is(n), Dim::Is(3)], "float32")?;
        let f = slice(&f, "flux")?;
        let vpls = self
            .vpls
            .iter()
            .enumerate()
            .map(|(i, v)| Vpl {
                flux: Vec3::from_slice(&f[3 * i..]),
                ..*v
            })
            .collect();
        let mut set = Self::new_checked(vpls, self.profile, self.radius)?;
        set.near_field = self.near_field;
        match &self.given_radii {
            Some(r) => set.with_given_radii(r.to_vec()),
            None => Ok(set),
        }
    }

    /// The same VPLs, their light with (`on`) or without the near-field gather
    /// (:attr:`near_field`).
    fn with_near_field(&self, on: bool) -> Self {
        Self {
            near_field: on,
            ..self.clone()
        }
    }

    /// Whether the set's light includes the light between nearby surfaces that no VPL
    /// carries, gathered from the view's pixels within :attr:`near_field_distance`
    /// (`vplace_core::shade::near_field`): what `evaluate` adds unless told otherwise, and what
    /// the write-back has EEVEE's fast GI add. False for a new set; `vplace.job.lay_out` turns
    /// it on where the captures say it helps (`vplace.job.choose_near_field`).
    #[getter]
    fn near_field(&self) -> bool {
        self.near_field
    }

    fn __len__(&self) -> usize {
        self.vpls.len()
    }

    /// Positions (N, 3) float32, offset off their surfaces.
    #[getter]
    fn position<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.column(py, |v| v.position)
    }

    /// Unit normals (N, 3) float32: the side the light leaves.
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.column(py, |v| v.normal)
    }

    /// Reflected flux (N, 3) float32, RGB watts.
    #[getter]
    fn flux<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.column(py, |v| v.flux)
    }

    /// The power of the Blender light of each VPL (N, 3) float32, RGB watts: the flux for the
    /// cosine profile (an AREA disk), twice the flux for omni (a POINT light).
    #[getter]
    fn blender_power<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let p = self.profile;
        let flat: Vec<f32> = self
            .vpls
            .iter()
            .flat_map(|v| p.blender_power(v.flux).to_array())
            .collect();
        Ok(PyArray1::from_vec(py, flat)
            .reshape([self.vpls.len(), 3])?
            .into_any())
    }

    /// `"cosine"` (AREA disk lights) or `"omni"` (POINT lights).
    #[getter]
    fn profile(&self) -> &'static str {
        profile_name(self.profile)
    }

    /// The set's near-field radius, metres: the smallest disk radius of a cosine VPL (see
    /// `radii`).
    #[getter]
    fn radius(&self) -> f32 {
        self.radius
    }

    /// The near-field radius of each VPL (N,) float32, metres: the radius of a disk of
    /// `DISK_PATCHES` surface patches of the size it stands for (from the spacing of its
    /// nearest VPLs), between `radius` and `MAX_RADIUS_FACTOR * radius`, or the radii given to
    /// the constructor. The evaluator and the refit shade a cosine VPL as a disk of this radius,
    /// and the write-back writes it (AREA disk of diameter `2 R_j`). Omni VPLs are points: all 0.
    #[getter]
    fn radii<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_vec(py, self.radii_vec())
    }

    /// The distance within which `evaluate(..., near_field=True)` gathers the short-range light
    /// the set cannot carry (`vplace_core::shade::near_field::gather_distance` of
    /// :attr:`radii`), world units; 0 for omni VPLs. EEVEE's fast GI gathers the same light
    /// within it (ray tracing on, global illumination): the write-back keeps it on the VPL
    /// collection of a set with :attr:`near_field`, and EEVEE's set-up applies it.
    #[getter]
    fn near_field_distance(&self) -> f32 {
        near_field::gather_distance(&self.radii_vec())
    }

    /// Whether the radii were given (`VplSet(..., radii=...)`) rather than computed from the
    /// set's spacing.
    #[getter]
    fn radii_given(&self) -> bool {
        self.given_radii.is_some()
    }

    fn __repr__(&self) -> String {
        format!(
            "VplSet({} VPLs, profile={:?}, radius={}{}{})",
            self.vpls.len(),
            profile_name(self.profile),
            self.radius,
            if self.given_radii.is_some() {
                ", radii given"
            } else {
                ""
            },
            if self.near_field { ", near field" } else { "" }
        )
    }
}

/// What an evaluation cost.
#[pyclass(name = "EvalStats", module = "vplace._native", frozen, get_all)]
pub struct PyEvalStats {
    /// Shadow rays traced (pixel-VPL pairs with a non-zero unshadowed contribution).
    pub shadow_rays: u64,
    /// Pixel-VPL pairs considered.
    pub pairs: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// The distance within which the near-field light was gathered from the view's pixels
    /// (`vplace_core::shade::near_field`), world units; 0 when it was not.
    pub near_field_distance: f32,
}

#[pymethods]
impl PyEvalStats {
    /// Shadow rays per second.
    #[getter]
    fn rays_per_second(&self) -> f64 {
        EvalStats {
            shadow_rays: self.shadow_rays,
            pairs: self.pairs,
            seconds: self.seconds,
        }
        .rays_per_second()
    }

    fn __repr__(&self) -> String {
        format!(
            "EvalStats(shadow_rays={}, pairs={}, seconds={:.3}, near_field_distance={:.4})",
            self.shadow_rays, self.pairs, self.seconds, self.near_field_distance
        )
    }
}

/// The default near-field radius of a scene's VPLs, metres.
pub fn default_radius(scene: &PyScene, radius: Option<f32>) -> f32 {
    radius.unwrap_or_else(|| scene.inner.near_field_radius())
}

/// Keller's instant radiosity (see `vplace.uniform_vpls`).
#[pyfunction]
#[pyo3(signature = (scene, n, *, seed = 0, bounces = 1, profile = "cosine", radius = None))]
fn uniform_vpls(
    py: Python<'_>,
    scene: &PyScene,
    n: usize,
    seed: u64,
    bounces: usize,
    profile: &str,
    radius: Option<f32>,
) -> PyResult<PyVplSet> {
    let profile = parse_profile(profile)?;
    let s = Arc::clone(&scene.inner);
    let vpls = run(py, move || vpl::light_path_vpls(&s, n, seed, bounces))?;
    PyVplSet::new_checked(vpls, profile, default_radius(scene, radius))
}

/// The reflective-shadow-map baseline (see `vplace.rsm_vpls`).
#[pyfunction]
#[pyo3(signature = (scene, n, *, profile = "cosine", radius = None))]
fn rsm_vpls(
    py: Python<'_>,
    scene: &PyScene,
    n: usize,
    profile: &str,
    radius: Option<f32>,
) -> PyResult<PyVplSet> {
    let profile = parse_profile(profile)?;
    let s = Arc::clone(&scene.inner);
    let vpls = run(py, move || rsm::rsm_vpls(&s, n))?;
    PyVplSet::new_checked(vpls, profile, default_radius(scene, radius))
}

impl PyVplSet {
    /// The radii of :attr:`radii`: given, or from the set's spacing; zeros for omni VPLs.
    fn radii_vec(&self) -> Vec<f32> {
        match (&self.given_radii, self.profile) {
            (Some(r), _) => r.to_vec(),
            (None, Profile::Cosine) => near_field_radii(&self.vpls, self.radius),
            (None, Profile::Omni) => vec![0.0; self.vpls.len()],
        }
    }
}

/// The indirect image of `vpls` over `view` (see `vplace.evaluate`). With `near_field` (None:
/// the set's own, `VplSet.near_field`), the short-range light the set cannot carry is gathered
/// from the view's pixels and added (`vplace_core::shade::near_field`); its distance is in the
/// stats (0 without).
#[pyfunction]
#[pyo3(signature = (scene, view, vpls, *, tile = 16, progress = None, brute_force = false, near_field = None))]
#[allow(clippy::too_many_arguments)]
fn evaluate<'py>(
    py: Python<'py>,
    scene: &PyScene,
    view: &PyView,
    vpls: &PyVplSet,
    tile: usize,
    progress: Option<&PyProgress>,
    brute_force: bool,
    near_field: Option<bool>,
) -> PyResult<(Bound<'py, PyAny>, PyEvalStats)> {
    let near_field = near_field.unwrap_or(vpls.near_field);
    let s = Arc::clone(&scene.inner);
    let v = Arc::clone(&view.inner);
    let set = Arc::clone(&vpls.vpls);
    let params = vpls.eval_params(tile);
    let given = vpls.given_radii.clone();
    // The set's radii as `VplSet.radii` gives them (omni VPLs without given radii: points).
    let points = given.is_none() && vpls.profile == Profile::Omni;
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let (h, w) = (v.height, v.width);
    let (image, stats, distance) = run(py, move || {
        let g = v.gbuffer();
        let radii = given.unwrap_or_else(|| Arc::new(vpl::near_field_radii(&set, params.radius)));
        let distance = if near_field && !points {
            near_field::gather_distance(&radii)
        } else {
            0.0
        };
        let (mut image, stats) = evaluator::evaluate_with_radii(
            &s,
            &g,
            &set,
            &radii,
            &params,
            prog.as_deref(),
            brute_force,
        )?;
        if distance > 0.0 {
            let near = near_field::near_field_light(&v, &image, distance, Some(&s))?;
            image.iter_mut().zip(near).for_each(|(a, b)| *a += b);
        }
        Ok((image, stats, distance))
    })?;
    let out = PyArray1::from_vec(py, image).reshape([h, w, 3])?.into_any();
    Ok((
        out,
        PyEvalStats {
            shadow_rays: stats.shadow_rays,
            pairs: stats.pairs,
            seconds: stats.seconds,
            near_field_distance: distance,
        },
    ))
}

/// The near-field light of `view` gathered within `distance` (scene units) from the VPLs'
/// indirect image `vpl_indirect` of that view (see `vplace.near_field_light`): what
/// `evaluate(..., near_field=True)` adds to the image it returns with `near_field=False`,
/// without evaluating the VPLs again.
#[pyfunction]
fn near_field_light<'py>(
    py: Python<'py>,
    scene: &PyScene,
    view: &PyView,
    vpl_indirect: &Bound<'py, PyAny>,
    distance: f32,
) -> PyResult<Bound<'py, PyAny>> {
    let v = Arc::clone(&view.inner);
    let (h, w) = (v.height, v.width);
    let checked = array::<f32>(
        vpl_indirect,
        "vpl_indirect",
        &[Dim::Is(h), Dim::Is(w), Dim::Is(3)],
        "float32",
    )?;
    let values = slice(&checked, "vpl_indirect")?;
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(input_error(format!(
            "vpl_indirect holds a non-finite value at pixel ({}, {})",
            i / 3 / w,
            i / 3 % w
        )));
    }
    if !(distance >= 0.0 && distance.is_finite()) {
        return Err(input_error(format!(
            "distance must be finite and >= 0, got {distance}"
        )));
    }
    let image = values.to_vec();
    let s = Arc::clone(&scene.inner);
    let near = run(py, move || {
        near_field::near_field_light(&v, &image, distance, Some(&s))
    })?;
    Ok(PyArray1::from_vec(py, near).reshape([h, w, 3])?.into_any())
}

/// Where `near_field_light` within `distance` can reach on `view`, from its geometry alone:
/// `(receivers, sources)`, (H, W) bool each (see `vplace.near_field_reach`).
#[pyfunction]
fn near_field_reach<'py>(
    py: Python<'py>,
    view: &PyView,
    distance: f32,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let v = Arc::clone(&view.inner);
    let (h, w) = (v.height, v.width);
    let (receivers, sources) = run(py, move || near_field::near_field_reach(&v, distance))?;
    Ok((
        PyArray1::from_vec(py, receivers)
            .reshape([h, w])?
            .into_any(),
        PyArray1::from_vec(py, sources).reshape([h, w])?.into_any(),
    ))
}

/// The near-field gather distance of VPLs of near-field radii `radii` (see
/// `VplSet.near_field_distance`).
#[pyfunction]
fn near_field_distance(radii: Vec<f32>) -> f32 {
    near_field::gather_distance(&radii)
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyVplSet>()?;
    m.add_class::<PyEvalStats>()?;
    m.add_function(wrap_pyfunction!(uniform_vpls, m)?)?;
    m.add_function(wrap_pyfunction!(rsm_vpls, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(near_field_distance, m)?)?;
    m.add_function(wrap_pyfunction!(near_field_light, m)?)?;
    m.add_function(wrap_pyfunction!(near_field_reach, m)?)?;
    m.add("VPL_SURFACE_OFFSET", vpl::Vpl::SURFACE_OFFSET)?;
    m.add("MAX_BOUNCES", vpl::MAX_BOUNCES)?;
    Ok(())
}
