//! Per-cell features and the regression label (DESIGN: Features and label; paper 1, steps 1-4).
//!
//! The image is split into square cells of `cell_px` pixels (the last row and column of cells
//! may be smaller). Over the *usable* pixels of a cell (covered by geometry, every pass finite)
//! each per-pixel feature of [`FEATURES`] is averaged; the cell-level features (coverage, normal
//! and depth variance) are computed from the same pixels. The label of a cell is
//! `dL = mean |L(I)|` over its usable pixels, `I` the view's indirect image (the light the VPLs
//! must reproduce) and `L` the Rec. 709 luminance ([`crate::color::luminance`]); with
//! `I = G - D` this is the paper's `mean |L(G) - L(D)|`.
//!
//! Several views are fitted as one model ([`fit_views`]): the cells of every view form one
//! design matrix, normalized with one Min-Max range and fitted once; R^2 is also reported per
//! view.
//!
//! Decisions recorded here:
//! - Cells without a usable pixel are excluded and counted ([`CellFeatures::empty_cells`]).
//! - A covered pixel holding NaN or inf in any pass the features read is *masked*: treated as
//!   uncovered and counted ([`CellFeatures::masked_pixels`]). A firefly in a render should not
//!   abort a fit; the count is reported so that it cannot go unnoticed. If nothing usable is
//!   left, extraction fails with [`VplaceError::Empty`].
//! - Values are raw per-cell means; Min-Max normalization over cells is [`MinMax`], kept with a
//!   fitted model so that another view is normalized with the same ranges.

use glam::Vec3;
use rayon::prelude::*;

use crate::color::luminance;
use crate::color::LUMINANCE;
use crate::error::{Result, VplaceError};
use crate::fit::regression::{self, DropReason, Fit, FitParams};
use crate::scene::{LightKind, Scene};
use crate::view::{check_len, GBuffer, View};

/// Where a feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// Listed by the paper (section 1 of the papers summary).
    Paper,
    /// Added by vplace.
    Ours,
}

/// One entry of the feature registry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FeatureDef {
    /// Stable name, used in tables and saved models (`snake_case`).
    pub name: &'static str,
    /// What the per-cell value is, in one line.
    pub doc: &'static str,
    /// Paper or ours.
    pub origin: Origin,
    /// A property of the surface, the same from every view (world normal, albedo, position,
    /// light); false for what depends on the view (depth, how the cell's pixels spread).
    pub surface: bool,
}

/// Number of registered features.
pub const FEATURE_COUNT: usize = 14;

/// Column of the light-cosine feature (unavailable without a light).
pub const LIGHT_COSINE: usize = 8;
/// Column of the reflectance feature (unavailable without a specular colour pass).
pub const REFLECTANCE: usize = 9;

/// The feature registry, in column order of [`CellFeatures::values`].
pub const FEATURES: [FeatureDef; FEATURE_COUNT] = [
    FeatureDef {
        name: "normal_x",
        doc: "mean world normal, x",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "normal_y",
        doc: "mean world normal, y",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "normal_z",
        doc: "mean world normal, z (up)",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "albedo_luminance",
        doc: "mean luminance of the diffuse albedo (DiffCol)",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "depth",
        doc: "mean planar camera depth, metres",
        origin: Origin::Paper,
        surface: false,
    },
    FeatureDef {
        name: "position_x",
        doc: "mean world position, x",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "position_y",
        doc: "mean world position, y",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "position_z",
        doc: "mean world position, z",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "light_cosine",
        doc: "mean max(0, n . l), l the unit direction to the strongest light",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "reflectance",
        doc: "mean luminance of the albedo + specular colour (DiffCol + GlossCol, the glossy \
              colour twice where the albedo adds the glossy layer vplace models)",
        origin: Origin::Paper,
        surface: true,
    },
    FeatureDef {
        name: "direct_luminance",
        doc: "mean luminance of the direct image D",
        origin: Origin::Ours,
        surface: true,
    },
    FeatureDef {
        name: "coverage",
        doc: "fraction of the cell's pixels that see geometry",
        origin: Origin::Ours,
        surface: false,
    },
    FeatureDef {
        name: "normal_variance",
        doc: "total variance of the normals, E[n.n] - |E[n]|^2",
        origin: Origin::Ours,
        surface: false,
    },
    FeatureDef {
        name: "depth_variance",
        doc: "variance of the planar depth, m^2",
        origin: Origin::Ours,
        surface: false,
    },
];

/// The strongest light of the view, for [`LIGHT_COSINE`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StrongestLight {
    /// A light at a world position (point, spot, area): `l = normalize(position - p)`.
    Position(Vec3),
    /// A sun travelling along this world direction: `l = -normalize(direction)`.
    Direction(Vec3),
}

