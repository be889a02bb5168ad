//! Features and regression: the registry, per-cell extraction, and the `Fit` model (fitted on
//! views or on a given design matrix).

use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;
use vplace_core::{
    fit::features::{
        self, CellFeatures, CellModel, StrongestLight, ViewFit, ViewFitParams, FEATURES,
        FEATURE_COUNT,
    },
    fit::model::{light_to_tuple, Fitted, Model},
    fit::regression::{self, Fit, FitParams},
    view::View,
};

use crate::arrays::{array, slice, Dim};
use crate::errors::{input_error, run};
use crate::params::PyFitParams;
use crate::scene::PyScene;
use crate::view::{views_of, PyView};

/// The feature registry: a list of `(name, doc, origin, surface)` in column order, with origin
/// `"paper"` or `"ours"` and `surface` true for a property of the surface (the same from every
/// view; only these are fitted with `surface_only`).
#[pyfunction]
fn feature_registry() -> Vec<(&'static str, &'static str, &'static str, bool)> {
    FEATURES
        .iter()
        .map(|f| {
            let origin = match f.origin {
                features::Origin::Paper => "paper",
                features::Origin::Ours => "ours",
            };
            (f.name, f.doc, origin, f.surface)
        })
        .collect()
}

/// A fitted linear model of the per-cell label (or of a given design) and its diagnostics: the
/// core's [`Model`].
#[pyclass(name = "Fit", module = "vplace._native", frozen)]
pub struct PyFit {
    model: Model,
}

impl PyFit {
    fn new(names: Vec<String>, fitted: Fitted) -> Self {
        Self {
            model: Model::new(names, fitted),
        }
    }

    fn fit(&self) -> &Fit {
        self.model.fit()
    }

    fn cells(&self) -> PyResult<&CellModel> {
        self.model.cells().ok_or_else(|| {
            input_error("this model was fitted on a design matrix; use predict_design")
        })
    }

    fn views(&self) -> &[ViewFit] {
        self.model.views()
    }

    /// The core model, for the layout.
    pub fn cell_model(&self) -> PyResult<&CellModel> {
        self.cells()
    }
}

#[pymethods]
impl PyFit {
    /// Names of every design column (the feature registry for a fit on views).
    #[getter]
    fn feature_names(&self) -> Vec<String> {
        self.model.names.clone()
    }

    /// The kept columns, in registry order.
    #[getter]
    fn kept(&self) -> Vec<String> {
        self.fit()
            .kept
            .iter()
            .map(|&j| self.model.names[j].clone())
            .collect()
    }

