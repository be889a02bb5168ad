//! Features and regression: the registry, per-cell extraction, and the fits (on a capture or
//! on a given design matrix).

use glam::Vec3;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use vplace_core::{
    features::{self, CellFeatures, FeatureInput, StrongestLight, FEATURES, FEATURE_COUNT},
    regression::{self, DropReason, Fit, FitParams},
};

use crate::arrays::{array, slice, Dim, GBufferArrays};
use crate::errors::{input_error, run};

/// The feature registry: a list of `(name, doc, origin)` with origin `"paper"` or `"ours"`, in
/// column order.
#[pyfunction]
fn feature_registry() -> Vec<(&'static str, &'static str, &'static str)> {
    FEATURES
        .iter()
        .map(|f| {
            let origin = match f.origin {
                features::Origin::Paper => "paper",
                features::Origin::Ours => "ours",
            };
            (f.name, f.doc, origin)
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn fit_params(
    folds: usize,
    select: bool,
    min_cv_gain: f64,
    collinear_rtol: f64,
    rank_rtol: Option<f64>,
    ridge_above: f64,
    seed: u64,
) -> FitParams {
    FitParams {
        folds,
        select,
        min_cv_gain,
        collinear_rtol,
        rank_rtol,
        ridge_above,
        seed,
    }
}

fn light(
    position: Option<[f32; 3]>,
    direction: Option<[f32; 3]>,
) -> PyResult<Option<StrongestLight>> {
    match (position, direction) {
        (Some(_), Some(_)) => Err(input_error(
            "give light_position or light_direction, not both",
        )),
        (Some(p), None) => Ok(Some(StrongestLight::Position(Vec3::from_array(p)))),
        (None, Some(d)) => Ok(Some(StrongestLight::Direction(Vec3::from_array(d)))),
        (None, None) => Ok(None),
    }
}

/// Runs `f` on a checked [`FeatureInput`] built from the numpy passes.
#[allow(clippy::too_many_arguments)]
fn with_input<'py, T: Send>(
    py: Python<'py>,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    direct: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    gi: Option<&Bound<'py, PyAny>>,
    specular: Option<&Bound<'py, PyAny>>,
    light: Option<StrongestLight>,
    f: impl FnOnce(&FeatureInput<'_>) -> vplace_core::Result<T> + Send,
) -> PyResult<T> {
    let arrays = GBufferArrays::read(position, normal, albedo, covered)?;
    let (img3, img1) = (arrays.img3(), arrays.img1());
    let dep = array::<f32>(depth, "depth", &img1, "float32")?;
    let dir = array::<f32>(direct, "direct", &img3, "float32")?;
    let gi = gi
        .map(|g| array::<f32>(g, "gi", &img3, "float32"))
        .transpose()?;
    let spec = specular
        .map(|s| array::<f32>(s, "specular", &img3, "float32"))
        .transpose()?;
    let g = arrays.gbuffer()?;
    let input = FeatureInput {
        width: g.width,
        height: g.height,
        position: g.position,
        normal: g.normal,
        albedo: g.albedo,
        depth: slice(&dep, "depth")?,
        direct: slice(&dir, "direct")?,
        gi: gi.as_ref().map(|g| slice(g, "gi")).transpose()?,
        specular: spec.as_ref().map(|s| slice(s, "specular")).transpose()?,
        covered: g.covered,
        light,
    };
    run(py, move || f(&input))
}

fn cells_to_dict<'py>(py: Python<'py>, c: CellFeatures) -> PyResult<Bound<'py, PyDict>> {
    let n = c.cells.len();
    let d = PyDict::new(py);
    d.set_item("cell_px", c.cell_px)?;
    d.set_item("cells_x", c.cells_x)?;
    d.set_item("cells_y", c.cells_y)?;
    let cells: Vec<i64> = c.cells.iter().map(|&i| i as i64).collect();
    d.set_item("cells", PyArray1::from_vec(py, cells))?;
    d.set_item(
        "values",
        PyArray1::from_vec(py, c.values).reshape([n, FEATURE_COUNT])?,
    )?;
    d.set_item("label", c.label.map(|l| PyArray1::from_vec(py, l)))?;
    let pixels: Vec<i64> = c.pixels.iter().map(|&i| i64::from(i)).collect();
    d.set_item("pixels", PyArray1::from_vec(py, pixels))?;
    d.set_item("empty_cells", c.empty_cells)?;
    d.set_item("masked_pixels", c.masked_pixels)?;
    d.set_item("available", c.available.to_vec())?;
    Ok(d)
}

fn reason_to_dict<'py>(py: Python<'py>, j: usize, r: &DropReason) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("index", j)?;
    match r {
        DropReason::Unavailable(why) => {
            d.set_item("reason", "unavailable")?;
            d.set_item("detail", *why)?;
        }
        DropReason::Constant => d.set_item("reason", "constant")?,
        DropReason::ConstantLabel => d.set_item("reason", "constant_label")?,
        DropReason::Collinear { residual, with } => {
            d.set_item("reason", "collinear")?;
            d.set_item("residual", *residual)?;
            d.set_item("with", with.clone())?;
        }
        DropReason::NoCvGain {
            cv_r2_with,
            cv_r2_without,
        } => {
            d.set_item("reason", "no_cv_gain")?;
            d.set_item("cv_r2_with", *cv_r2_with)?;
            d.set_item("cv_r2_without", *cv_r2_without)?;
        }
    }
    Ok(d)
}