/// The captured passes of one view. Images are flat `H x W x 3` (`depth`, `covered`: `H x W`),
/// row 0 at the top; see DESIGN, Capture.
#[derive(Debug, Clone, Copy)]
pub struct FeatureInput<'a> {
    /// Position, normal, albedo and coverage (the normal need not be unit length).
    pub gbuffer: GBuffer<'a>,
    /// Planar camera depth (Cycles Z) per pixel; background values are ignored via `covered`.
    pub depth: &'a [f32],
    /// The direct image `D`.
    pub direct: &'a [f32],
    /// The indirect image `I` the label is taken from; `None` for a view that is only
    /// predicted (no label).
    pub indirect: Option<&'a [f32]>,
    /// Specular colour (Cycles GlossCol); `None` makes [`REFLECTANCE`] unavailable.
    pub specular: Option<&'a [f32]>,
    /// The strongest light; `None` makes [`LIGHT_COSINE`] unavailable.
    pub light: Option<StrongestLight>,
}

/// Per-cell features of one view. Invariant: `values.len() == cells.len() * FEATURE_COUNT`,
/// `cells` ascending and every listed cell has at least one usable pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct CellFeatures {
    /// Cell size, pixels.
    pub cell_px: usize,
    /// Cells per image row: `ceil(width / cell_px)`.
    pub cells_x: usize,
    /// Cells per image column: `ceil(height / cell_px)`.
    pub cells_y: usize,
    /// Flat grid index (`row * cells_x + col`, row 0 at the top) of every non-empty cell.
    pub cells: Vec<usize>,
    /// Raw per-cell values, `cells.len() x FEATURE_COUNT`, row-major, columns as [`FEATURES`].
    pub values: Vec<f64>,
    /// The label `dL` per listed cell, when the indirect image was given.
    pub label: Option<Vec<f64>>,
    /// Usable pixels per listed cell.
    pub pixels: Vec<u32>,
    /// Cells of the grid without a usable pixel (excluded).
    pub empty_cells: usize,
    /// Covered pixels dropped because a pass held NaN or inf there.
    pub masked_pixels: usize,
    /// Per feature: false when its input was not given (its column is then all zeros).
    pub available: [bool; FEATURE_COUNT],
}

/// Running sums of one cell.
#[derive(Clone, Copy, Default)]
struct Acc {
    n: u32,
    total: u32,
    masked: u32,
    sum: [f64; 11],
    nn: f64,
    depth_shift: f32,
    dsum: f64,
    dsq: f64,
    label: f64,
}

#[inline]
fn lum(v: &[f32]) -> f32 {
    luminance(Vec3::from_slice(v))
}

#[inline]
fn finite3(v: &[f32]) -> bool {
    v[0].is_finite() && v[1].is_finite() && v[2].is_finite()
}

impl FeatureInput<'_> {
    /// Checks every array's length and the light. Non-finite values are not errors here: the
    /// extraction masks such pixels and counts them.
    pub fn validate(&self) -> Result<()> {
        self.gbuffer.check_shape()?;
        let (w, h) = (self.gbuffer.width, self.gbuffer.height);
        check_len("direct", self.direct.len(), w, h, 3)?;
        if let Some(ind) = self.indirect {
            check_len("indirect", ind.len(), w, h, 3)?;
        }
        if let Some(s) = self.specular {
            check_len("specular", s.len(), w, h, 3)?;
        }
        check_len("depth", self.depth.len(), w, h, 1)?;
        self.check_light()
    }

    /// Checks the light: a finite position, or a finite non-zero direction.
    fn check_light(&self) -> Result<()> {
        match self.light {
            Some(StrongestLight::Position(p)) if !p.is_finite() => Err(VplaceError::NonFinite {
                what: "light position".into(),
                index: 0,
            }),
            Some(StrongestLight::Direction(d)) if !d.is_finite() || d.length_squared() == 0.0 => {
                Err(VplaceError::Invalid {
                    what: "light direction".into(),
                    reason: "must be finite and non-zero".into(),
                })
            }
            _ => Ok(()),
        }
    }
}

/// Extracts the per-cell features (and the label when `gi` is given) of one view.
///
/// Parallel over rows of cells. Errors: bad lengths, `cell_px == 0`, a bad light, or no usable
/// pixel at all.
pub fn extract_features(input: &FeatureInput<'_>, cell_px: usize) -> Result<CellFeatures> {
    input.validate()?;
    extract_checked(input, cell_px)
}

/// [`extract_features`] of `view` with `light`: the view's arrays were checked when it was made
/// ([`View::new`]), so only the light and `cell_px` are.
pub fn extract_view_features(
    view: &View,
    light: Option<StrongestLight>,
    cell_px: usize,
) -> Result<CellFeatures> {
    let input = FeatureInput::of(view, light);
    input.check_light()?;
    extract_checked(&input, cell_px)
}