    /// Each dropped column with the reason, in the order they were dropped.
    #[getter]
    fn dropped<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, why) in &self.model.dropped {
            d.set_item(name, why)?;
        }
        Ok(d)
    }

    /// `b0`, on the (normalized) design scale.
    #[getter]
    fn intercept(&self) -> f64 {
        self.fit().intercept
    }

    /// `b_j` of each kept column.
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let f = self.fit();
        let d = PyDict::new(py);
        for &j in &f.kept {
            d.set_item(&self.model.names[j], f.coefficients[j])?;
        }
        Ok(d)
    }

    /// `|b_j| / sum |b_k|` of each kept column: sums to 1, or all zero when every coefficient is.
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let f = self.fit();
        let d = PyDict::new(py);
        for &j in &f.kept {
            d.set_item(&self.model.names[j], f.weights[j])?;
        }
        Ok(d)
    }

    /// R^2 on the fitted rows.
    #[getter]
    fn r2(&self) -> f64 {
        self.fit().r2
    }

    /// Adjusted R^2, or None when there are too few rows.
    #[getter]
    fn adjusted_r2(&self) -> Option<f64> {
        self.fit().adjusted_r2
    }

    /// Cross-validated R^2 of the kept columns, when CV ran.
    #[getter]
    fn cv_r2(&self) -> Option<f64> {
        self.fit().cv_r2
    }

    /// CV folds used (0: no CV).
    #[getter]
    fn folds(&self) -> usize {
        self.fit().folds
    }

    /// Condition number of the standardized design of the kept columns.
    #[getter]
    fn condition_number(&self) -> f64 {
        self.fit().condition_number
    }

    /// Numerical rank of that design.
    #[getter]
    fn rank(&self) -> usize {
        self.fit().rank
    }

    /// Ridge term of the fallback solve (0 when unused).
    #[getter]
    fn ridge_lambda(&self) -> f64 {
        self.fit().ridge_lambda
    }

    /// Rows fitted (cells of every view, or design rows).
    #[getter]
    fn n_cells(&self) -> usize {
        self.fit().n
    }

    /// Fitted value of every row (empty for a loaded model).
    #[getter]
    fn fitted<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.fit().fitted)
    }

    /// Cell size in pixels, or None for a design fit.
    #[getter]
    fn cell_px(&self) -> Option<usize> {
        self.cells().ok().map(|m| m.cell_px)
    }

    /// The light of the light-cosine feature, `("position" | "direction", xyz)`, or None.
    #[getter]
    fn light(&self) -> Option<(&'static str, [f32; 3])> {
        self.cells().ok().and_then(|m| m.light).map(light_to_tuple)
    }

    /// Names of the views fitted on, in order.
    #[getter]
    fn view_names(&self) -> Vec<String> {
        self.views().iter().map(|v| v.name.clone()).collect()
    }

    /// R^2 of each fitted view over its own cells (None where its label is constant).
    #[getter]
    fn view_r2<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for v in self.views() {
            d.set_item(&v.name, v.r2)?;
        }
        Ok(d)
    }

    /// Cells without a usable pixel, over every fitted view.
    #[getter]
    fn empty_cells(&self) -> usize {
        self.views().iter().map(|v| v.empty_cells).sum()
    }

    /// Covered pixels masked for non-finite passes, over every fitted view.
    #[getter]
    fn masked_pixels(&self) -> usize {
        self.views().iter().map(|v| v.masked_pixels).sum()
    }

    /// Min-Max lower bound of every feature over the fitted cells, or None for a design fit.
    #[getter]
    fn feature_min(&self) -> Option<Vec<f64>> {
        self.cells().ok().map(|m| m.ranges.min.clone())
    }

    /// Min-Max upper bound of every feature over the fitted cells, or None for a design fit.
    #[getter]
    fn feature_max(&self) -> Option<Vec<f64>> {
        self.cells().ok().map(|m| m.ranges.max.clone())
    }

    /// The predicted label of every cell of `view` (float64 (cells_y, cells_x), 0 where a cell
    /// sees no geometry); the view needs no indirect image.
    fn predict<'py>(&self, py: Python<'py>, view: &PyView) -> PyResult<Bound<'py, PyAny>> {
        let model = self.cells()?.clone();
        let v = Arc::clone(&view.inner);
        let c = model.cell_px;
        let (cy, cx) = (v.height.div_ceil(c), v.width.div_ceil(c));
        let out = run(py, move || model.predict_view(&v))?;
        Ok(PyArray1::from_vec(py, out).reshape([cy, cx])?.into_any())
    }

    /// Per kept feature name, the fraction of the cells of `view` outside the range the model
    /// was fitted on (where `predict` holds the feature at the range's edge).
    fn out_of_range(&self, py: Python<'_>, view: &PyView) -> PyResult<Vec<(String, f64)>> {
        let model = self.cells()?.clone();
        let v = Arc::clone(&view.inner);
        let out = run(py, move || model.out_of_range_view(&v))?;
        Ok(out
            .into_iter()
            .map(|(j, f)| (self.model.names[j].clone(), f))
            .collect())
    }

    /// The prediction for rows of the design columns (float64 (n, len(feature_names))).
    fn predict_design<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let p = self.model.names.len();
        let xa = array::<f64>(x, "x", &[Dim::Any, Dim::Is(p)], "float64")?;
        let xs = slice(&xa, "x")?;
        let f = self.fit().clone();
        Ok(PyArray1::from_vec(py, run(py, move || f.predict(xs))?))
    }

    /// The model as JSON (everything but the fitted values; the core's document).
    fn to_json(&self) -> String {
        self.model.to_json()
    }

    /// Loads a model saved by `to_json`.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        Ok(Self {
            model: Model::from_json(text).map_err(crate::errors::to_py)?,
        })
    }

    /// The model as a readable table.
    fn __str__(&self) -> String {
        let f = self.fit();
        let num = |v: Option<f64>| v.map_or("n/a".to_owned(), |v| format!("{v:.4}"));
        let mut head = format!("vplace fit: {} cells", f.n);
        if let Fitted::Views(m) = &self.model.fitted {
            head += &format!(
                " of {} px from {} view(s) ({} without geometry excluded, {} non-finite pixels masked)",
                m.cell_px,
                m.views.len(),
                self.empty_cells(),
                self.masked_pixels()
            );
        }
        let cv = if f.folds > 0 {
            format!("CV R^2 ({}-fold) {}", f.folds, num(f.cv_r2))
        } else {
            "CV R^2 n/a".to_owned()
        };
        let ridge = if f.ridge_lambda > 0.0 {
            format!("   ridge lambda {:.2e}", f.ridge_lambda)
        } else {
            String::new()
        };
        let mut lines = vec![
            head,
            format!(
                "R^2 {}   adjusted R^2 {}   {cv}",
                num(Some(f.r2)),
                num(f.adjusted_r2)
            ),
            format!(
                "condition number {:.3e}   rank {}{ridge}",
                f.condition_number, f.rank
            ),
        ];
        if self.views().len() > 1 {
            for v in self.views() {
                lines.push(format!(
                    "  view {:?}: {} cells, R^2 {}",
                    v.name,
                    v.cells,
                    num(v.r2)
                ));
            }
        }
        lines.push(String::new());
        lines.push(format!(
            "{:<20} {:>14} {:>8}",
            "feature", "coefficient", "weight"
        ));
        lines.push(format!("{:<20} {:>14.6e}", "intercept", f.intercept));
        let mut order = f.kept.clone();
        order.sort_by(|&a, &b| f.weights[b].total_cmp(&f.weights[a]).then(a.cmp(&b)));
        for j in order {
            lines.push(format!(
                "{:<20} {:>14.6e} {:>8.4}",
                self.model.names[j], f.coefficients[j], f.weights[j]
            ));
        }
        if !self.model.dropped.is_empty() {
            lines.push(String::new());
            lines.push("dropped:".to_owned());
            for (name, why) in &self.model.dropped {
                lines.push(format!("  {name:<20} {why}"));
            }
        }
        lines.join("\n")
    }

    fn __repr__(&self) -> String {
        format!(
            "Fit({} rows, kept {:?}, R^2 {:.4})",
            self.fit().n,
            self.kept(),
            self.fit().r2
        )
    }
}

