//! A fitted model with its column names and drop reasons, and its JSON document (the saved
//! model of the add-on's panel and the report's `model.json`).
//!
//! The document is an object with `format` = [`FORMAT`] and `version` = [`VERSION`], the
//! regression's fields (`feature_names`, `n`, `intercept`, `coefficients`, `weights`, `kept`,
//! `dropped` as `[name, reason]` pairs, `r2`, `adjusted_r2`, `cv_r2`, `folds`,
//! `condition_number` (null when infinite), `rank`, `ridge_lambda`) and, for a model fitted on
//! views, `cell_px`, `feature_min`, `feature_max`, `light` (`["position" | "direction", xyz]` or
//! null), `label_max` and `views` (`name`, `cells`, `empty_cells`, `masked_pixels`, `r2` each).
//! The fitted values are not saved. Floats are written in their shortest exact form (an `f32`
//! light as the `f64` it widens to), so a document reads back to the very same model.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{Result, VplaceError};
use crate::fit::features::{CellModel, MinMax, StrongestLight, ViewFit, FEATURE_COUNT};
use crate::fit::regression::{DropReason, Fit};

/// Saved-model format name.
pub const FORMAT: &str = "vplace.fit";
/// Saved-model format version.
pub const VERSION: u32 = 3;

/// What a model was fitted on.
#[derive(Debug, Clone, PartialEq)]
pub enum Fitted {
    /// The cells of captured views: predicts other views.
    Views(CellModel),
    /// A given design matrix.
    Design(Fit),
}

/// A fitted model with the names of its design columns. Invariant: `names.len()` is the fit's
/// column count (the feature registry's for [`Fitted::Views`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Name of every design column.
    pub names: Vec<String>,
    /// The fit.
    pub fitted: Fitted,
    /// `(name, why)` of every dropped column, in the order they were dropped.
    pub dropped: Vec<(String, String)>,
}

/// Why column `r` was dropped, in words (`names` name the columns of a collinearity).
#[must_use]
pub fn reason_text(r: &DropReason, names: &[String]) -> String {
    match r {
        DropReason::Unavailable(why) => format!("unavailable: {why}"),
        DropReason::Excluded(why) => format!("excluded: {why}"),
        DropReason::Constant => "constant over the cells".into(),
        DropReason::ConstantLabel => "the label is constant".into(),
        DropReason::Collinear { residual, with } => {
            let with: Vec<&str> = with.iter().map(|&j| names[j].as_str()).collect();
            let with = if with.is_empty() {
                "the intercept".to_owned()
            } else {
                with.join(", ")
            };
            format!("collinear with {with} (residual {residual:.1e})")
        }
        DropReason::NoCvGain {
            cv_r2_with,
            cv_r2_without,
        } => format!("no CV gain (CV R^2 {cv_r2_with:.4} with, {cv_r2_without:.4} without)"),
    }
}

/// The light of the light-cosine feature as `(kind, xyz)`.
#[must_use]
pub fn light_to_tuple(l: StrongestLight) -> (&'static str, [f32; 3]) {
    match l {
        StrongestLight::Position(p) => ("position", p.to_array()),
        StrongestLight::Direction(d) => ("direction", d.to_array()),
    }
}

impl Model {
    /// A model of `fitted` with column `names`; the drop reasons are put in words.
    #[must_use]
    pub fn new(names: Vec<String>, fitted: Fitted) -> Self {
        let fit = match &fitted {
            Fitted::Views(m) => &m.fit,
            Fitted::Design(f) => f,
        };
        let dropped = fit
            .dropped
            .iter()
            .map(|(j, r)| (names[*j].clone(), reason_text(r, &names)))
            .collect();
        Self {
            names,
            fitted,
            dropped,
        }
    }

    /// The regression.
    #[must_use]
    pub fn fit(&self) -> &Fit {
        match &self.fitted {
            Fitted::Views(m) => &m.fit,
            Fitted::Design(f) => f,
        }
    }

    /// The cell model, for a model fitted on views.
    #[must_use]
    pub fn cells(&self) -> Option<&CellModel> {
        match &self.fitted {
            Fitted::Views(m) => Some(m),
            Fitted::Design(_) => None,
        }
    }

    /// The fitted views (none for a design fit).
    #[must_use]
    pub fn views(&self) -> &[ViewFit] {
        self.cells().map_or(&[], |m| &m.views)
    }

    /// The model as a JSON document (see the module docs).
    #[must_use]
    pub fn to_json(&self) -> String {
        let f = self.fit();
        let cells = self.cells();
        let doc = Document {
            format: FORMAT.to_owned(),
            version: VERSION,
            feature_names: self.names.clone(),
            n: f.n,
            intercept: f.intercept,
            coefficients: f.coefficients.clone(),
            weights: f.weights.clone(),
            kept: f.kept.clone(),
            dropped: self.dropped.clone(),
            r2: f.r2,
            adjusted_r2: f.adjusted_r2,
            cv_r2: f.cv_r2,
            folds: f.folds,
            condition_number: f.condition_number.is_finite().then_some(f.condition_number),
            rank: f.rank,
            ridge_lambda: f.ridge_lambda,
            cell_px: cells.map(|m| m.cell_px),
            feature_min: cells.map(|m| m.ranges.min.clone()),
            feature_max: cells.map(|m| m.ranges.max.clone()),
            light: cells.map(|m| {
                m.light.map(|l| {
                    let (kind, v) = light_to_tuple(l);
                    (kind.to_owned(), v.map(f64::from))
                })
            }),
            label_max: cells.map(|m| m.label_max),
            views: cells.map(|m| {
                m.views
                    .iter()
                    .map(|v| ViewDoc {
                        name: v.name.clone(),
                        cells: v.cells,
                        empty_cells: v.empty_cells,
                        masked_pixels: v.masked_pixels,
                        r2: v.r2,
                    })
                    .collect()
            }),
        };
        serde_json::to_string(&doc).expect("a model document always serializes")
    }