/// The extraction of an input whose arrays have their sizes.
fn extract_checked(input: &FeatureInput<'_>, cell_px: usize) -> Result<CellFeatures> {
    if cell_px == 0 {
        return Err(VplaceError::OutOfRange {
            what: "cell_px".into(),
            value: "0".into(),
            expected: "at least 1".into(),
        });
    }
    let (w, h) = (input.gbuffer.width, input.gbuffer.height);
    let cells_x = w.div_ceil(cell_px);
    let cells_y = h.div_ceil(cell_px);
    let light = input.light.map(|l| match l {
        StrongestLight::Position(p) => StrongestLight::Position(p),
        StrongestLight::Direction(d) => StrongestLight::Direction(-d.normalize()),
    });

    let rows: Vec<Vec<Acc>> = (0..cells_y)
        .into_par_iter()
        .map(|cy| accumulate_row(input, light, cell_px, cells_x, cy))
        .collect();

    let mut out = CellFeatures {
        cell_px,
        cells_x,
        cells_y,
        cells: Vec::new(),
        values: Vec::new(),
        label: input.indirect.map(|_| Vec::new()),
        pixels: Vec::new(),
        empty_cells: 0,
        masked_pixels: 0,
        available: [true; FEATURE_COUNT],
    };
    out.available[LIGHT_COSINE] = input.light.is_some();
    out.available[REFLECTANCE] = input.specular.is_some();
    for (cy, row) in rows.iter().enumerate() {
        for (cx, a) in row.iter().enumerate() {
            out.masked_pixels += a.masked as usize;
            if a.n == 0 {
                out.empty_cells += 1;
                continue;
            }
            let n = f64::from(a.n);
            out.cells.push(cy * cells_x + cx);
            out.pixels.push(a.n);
            let mean: Vec<f64> = a.sum.iter().map(|s| s / n).collect();
            out.values.extend_from_slice(&mean[..10]);
            out.values.push(mean[10]);
            out.values.push(n / f64::from(a.total));
            let mean_n2 = mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2];
            out.values.push((a.nn / n - mean_n2).max(0.0));
            let dm = a.dsum / n;
            out.values.push((a.dsq / n - dm * dm).max(0.0));
            if let Some(label) = out.label.as_mut() {
                label.push(a.label / n);
            }
        }
    }
    if out.cells.is_empty() {
        return Err(VplaceError::Empty {
            what: "usable pixels".into(),
            hint: format!(
                "no covered pixel with finite passes ({} covered pixels masked for NaN or inf)",
                out.masked_pixels
            ),
        });
    }
    Ok(out)
}

/// Pixels summed in `f32` before a flush into the cell's `f64` sums (bounds the rounding).
const SEGMENT: usize = 32;

/// One image row of every pass.
struct Row<'a> {
    pos: &'a [f32],
    nrm: &'a [f32],
    alb: &'a [f32],
    dir: &'a [f32],
    dep: &'a [f32],
    cov: &'a [bool],
    ind: Option<&'a [f32]>,
    spec: Option<&'a [f32]>,
}

fn accumulate_row(
    input: &FeatureInput<'_>,
    light: Option<StrongestLight>,
    cell_px: usize,
    cells_x: usize,
    cy: usize,
) -> Vec<Acc> {
    let w = input.gbuffer.width;
    let mut accs = vec![Acc::default(); cells_x];
    let y0 = cy * cell_px;
    let y1 = (y0 + cell_px).min(input.gbuffer.height);
    for y in y0..y1 {
        let (r1, r3) = (y * w..(y + 1) * w, 3 * y * w..3 * (y + 1) * w);
        let row = Row {
            pos: &input.gbuffer.position[r3.clone()],
            nrm: &input.gbuffer.normal[r3.clone()],
            alb: &input.gbuffer.albedo[r3.clone()],
            dir: &input.direct[r3.clone()],
            dep: &input.depth[r1.clone()],
            cov: &input.gbuffer.covered[r1],
            ind: input.indirect.map(|g| &g[r3.clone()]),
            spec: input.specular.map(|s| &s[r3.clone()]),
        };
        for (cx, acc) in accs.iter_mut().enumerate() {
            let x0 = cx * cell_px;
            let x1 = (x0 + cell_px).min(w);
            acc.total += (x1 - x0) as u32;
            let mut s = x0;
            while s < x1 {
                let e = (s + SEGMENT).min(x1);
                segment(acc, &row, s, e, light);
                s = e;
            }
        }
    }
    accs
}

