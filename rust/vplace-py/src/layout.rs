//! The layout (strata, allocation, iteration), the RSM baseline and SSIM.

use glam::Mat4;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;
use vplace_core::{
    evaluator::EvalParams,
    layout::{Allocation, LayoutParams, LayoutView, Strata},
    metrics, refine, rsm, vpl,
};

use crate::arrays::{array, slice, Dim, GBufferArrays};
use crate::errors::run;
use crate::scene::{parse_profile, vpls_to_dict, PyProgress, PyScene};

fn counts_grid<'py>(
    py: Python<'py>,
    strata: &Strata,
    a: &Allocation,
) -> PyResult<Bound<'py, PyAny>> {
    let cells = strata.offscreen();
    let counts: Vec<i64> = a.counts[..cells].iter().map(|&c| c as i64).collect();
    Ok(PyArray1::from_vec(py, counts)
        .reshape([strata.cells_y, strata.cells_x])?
        .into_any())
}

/// VPLs the allocation gives the off-screen strata.
fn offscreen_count(strata: &Strata, a: &Allocation) -> usize {
    a.counts[strata.offscreen()..].iter().sum()
}

/// Lays out `budget` VPLs for one view (DESIGN, Layout) and, when `indirect` is given, refines
/// the allocation against it. See `vplace.layout` for the arguments and the returned dict.
#[pyfunction]
#[pyo3(signature = (scene, position, normal, albedo, covered, diffuse_direct, camera_position,
    world_to_clip, *, indirect = None, predicted = None, budget = 256, alpha = 1.0, cell_px = 16,
    light_rays = 4096, bounces = vpl::MAX_BOUNCES, seed = 0, stride = 4, iterations = 3, tolerance = 0.01, step = 0.5,
    profile = "cosine", r_min = 0.01, tile = 16, progress = None))]