    /// Reads a model saved by [`Model::to_json`]. Errors: not JSON, not a [`FORMAT`] version
    /// [`VERSION`] document, or columns that do not match the feature names.
    pub fn from_json(text: &str) -> Result<Self> {
        let doc: Document =
            serde_json::from_str(text).map_err(|e| bad(&format!("invalid JSON ({e})")))?;
        if doc.format != FORMAT || doc.version != VERSION {
            return Err(bad("wrong format or version"));
        }
        let p = doc.feature_names.len();
        if doc.coefficients.len() != p || doc.weights.len() != p || doc.kept.iter().any(|&j| j >= p)
        {
            return Err(bad("columns do not match the feature names"));
        }
        let fit = Fit {
            p,
            n: doc.n,
            intercept: doc.intercept,
            coefficients: doc.coefficients,
            weights: doc.weights,
            kept: doc.kept,
            dropped: Vec::new(),
            r2: doc.r2,
            adjusted_r2: doc.adjusted_r2,
            cv_r2: doc.cv_r2,
            folds: doc.folds,
            condition_number: doc.condition_number.unwrap_or(f64::INFINITY),
            rank: doc.rank,
            ridge_lambda: doc.ridge_lambda,
            fitted: Vec::new(),
        };
        let fitted = match doc.cell_px {
            None => Fitted::Design(fit),
            Some(cell_px) => {
                if p != FEATURE_COUNT {
                    return Err(bad("a view model needs every registered feature"));
                }
                let light = match doc.light.flatten() {
                    None => None,
                    Some((kind, v)) => {
                        let v = Vec3::from_array(v.map(|x| x as f32));
                        match kind.as_str() {
                            "position" => Some(StrongestLight::Position(v)),
                            "direction" => Some(StrongestLight::Direction(v)),
                            _ => return Err(bad("light kind")),
                        }
                    }
                };
                let (Some(min), Some(max)) = (doc.feature_min, doc.feature_max) else {
                    return Err(bad("no feature ranges"));
                };
                if min.len() != p || max.len() != p {
                    return Err(bad("feature ranges"));
                }
                let views = doc
                    .views
                    .ok_or_else(|| bad("no \"views\""))?
                    .into_iter()
                    .map(|v| ViewFit {
                        name: v.name,
                        cells: v.cells,
                        empty_cells: v.empty_cells,
                        masked_pixels: v.masked_pixels,
                        r2: v.r2,
                    })
                    .collect();
                Fitted::Views(CellModel {
                    ranges: MinMax { min, max },
                    fit,
                    cell_px,
                    light,
                    views,
                    label_max: doc.label_max.ok_or_else(|| bad("no \"label_max\""))?,
                })
            }
        };
        Ok(Self {
            names: doc.feature_names,
            fitted,
            dropped: doc.dropped,
        })
    }
}

fn bad(what: &str) -> VplaceError {
    VplaceError::Invalid {
        what: format!("not a {FORMAT} version {VERSION} document"),
        reason: what.to_owned(),
    }
}

/// The JSON document, field for field (the view-model fields absent for a design fit).
#[derive(Serialize, Deserialize)]
struct Document {
    format: String,
    version: u32,
    feature_names: Vec<String>,
    n: usize,
    intercept: f64,
    coefficients: Vec<f64>,
    weights: Vec<f64>,
    kept: Vec<usize>,
    dropped: Vec<(String, String)>,
    r2: f64,
    adjusted_r2: Option<f64>,
    cv_r2: Option<f64>,
    folds: usize,
    condition_number: Option<f64>,
    rank: usize,
    ridge_lambda: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cell_px: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    feature_min: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    feature_max: Option<Vec<f64>>,
    /// Absent for a design fit; null for a view model without a light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    light: Option<Option<(String, [f64; 3])>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    label_max: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    views: Option<Vec<ViewDoc>>,
}

#[derive(Serialize, Deserialize)]
struct ViewDoc {
    name: String,
    cells: usize,
    empty_cells: usize,
    masked_pixels: usize,
    r2: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::features::{extract_features, fit_cells};
    use crate::fit::regression::FitParams;
    use crate::test_util::Passes;

    #[test]
    fn a_saved_model_reads_back_the_same() {
        let p = Passes::room(64, 48);
        let cells = extract_features(&p.input(), 8).unwrap();
        let m = fit_cells(&[cells], &["room"], None, true, &FitParams::default()).unwrap();
        let names: Vec<String> = crate::fit::features::FEATURES
            .iter()
            .map(|f| f.name.to_owned())
            .collect();
        let model = Model::new(names, Fitted::Views(m));
        let back = Model::from_json(&model.to_json()).unwrap();
        assert_eq!(back.to_json(), model.to_json());
        assert_eq!(back.cells().unwrap().ranges, model.cells().unwrap().ranges);
        assert!(Model::from_json("{\"format\": \"other\"}").is_err());
        assert!(Model::from_json("not json").is_err());
    }
}