/// Adds the usable pixels `s..e` of `row` to `acc`, summing in `f32` first.
#[inline]
fn segment(acc: &mut Acc, row: &Row<'_>, s: usize, e: usize, light: Option<StrongestLight>) {
    let mut sum = [0.0f32; 11];
    let (mut nn, mut dsum, mut dsq, mut label) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let mut n = 0u32;
    for x in s..e {
        if !row.cov[x] {
            continue;
        }
        let j = 3 * x;
        let p = &row.pos[j..j + 3];
        let nrm = &row.nrm[j..j + 3];
        let alb = &row.alb[j..j + 3];
        let d = &row.dir[j..j + 3];
        let depth = row.dep[x];
        let g = row.ind.map(|g| &g[j..j + 3]);
        let sp = row.spec.map(|s| &s[j..j + 3]);
        let ok = finite3(p)
            && finite3(nrm)
            && finite3(alb)
            && finite3(d)
            && depth.is_finite()
            && g.is_none_or(finite3)
            && sp.is_none_or(finite3);
        if !ok {
            acc.masked += 1;
            continue;
        }
        let alb_l = lum(alb);
        // The albedo is the receivers' reflectance: where vplace models a glossy layer it holds
        // GlossCol already, which this then counts twice. DiffCol + GlossCol there instead (the
        // view's `diffuse_color`) was measured at stop 81 and not kept: Sponza, 32 seeds, lost
        // on most views (Balcony -.010, made views -.010 and -.009; the rooms within .0004).
        let refl = sp.map_or(0.0, |s| alb_l + lum(s));
        let nv = Vec3::from_slice(nrm);
        let cosine = match light {
            None => 0.0,
            Some(StrongestLight::Position(lp)) => {
                let l = lp - Vec3::from_slice(p);
                let len2 = l.length_squared();
                if len2 > 0.0 {
                    (nv.dot(l) / len2.sqrt()).max(0.0)
                } else {
                    0.0
                }
            }
            Some(StrongestLight::Direction(l)) => nv.dot(l).max(0.0),
        };
        let direct_l = lum(d);
        if acc.n == 0 && n == 0 {
            acc.depth_shift = depth;
        }
        n += 1;
        let vals = [
            nrm[0], nrm[1], nrm[2], alb_l, depth, p[0], p[1], p[2], cosine, refl, direct_l,
        ];
        for (s, v) in sum.iter_mut().zip(vals) {
            *s += v;
        }
        nn += nv.length_squared();
        let dd = depth - acc.depth_shift;
        dsum += dd;
        dsq += dd * dd;
        if let Some(g) = g {
            label += lum(g).abs();
        }
    }
    if n == 0 {
        return;
    }
    acc.n += n;
    for (a, s) in acc.sum.iter_mut().zip(sum) {
        *a += f64::from(s);
    }
    acc.nn += f64::from(nn);
    acc.dsum += f64::from(dsum);
    acc.dsq += f64::from(dsq);
    acc.label += f64::from(label);
}

/// Min-Max normalization ranges over cells, one `[min, max]` per feature column.
#[derive(Debug, Clone, PartialEq)]
pub struct MinMax {
    /// Per-column minimum over the fitted cells.
    pub min: Vec<f64>,
    /// Per-column maximum over the fitted cells; `max >= min`.
    pub max: Vec<f64>,
}

impl MinMax {
    /// The ranges of the `p` columns of the row-major `values`. Errors on an empty table or
    /// non-finite values.
    pub fn fit(values: &[f64], p: usize) -> Result<Self> {
        if p == 0 || values.is_empty() || values.len() % p != 0 {
            return Err(VplaceError::Shape {
                what: "feature values".into(),
                expected: format!("a non-empty multiple of {p} values"),
                got: format!("{} values", values.len()),
            });
        }
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(VplaceError::NonFinite {
                what: "feature values".into(),
                index,
            });
        }
        let mut min = vec![f64::INFINITY; p];
        let mut max = vec![f64::NEG_INFINITY; p];
        for row in values.chunks_exact(p) {
            for (j, &v) in row.iter().enumerate() {
                min[j] = min[j].min(v);
                max[j] = max[j].max(v);
            }
        }
        Ok(Self { min, max })
    }

    /// `(v - min) / (max - min)` per column; a column whose range is zero maps to 0. Values of
    /// another view may fall outside `[0, 1]`.
    #[must_use]
    pub fn apply(&self, values: &[f64]) -> Vec<f64> {
        let p = self.min.len();
        values
            .chunks_exact(p)
            .flat_map(|row| {
                row.iter().enumerate().map(|(j, &v)| {
                    let range = self.max[j] - self.min[j];
                    if range > 0.0 {
                        (v - self.min[j]) / range
                    } else {
                        0.0
                    }
                })
            })
            .collect()
    }
}

impl<'a> FeatureInput<'a> {
    /// The passes of `view` with `light`; the label comes from the view's indirect image.
    #[must_use]
    pub fn of(view: &'a View, light: Option<StrongestLight>) -> Self {
        Self {
            gbuffer: view.gbuffer(),
            depth: &view.depth,
            direct: &view.direct,
            indirect: view.indirect.as_deref(),
            specular: view.specular.as_deref(),
            light,
        }
    }
}