#[allow(clippy::too_many_arguments)]
fn layout<'py>(
    py: Python<'py>,
    scene: &PyScene,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    diffuse_direct: &Bound<'py, PyAny>,
    camera_position: [f32; 3],
    world_to_clip: [[f32; 4]; 4],
    indirect: Option<&Bound<'py, PyAny>>,
    predicted: Option<&Bound<'py, PyAny>>,
    budget: usize,
    alpha: f32,
    cell_px: usize,
    light_rays: usize,
    bounces: usize,
    seed: u64,
    stride: usize,
    iterations: usize,
    tolerance: f64,
    step: f64,
    profile: &str,
    r_min: f32,
    tile: usize,
    progress: Option<&PyProgress>,
) -> PyResult<Bound<'py, PyDict>> {
    let profile = parse_profile(profile)?;
    let arrays = GBufferArrays::read(position, normal, albedo, covered)?;
    let (h, w) = (arrays.height, arrays.width);
    let img3 = arrays.img3();
    let dd = array::<f32>(diffuse_direct, "diffuse_direct", &img3, "float32")?;
    let ind = indirect
        .map(|a| array::<f32>(a, "indirect", &img3, "float32"))
        .transpose()?;
    let cells = [
        Dim::Is(h.div_ceil(cell_px.max(1))),
        Dim::Is(w.div_ceil(cell_px.max(1))),
    ];
    let pred = predicted
        .map(|a| array::<f64>(a, "predicted", &cells, "float64"))
        .transpose()?;
    let view = LayoutView {
        gbuffer: arrays.gbuffer()?,
        diffuse_direct: slice(&dd, "diffuse_direct")?,
        camera_position: glam::Vec3::from_array(camera_position),
        // Rows as numpy and Blender write them.
        world_to_clip: Mat4::from_cols_array_2d(&world_to_clip).transpose(),
    };
    let indirect = ind.as_ref().map(|a| slice(a, "indirect")).transpose()?;
    let predicted = pred.as_ref().map(|a| slice(a, "predicted")).transpose()?;
    let params = refine::RefineParams {
        layout: LayoutParams {
            budget,
            alpha,
            cell_px,
            light_rays,
            seed,
            bounces,
        },
        eval: EvalParams {
            profile,
            r_min,
            tile,
        },
        stride,
        max_iterations: iterations,
        tolerance,
        step,
    };
    let s = Arc::clone(&scene.inner);
    let prog = progress.map(|p| Arc::clone(&p.inner));
    let d = PyDict::new(py);
    match indirect {
        Some(ind) => {
            let r = run(py, move || {
                refine::refine(&s, &view, ind, predicted, &params, prog.as_deref())
            })?;
            let best = &r.iterations[r.best].allocation;
            let vd = vpls_to_dict(py, &r.vpls)?;
            d.update(vd.as_mapping())?;
            d.set_item("counts", counts_grid(py, &r.strata, best)?)?;
            d.set_item("offscreen_count", offscreen_count(&r.strata, best))?;
            d.set_item("pool_count", best.pool_count)?;
            d.set_item(
                "errors",
                r.iterations.iter().map(|i| i.error).collect::<Vec<_>>(),
            )?;
            d.set_item(
                "shadow_rays",
                r.iterations
                    .iter()
                    .map(|i| i.shadow_rays)
                    .collect::<Vec<_>>(),
            )?;
            d.set_item(
                "reused_rays",
                r.iterations
                    .iter()
                    .map(|i| i.reused_rays)
                    .collect::<Vec<_>>(),
            )?;
            d.set_item(
                "seconds",
                r.iterations.iter().map(|i| i.seconds).collect::<Vec<_>>(),
            )?;
            d.set_item("best", r.best)?;
            set_strata(py, &d, &r.strata)?;
        }
        None => {
            let lp = params.layout;
            let (vpls, a, strata) = run(py, move || {
                vplace_core::layout::layout(&s, &view, predicted, &lp)
            })?;
            let vd = vpls_to_dict(py, &vpls)?;
            d.update(vd.as_mapping())?;
            d.set_item("counts", counts_grid(py, &strata, &a)?)?;
            d.set_item("offscreen_count", offscreen_count(&strata, &a))?;
            d.set_item("pool_count", a.pool_count)?;
            d.set_item("errors", Vec::<f64>::new())?;
            d.set_item("shadow_rays", Vec::<u64>::new())?;
            d.set_item("reused_rays", Vec::<u64>::new())?;
            d.set_item("seconds", Vec::<f64>::new())?;
            d.set_item("best", py.None())?;
            set_strata(py, &d, &strata)?;
        }
    }
    Ok(d)
}

fn set_strata(py: Python<'_>, d: &Bound<'_, PyDict>, s: &Strata) -> PyResult<()> {
    let cells = s.offscreen();
    let flux: Vec<f32> = s.flux[..cells].iter().flat_map(|f| f.to_array()).collect();
    d.set_item(
        "strata_flux",
        PyArray1::from_vec(py, flux).reshape([s.cells_y, s.cells_x, 3])?,
    )?;
    d.set_item("offscreen_flux", s.offscreen_flux().to_array())?;
    d.set_item("offscreen_view_weight", s.view_weight[cells..].to_vec())?;
    d.set_item("candidates", s.emitters.len())?;
    d.set_item("light_hits_on_screen", s.light_hits_on_screen)?;
    Ok(())
}

/// The reflective-shadow-map baseline: `n` rays on a regular lattice over the lights' views,
/// first hits become VPLs. Returns a dict of float32 arrays `position`, `normal`, `flux`, (m, 3),
/// `m <= n` (rays that leave the scene make none).
#[pyfunction]
fn rsm_vpls<'py>(py: Python<'py>, scene: &PyScene, n: usize) -> PyResult<Bound<'py, PyDict>> {
    let s = Arc::clone(&scene.inner);
    let vpls = run(py, move || rsm::rsm_vpls(&s, n))?;
    vpls_to_dict(py, &vpls)
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

/// Registers this file's functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(layout, m)?)?;
    m.add_function(wrap_pyfunction!(rsm_vpls, m)?)?;
    m.add_function(wrap_pyfunction!(ssim, m)?)?;
    Ok(())
}