fn registry_names() -> Vec<String> {
    FEATURES.iter().map(|f| f.name.to_owned()).collect()
}

/// The per-cell features of one view (`vplace.extract_features`).
#[pyclass(name = "CellFeatures", module = "vplace._native", frozen)]
pub struct PyCellFeatures {
    inner: CellFeatures,
}

#[pymethods]
impl PyCellFeatures {
    /// The feature names, in column order.
    #[getter]
    fn names(&self) -> Vec<String> {
        registry_names()
    }
    /// Cell size, pixels.
    #[getter]
    fn cell_px(&self) -> usize {
        self.inner.cell_px
    }
    /// Cells per image row.
    #[getter]
    fn cells_x(&self) -> usize {
        self.inner.cells_x
    }
    /// Cells per image column.
    #[getter]
    fn cells_y(&self) -> usize {
        self.inner.cells_y
    }
    /// Flat grid index (row-major, row 0 at the top) of every non-empty cell, int64.
    #[getter]
    fn cells<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let cells: Vec<i64> = self.inner.cells.iter().map(|&i| i as i64).collect();
        PyArray1::from_vec(py, cells)
    }
    /// Raw per-cell values, float64 (cells, features).
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let n = self.inner.cells.len();
        Ok(PyArray1::from_slice(py, &self.inner.values)
            .reshape([n, FEATURE_COUNT])?
            .into_any())
    }
    /// The label per listed cell (float64), or None without an indirect image.
    #[getter]
    fn label<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner
            .label
            .as_ref()
            .map(|l| PyArray1::from_slice(py, l))
    }
    /// Usable pixels per listed cell, int64.
    #[getter]
    fn pixels<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let pixels: Vec<i64> = self.inner.pixels.iter().map(|&i| i64::from(i)).collect();
        PyArray1::from_vec(py, pixels)
    }
    /// Cells of the grid without a usable pixel.
    #[getter]
    fn empty_cells(&self) -> usize {
        self.inner.empty_cells
    }
    /// Covered pixels dropped for a non-finite pass.
    #[getter]
    fn masked_pixels(&self) -> usize {
        self.inner.masked_pixels
    }
    /// Per feature: false when its input was not given.
    #[getter]
    fn available(&self) -> Vec<bool> {
        self.inner.available.to_vec()
    }

    fn __repr__(&self) -> String {
        format!(
            "CellFeatures({} cells of {} px, {} x {} grid)",
            self.inner.cells.len(),
            self.inner.cell_px,
            self.inner.cells_x,
            self.inner.cells_y
        )
    }
}