/// The strongest light of `scene` seen from the mean covered position of `views`: the light
/// with the largest luminance of irradiance there, `P / (4 pi r^2)` for a point or spot,
/// `P / (pi r^2)` for an area light, `P` (W/m^2) for a sun, half the light of a world image
/// with a dominant direction (a uniform world has none), `P / (2 pi r^2)` from the power-weighted
/// centroid of the emissive triangles. `None` without such a light.
#[must_use]
pub fn strongest_light(scene: &Scene, views: &[&View]) -> Option<StrongestLight> {
    let (mut sum, mut n) = ([0.0f64; 3], 0u64);
    for v in views {
        for (p, _) in v.covered.iter().enumerate().filter(|(_, &c)| c) {
            for (s, &x) in sum.iter_mut().zip(&v.position[3 * p..3 * p + 3]) {
                *s += f64::from(x);
            }
            n += 1;
        }
    }
    let centre = if n > 0 {
        sum.map(|s| s / n as f64)
    } else {
        [0.0; 3]
    };
    let mut best: Option<(f64, StrongestLight)> = None;
    let at = |position: Vec3, power: f64, k: f64| {
        let d = [0, 1, 2].map(|i| f64::from(position[i]) - centre[i]);
        let r2 = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).max(1e-12);
        (power / (k * r2), StrongestLight::Position(position))
    };
    let mut candidates = Vec::new();
    for light in &scene.lights {
        let power = f64::from(light.power.dot(LUMINANCE));
        candidates.push(match &light.kind {
            LightKind::Sun { .. } => (power, StrongestLight::Direction(light.direction)),
            LightKind::World { map } => {
                // An image with a dominant direction (a sun in the sky): light travelling away
                // from it, half of the map's light; a uniform world has no direction.
                let Some((m, dir)) = map
                    .as_ref()
                    .and_then(|m| m.dominant_direction().map(|d| (m, d)))
                else {
                    continue;
                };
                let integral = f64::from((light.power * m.integral()).dot(LUMINANCE));
                (0.5 * integral, StrongestLight::Direction(-dir))
            }
            LightKind::Area { .. } => at(light.position, power, std::f64::consts::PI),
            LightKind::Point { .. } | LightKind::Spot { .. } => {
                at(light.position, power, 4.0 * std::f64::consts::PI)
            }
        });
    }
    let mesh = scene.emissive();
    if !mesh.is_empty() {
        let power = f64::from(mesh.power().dot(LUMINANCE));
        candidates.push(at(mesh.centroid(), power, 2.0 * std::f64::consts::PI));
    }
    for (irradiance, found) in candidates {
        if best.is_none_or(|(b, _)| irradiance > b) {
            best = Some((irradiance, found));
        }
    }
    best.map(|(_, l)| l)
}

/// How well the model explains one of the views it was fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewFit {
    /// The view's name.
    pub name: String,
    /// Cells of the view in the design matrix.
    pub cells: usize,
    /// Cells of the view's grid without a usable pixel.
    pub empty_cells: usize,
    /// Covered pixels masked for non-finite passes (when the view was made, or by the
    /// feature extraction).
    pub masked_pixels: usize,
    /// `1 - SS_res / SS_tot` over the view's cells (about its own mean); `None` when its label
    /// is constant.
    pub r2: Option<f64>,
}

/// A regression model of the per-cell label, fitted on the cells of one or more views, with
/// what another view needs to be predicted the same way: the Min-Max ranges, the cell size and
/// the light of the light-cosine feature.
#[derive(Debug, Clone, PartialEq)]
pub struct CellModel {
    /// Min-Max ranges of the raw features over the fitted cells.
    pub ranges: MinMax,
    /// The fit on the normalized features (columns as [`FEATURES`]).
    pub fit: Fit,
    /// Cell size, pixels.
    pub cell_px: usize,
    /// The light of [`LIGHT_COSINE`], if any.
    pub light: Option<StrongestLight>,
    /// The fitted views, in order; their cells are consecutive rows of the fit.
    pub views: Vec<ViewFit>,
    /// The largest label of the fitted cells: predictions are held to `[0, label_max]`.
    pub label_max: f64,
}

/// Why the features of the view are left out of a surface-only model.
pub const VIEW_DEPENDENT: &str =
    "depends on the view, not on the surface: the lights must hold from every view";