fn fit_to_dict<'py>(py: Python<'py>, f: Fit) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("n", f.n)?;
    d.set_item("p", f.p)?;
    d.set_item("intercept", f.intercept)?;
    d.set_item("coefficients", PyArray1::from_vec(py, f.coefficients))?;
    d.set_item("weights", PyArray1::from_vec(py, f.weights))?;
    d.set_item("kept", f.kept.clone())?;
    let dropped = PyList::empty(py);
    for (j, r) in &f.dropped {
        dropped.append(reason_to_dict(py, *j, r)?)?;
    }
    d.set_item("dropped", dropped)?;
    d.set_item("r2", f.r2)?;
    d.set_item("adjusted_r2", f.adjusted_r2)?;
    d.set_item("cv_r2", f.cv_r2)?;
    d.set_item("folds", f.folds)?;
    d.set_item("condition_number", f.condition_number)?;
    d.set_item("rank", f.rank)?;
    d.set_item("ridge_lambda", f.ridge_lambda)?;
    d.set_item("fitted", PyArray1::from_vec(py, f.fitted))?;
    Ok(d)
}

/// Per-cell features of one view (see `vplace_core::features`). Returns a dict: `cell_px`,
/// `cells_x`, `cells_y`, `cells` (int64, flat indices of the non-empty cells), `values`
/// (float64, (n, 14), raw means), `label` (float64 (n,) or None without `gi`), `pixels`,
/// `empty_cells`, `masked_pixels`, `available` (14 bools).
#[pyfunction]
#[pyo3(signature = (position, normal, albedo, depth, direct, covered, *, gi = None,
    specular = None, light_position = None, light_direction = None, cell_px = 16))]
#[allow(clippy::too_many_arguments)]
fn extract_features<'py>(
    py: Python<'py>,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    direct: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    gi: Option<&Bound<'py, PyAny>>,
    specular: Option<&Bound<'py, PyAny>>,
    light_position: Option<[f32; 3]>,
    light_direction: Option<[f32; 3]>,
    cell_px: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let l = light(light_position, light_direction)?;
    let cells = with_input(
        py,
        position,
        normal,
        albedo,
        depth,
        direct,
        covered,
        gi,
        specular,
        l,
        |inp| features::extract_features(inp, cell_px),
    )?;
    cells_to_dict(py, cells)
}