/// The strongest light of `scene` for `views`.
fn light_for(scene: &PyScene, views: &[Arc<View>]) -> Option<StrongestLight> {
    let refs: Vec<&View> = views.iter().map(|v| v.as_ref()).collect();
    features::strongest_light(&scene.inner, &refs)
}

/// Per-cell features of one view (see `vplace.extract_features`).
#[pyfunction]
#[pyo3(signature = (scene, view, *, cell_px = 16))]
fn extract_features(
    py: Python<'_>,
    scene: &PyScene,
    view: &PyView,
    cell_px: usize,
) -> PyResult<PyCellFeatures> {
    let v = Arc::clone(&view.inner);
    let light = light_for(scene, std::slice::from_ref(&v));
    let inner = run(py, move || {
        features::extract_view_features(&v, light, cell_px)
    })?;
    Ok(PyCellFeatures { inner })
}

/// Fits one model on the cells of every view (see `vplace.fit`).
#[pyfunction]
#[pyo3(signature = (scene, views, params = None))]
fn fit(
    py: Python<'_>,
    scene: &PyScene,
    views: Vec<Bound<'_, PyView>>,
    params: Option<&PyFitParams>,
) -> PyResult<PyFit> {
    let views = views_of(&views);
    let light = light_for(scene, &views);
    let p = params.map_or(ViewFitParams::DEFAULT, |p| p.inner);
    let model = run(py, move || {
        let refs: Vec<&View> = views.iter().map(|v| v.as_ref()).collect();
        features::fit_views(&refs, light, p.cell_px, p.surface_only, &p.regression)
    })?;
    Ok(PyFit::new(registry_names(), Fitted::Views(model)))
}

/// Fits `y` (float64 (n,)) on the columns of `x` (float64 (n, p)) with the solver of `fit`
/// (see `vplace.fit_design`; only the regression's settings of `params` are read).
#[pyfunction]
#[pyo3(signature = (x, y, params = None, *, names = None))]
fn fit_design(
    py: Python<'_>,
    x: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    params: Option<&PyFitParams>,
    names: Option<Vec<String>>,
) -> PyResult<PyFit> {
    let xa = array::<f64>(x, "x", &[Dim::Any, Dim::Any], "float64")?;
    let (n, p) = (xa.shape()[0], xa.shape()[1]);
    let ya = array::<f64>(y, "y", &[Dim::Is(n)], "float64")?;
    let names = names.unwrap_or_else(|| (0..p).map(|j| format!("x{j}")).collect());
    if names.len() != p {
        return Err(input_error(format!(
            "names: expected {p} names, got {}",
            names.len()
        )));
    }
    let (xs, ys) = (slice(&xa, "x")?, slice(&ya, "y")?);
    let params = params.map_or(FitParams::DEFAULT, |p| p.inner.regression);
    let f = run(py, move || regression::fit(xs, ys, p, &params))?;
    Ok(PyFit::new(names, Fitted::Design(f)))
}

/// Registers this file's classes and functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyFit>()?;
    m.add_class::<PyCellFeatures>()?;
    m.add_function(wrap_pyfunction!(feature_registry, m)?)?;
    m.add_function(wrap_pyfunction!(extract_features, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit_design, m)?)?;
    Ok(())
}