/// Normalizes the features of `cells` (the cells of the views named `names`, in order) and fits
/// their label (see [`crate::fit::regression`]); `light` is what the light-cosine feature was computed
/// with. Features whose input was not given are reported as [`DropReason::Unavailable`]; with
/// `surface_only` the features that are not properties of the surface ([`FeatureDef::surface`])
/// are left out, reported as [`DropReason::Excluded`].
pub fn fit_cells(
    cells: &[CellFeatures],
    names: &[&str],
    light: Option<StrongestLight>,
    surface_only: bool,
    params: &FitParams,
) -> Result<CellModel> {
    let mut values = Vec::new();
    let mut label = Vec::new();
    let mut available = [true; FEATURE_COUNT];
    for (c, name) in cells.iter().zip(names) {
        let l = c.label.as_ref().ok_or_else(|| VplaceError::Invalid {
            what: format!("view {name:?}"),
            reason: "it has no indirect image; fitting needs one (prediction does not)".into(),
        })?;
        values.extend_from_slice(&c.values);
        label.extend_from_slice(l);
        for (a, b) in available.iter_mut().zip(c.available) {
            *a &= b;
        }
    }
    let ranges = MinMax::fit(&values, FEATURE_COUNT)?;
    let mut x = ranges.apply(&values);
    let excluded: Vec<usize> = (0..FEATURE_COUNT)
        .filter(|&j| surface_only && !FEATURES[j].surface)
        .collect();
    // An excluded column is made constant, so that the regression drops it; its reason is
    // then set below.
    for row in x.chunks_exact_mut(FEATURE_COUNT) {
        for &j in &excluded {
            row[j] = 0.0;
        }
    }
    let mut fit = regression::fit(&x, &label, FEATURE_COUNT, params)?;
    for (j, reason) in &mut fit.dropped {
        if !available[*j] {
            *reason = DropReason::Unavailable(if *j == LIGHT_COSINE {
                "no strongest light given"
            } else {
                "no specular colour pass given"
            });
        } else if excluded.contains(j) {
            *reason = DropReason::Excluded(VIEW_DEPENDENT);
        }
    }
    let mut views = Vec::with_capacity(cells.len());
    let mut row = 0;
    for (c, name) in cells.iter().zip(names) {
        let n = c.cells.len();
        let y = &label[row..row + n];
        let f = &fit.fitted[row..row + n];
        let mean = y.iter().sum::<f64>() / n as f64;
        let ss_tot: f64 = y.iter().map(|v| (v - mean) * (v - mean)).sum();
        let ss_res: f64 = y.iter().zip(f).map(|(a, b)| (a - b) * (a - b)).sum();
        views.push(ViewFit {
            name: (*name).to_owned(),
            cells: n,
            empty_cells: c.empty_cells,
            masked_pixels: c.masked_pixels,
            r2: (ss_tot > 0.0).then(|| 1.0 - ss_res / ss_tot),
        });
        row += n;
    }
    Ok(CellModel {
        ranges,
        fit,
        cell_px: cells[0].cell_px,
        light,
        views,
        label_max: label.iter().copied().fold(0.0, f64::max),
    })
}

/// Settings of a fit on views: the cells, the choice of features and the regression's own.
/// `Copy`, with named presets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewFitParams {
    /// Cell size in pixels (`>= 1`).
    pub cell_px: usize,
    /// Fit only the features of the surface (the same from every view), so that the model
    /// holds from views it was not fitted on.
    pub surface_only: bool,
    /// The regression (selection, tolerances, ridge, folds).
    pub regression: FitParams,
}

impl ViewFitParams {
    /// 16-pixel cells, surface features only, [`FitParams::DEFAULT`].
    pub const DEFAULT: Self = Self {
        cell_px: 16,
        surface_only: true,
        regression: FitParams::DEFAULT,
    };
    /// Every feature, plain OLS ([`FitParams::PLAIN_OLS`]): what `numpy.linalg.lstsq` fits.
    pub const PLAIN_OLS: Self = Self {
        cell_px: 16,
        surface_only: false,
        regression: FitParams::PLAIN_OLS,
    };
}

impl Default for ViewFitParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Fits one model on the cells of every view of `views` (each needs its indirect image), with
/// `light` for the light-cosine feature (see [`strongest_light`]) and, with `surface_only`,
/// only the features of the surface (see [`fit_cells`]).
///
/// Errors: no views, a view without an indirect image, bad `cell_px`, no usable pixel in a
/// view, or the regression's own errors.
pub fn fit_views(
    views: &[&View],
    light: Option<StrongestLight>,
    cell_px: usize,
    surface_only: bool,
    params: &FitParams,
) -> Result<CellModel> {
    if views.is_empty() {
        return Err(VplaceError::Empty {
            what: "views".into(),
            hint: "give at least one captured view to fit on".into(),
        });
    }
    let cells = views
        .iter()
        .map(|v| extract_view_features(v, light, cell_px))
        .collect::<Result<Vec<_>>>()?;
    let names: Vec<&str> = views.iter().map(|v| v.name.as_str()).collect();
    let mut model = fit_cells(&cells, &names, light, surface_only, params)?;
    for (f, v) in model.views.iter_mut().zip(views) {
        f.masked_pixels += v.masked_pixels;
    }
    Ok(model)
}