/// Extracts the features of a view with its GI image and fits the label on them. Returns
/// `(features, fit, feature_min, feature_max)`: the dicts of `extract_features` and
/// `fit_design`, and the Min-Max ranges (float64 (14,)).
#[pyfunction]
#[pyo3(signature = (position, normal, albedo, depth, direct, covered, gi, *, specular = None,
    light_position = None, light_direction = None, cell_px = 16, folds = 5, select = true,
    min_cv_gain = 1e-3, collinear_rtol = 1e-6, rank_rtol = None, ridge_above = 1e6,
    seed = 0x5eed))]
#[allow(clippy::too_many_arguments)]
#[allow(clippy::type_complexity)]
fn fit_capture<'py>(
    py: Python<'py>,
    position: &Bound<'py, PyAny>,
    normal: &Bound<'py, PyAny>,
    albedo: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    direct: &Bound<'py, PyAny>,
    covered: &Bound<'py, PyAny>,
    gi: &Bound<'py, PyAny>,
    specular: Option<&Bound<'py, PyAny>>,
    light_position: Option<[f32; 3]>,
    light_direction: Option<[f32; 3]>,
    cell_px: usize,
    folds: usize,
    select: bool,
    min_cv_gain: f64,
    collinear_rtol: f64,
    rank_rtol: Option<f64>,
    ridge_above: f64,
    seed: u64,
) -> PyResult<(
    Bound<'py, PyDict>,
    Bound<'py, PyDict>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
)> {
    let l = light(light_position, light_direction)?;
    let params = fit_params(
        folds,
        select,
        min_cv_gain,
        collinear_rtol,
        rank_rtol,
        ridge_above,
        seed,
    );
    let (cells, model) = with_input(
        py,
        position,
        normal,
        albedo,
        depth,
        direct,
        covered,
        Some(gi),
        specular,
        l,
        |inp| {
            let cells = features::extract_features(inp, cell_px)?;
            let model = features::fit_cells(&cells, &params)?;
            Ok((cells, model))
        },
    )?;
    let lo = PyArray1::from_vec(py, model.ranges.min).into_any();
    let hi = PyArray1::from_vec(py, model.ranges.max).into_any();
    Ok((
        cells_to_dict(py, cells)?,
        fit_to_dict(py, model.fit)?,
        lo,
        hi,
    ))
}

/// Fits `y` (float64 (n,)) on the columns of `x` (float64 (n, p)); the low-level solver of
/// `vplace_core::regression::fit`. Non-finite values are an `InputError`. Returns a dict:
/// `intercept`, `coefficients`, `weights` (float64 (p,)), `kept` (indices), `dropped` (list of
/// dicts with `index`, `reason` and details), `r2`, `adjusted_r2`, `cv_r2`, `folds`,
/// `condition_number`, `rank`, `ridge_lambda`, `fitted`, `n`, `p`.
#[pyfunction]
#[pyo3(signature = (x, y, *, folds = 5, select = true, min_cv_gain = 1e-3,
    collinear_rtol = 1e-6, rank_rtol = None, ridge_above = 1e6, seed = 0x5eed))]
#[allow(clippy::too_many_arguments)]
fn fit_design<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    folds: usize,
    select: bool,
    min_cv_gain: f64,
    collinear_rtol: f64,
    rank_rtol: Option<f64>,
    ridge_above: f64,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let xa = array::<f64>(x, "x", &[Dim::Any, Dim::Any], "float64")?;
    let (n, p) = (xa.shape()[0], xa.shape()[1]);
    let ya = array::<f64>(y, "y", &[Dim::Is(n)], "float64")?;
    let (xs, ys) = (slice(&xa, "x")?, slice(&ya, "y")?);
    let params = fit_params(
        folds,
        select,
        min_cv_gain,
        collinear_rtol,
        rank_rtol,
        ridge_above,
        seed,
    );
    let f = run(py, move || regression::fit(xs, ys, p, &params))?;
    fit_to_dict(py, f)
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(feature_registry, m)?)?;
    m.add_function(wrap_pyfunction!(extract_features, m)?)?;
    m.add_function(wrap_pyfunction!(fit_capture, m)?)?;
    m.add_function(wrap_pyfunction!(fit_design, m)?)?;
    Ok(())
}