impl CellModel {
    /// The predicted label of every cell of the grid of `cells` (`cells_y x cells_x`, row-major);
    /// cells without geometry get 0 (they hold no pixel to light).
    ///
    /// The model is trusted only where it was fitted: a cell's normalized features are held to
    /// the fitted range `[0, 1]` (a feature of another view beyond the range counts as its edge),
    /// and the prediction to `[0, label_max]`. A linear model extrapolated far outside its data
    /// (another view's depths or positions) can predict anything; held at the edge it predicts
    /// what the nearest fitted cells had.
    #[must_use]
    pub fn predict(&self, cells: &CellFeatures) -> Vec<f64> {
        let mut x = self.ranges.apply(&cells.values);
        x.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        let mut out = vec![0.0; cells.cells_x * cells.cells_y];
        for (row, &c) in x.chunks_exact(FEATURE_COUNT).zip(&cells.cells) {
            out[c] = self.fit.predict_row(row).clamp(0.0, self.label_max);
        }
        out
    }

    /// The predicted label of every cell of `view`, with the model's cell size and light.
    pub fn predict_view(&self, view: &View) -> Result<Vec<f64>> {
        let cells = extract_view_features(view, self.light, self.cell_px)?;
        Ok(self.predict(&cells))
    }

    /// Per kept feature (column, fraction): the fraction of `cells` whose value lies outside
    /// the fitted range, where [`CellModel::predict`] holds it to the edge.
    #[must_use]
    pub fn out_of_range(&self, cells: &CellFeatures) -> Vec<(usize, f64)> {
        // Min-Max of f32 passes: a cell within rounding of the edge is in range.
        const SLACK: f64 = 1e-6;
        let x = self.ranges.apply(&cells.values);
        let n = cells.cells.len().max(1) as f64;
        self.fit
            .kept
            .iter()
            .map(|&j| {
                let outside = x
                    .chunks_exact(FEATURE_COUNT)
                    .filter(|row| !(-SLACK..=1.0 + SLACK).contains(&row[j]))
                    .count();
                (j, outside as f64 / n)
            })
            .collect()
    }

    /// [`CellModel::out_of_range`] for the cells of `view`.
    pub fn out_of_range_view(&self, view: &View) -> Result<Vec<(usize, f64)>> {
        let cells = extract_view_features(view, self.light, self.cell_px)?;
        Ok(self.out_of_range(&cells))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::Passes;

    fn bufs(w: usize, h: usize) -> Passes {
        Passes::grid(w, h)
    }

    fn input(b: &Passes) -> FeatureInput<'_> {
        b.input()
    }

    #[test]
    fn registry_names_are_unique_and_documented() {
        for (i, f) in FEATURES.iter().enumerate() {
            assert!(!f.doc.is_empty());
            assert!(FEATURES[i + 1..].iter().all(|g| g.name != f.name));
        }
        assert_eq!(FEATURES[LIGHT_COSINE].name, "light_cosine");
        assert_eq!(FEATURES[REFLECTANCE].name, "reflectance");
    }

    #[test]
    fn cell_means_label_and_empty_cells() {
        let b = bufs(8, 6);
        let f = extract_features(&input(&b), 2).unwrap();
        assert_eq!((f.cells_x, f.cells_y), (4, 3));
        // Pixels with x >= 4 and y >= 3 are background: cells (row 2, cols 2 and 3) are empty.
        assert_eq!(f.empty_cells, 2);
        assert_eq!(f.cells.len(), 10);
        let p = FEATURE_COUNT;
        // Cell 0 (x 0..2, y 0..2): position_x mean 0.5, label mean 0.01 * 0.5.
        assert!((f.values[5] - 0.5).abs() < 1e-12);
        assert!((f.values[4] - 2.5).abs() < 1e-12);
        assert!((f.values[11] - 1.0).abs() < 1e-12);
        assert!((f.values[13] - 0.25).abs() < 1e-9);
        assert!(f.values[12].abs() < 1e-12);
        let label = f.label.as_ref().unwrap();
        assert!((label[0] - 0.005).abs() < 1e-6);
        // Cell at row 1, col 2 (x 4..6, y 2..4): only y = 2 covered -> coverage 0.5.
        let k = f.cells.iter().position(|&c| c == 4 + 2).unwrap();
        assert!((f.values[k * p + 11] - 0.5).abs() < 1e-12);
        assert_eq!(f.pixels[k], 2);
        assert!(f.available[LIGHT_COSINE] && !f.available[REFLECTANCE]);
    }

    #[test]
    fn non_finite_pixels_are_masked_and_counted() {
        let mut b = bufs(4, 4);
        b.indirect[0] = f32::NAN;
        b.depth[1] = f32::INFINITY;
        b.gbuffer.position[3 * 6] = f32::NAN;
        b.gbuffer.position[3 * 15] = f32::NAN; // uncovered: not counted
        let f = extract_features(&input(&b), 2).unwrap();
        assert_eq!(f.masked_pixels, 3);
        assert!(f.values.iter().all(|v| v.is_finite()));
        assert!(f.label.unwrap().iter().all(|v| v.is_finite()));
    }

    #[test]
    fn one_pixel_cells_and_bad_input() {
        let b = bufs(3, 2);
        let f = extract_features(&input(&b), 1).unwrap();
        assert_eq!(f.cells.len() + f.empty_cells, 6);
        assert!(f.pixels.iter().all(|&n| n == 1));
        assert!(extract_features(&input(&b), 0).is_err());
        let mut bad = input(&b);
        bad.depth = &b.depth[1..];
        assert!(matches!(
            extract_features(&bad, 1),
            Err(VplaceError::Shape { .. })
        ));
        let mut none = bufs(2, 2);
        none.gbuffer.covered.fill(false);
        assert!(matches!(
            extract_features(&input(&none), 1),
            Err(VplaceError::Empty { .. })
        ));
    }

    #[test]
    fn light_cosine_point_and_sun() {
        let b = bufs(2, 2);
        let mut inp = input(&b);
        inp.light = Some(StrongestLight::Direction(Vec3::new(0.0, 0.0, -2.0)));
        let f = extract_features(&inp, 1).unwrap();
        assert!((f.values[LIGHT_COSINE] - 1.0).abs() < 1e-6);
        inp.light = Some(StrongestLight::Position(Vec3::new(0.0, 0.0, -1.0)));
        let f = extract_features(&inp, 1).unwrap();
        assert_eq!(f.values[LIGHT_COSINE], 0.0);
    }

    #[test]
    fn surface_only_leaves_out_the_features_of_the_view() {
        let b = bufs(16, 8);
        let cells = extract_features(&input(&b), 2).unwrap();
        let params = FitParams {
            select: false,
            ..FitParams::DEFAULT
        };
        let light = Some(b.light);
        let all = fit_cells(std::slice::from_ref(&cells), &["v"], light, false, &params).unwrap();
        let surface = fit_cells(&[cells], &["v"], light, true, &params).unwrap();
        for (j, f) in FEATURES.iter().enumerate() {
            let excluded = surface
                .fit
                .dropped
                .iter()
                .any(|(k, r)| *k == j && *r == DropReason::Excluded(VIEW_DEPENDENT));
            assert_eq!(excluded, !f.surface, "{}", f.name);
            assert!(!surface.fit.kept.contains(&j) || f.surface);
        }
        assert!(all
            .fit
            .dropped
            .iter()
            .all(|(_, r)| !matches!(r, DropReason::Excluded(_))));
        // The label (0.01 x) is linear in position_x, a feature of the surface: both fit it.
        assert!(surface.fit.r2 > 0.999 && all.fit.r2 > 0.999);
    }

    #[test]
    fn predictions_hold_to_the_fitted_range() {
        let b = bufs(16, 8);
        let cells = extract_features(&input(&b), 2).unwrap();
        let model = fit_cells(
            std::slice::from_ref(&cells),
            &["v"],
            Some(b.light),
            true,
            &FitParams::DEFAULT,
        )
        .unwrap();
        let x = FEATURES
            .iter()
            .position(|f| f.name == "position_x")
            .unwrap();
        assert!(model.fit.kept.contains(&x));
        let label = cells.label.clone().unwrap();
        let top = label.iter().copied().fold(0.0, f64::max);
        assert_eq!(model.label_max, top);
        // A view far beyond the fitted positions (as another camera may see): the prediction is
        // what the cells at the edge of the range get, never the line extended 100 m on.
        let mut far = cells.clone();
        let mut edge = cells.clone();
        for (f, e) in far
            .values
            .chunks_exact_mut(FEATURE_COUNT)
            .zip(edge.values.chunks_exact_mut(FEATURE_COUNT))
        {
            f[x] += 100.0;
            e[x] = model.ranges.max[x];
        }
        let p = model.predict(&far);
        assert_eq!(p, model.predict(&edge));
        assert!(p.iter().all(|&v| (0.0..=top).contains(&v)));
        let mut below = cells.clone();
        below
            .values
            .chunks_exact_mut(FEATURE_COUNT)
            .for_each(|r| r[x] -= 100.0);
        assert!(model.predict(&below).iter().all(|&v| v >= 0.0));
        let outside = model.out_of_range(&far);
        assert_eq!(outside.iter().find(|(j, _)| *j == x), Some(&(x, 1.0)));
        assert!(model.out_of_range(&cells).iter().all(|(_, f)| *f == 0.0));
    }

    #[test]
    fn min_max() {
        let mm = MinMax::fit(&[1.0, 5.0, 3.0, 5.0], 2).unwrap();
        assert_eq!(mm.apply(&[2.0, 5.0, 5.0, 5.0]), vec![0.5, 0.0, 2.0, 0.0]);
        assert!(MinMax::fit(&[], 2).is_err());
        assert!(MinMax::fit(&[f64::NAN, 1.0], 2).is_err());
    }
}
