//! Regression-guided VPL layout (DESIGN, Layout): candidate emitters, strata, allocation by
//! largest remainder, and flux-proportional draws inside each stratum.
//!
//! The layout reads one or more [`View`]s and lays out one world-space VPL set for all of them.
//! Candidate emitters are surface points that receive light:
//! - every covered pixel `p` of every view, reflecting `Phi_p = albedo_p * pi * E_p * A_p`,
//!   `A_p = r^2 * omega_p / |cos|` its world-space footprint (`r` the radial distance from the
//!   camera, `omega_p` the pixel's solid angle from the camera matrix, `cos` between the normal
//!   and the view ray, clamped at [`MIN_VIEW_COSINE`]) and `E_p / pi` the irradiance / pi the
//!   surface receives ([`emitter_irradiance`]: `DiffDir`, plus `DiffInd` or the fit's
//!   prediction with `multi_bounce`). A surface seen by several views is counted once: a
//!   pixel emitter of view `v` that an earlier view sees ([`View::sees`]) is dropped
//!   ([`Strata::shared_pixels`]);
//! - hits of light paths (Keller's [`light_path_vpls`], every bounce by default) that no view
//!   sees: they stand for the light reflected off screen.
//!
//! Strata are the image cells of every view (`cell_px` square, row-major, row 0 at the top; the
//! views' grids one after the other, [`Strata::grids`]) plus the off-screen strata (from index
//! [`Strata::offscreen`] on). Off-screen emitters differ wildly in how much of
//! their light reaches what the camera sees (in Sponza most of the sun's reflected flux leaves
//! the roofs toward the sky), so they are grouped by their *view efficiency* `eta_e`: the mean
//! unshadowed irradiance-times-albedo they give a sparse grid of the views' covered pixels per
//! unit flux ([`view_efficiency`]). Emitters with `eta_e = 0` form a dark stratum (the last);
//! the others [`OFFSCREEN_BINS`] strata of equal view contribution `lum(Phi_e) * eta_e`, by
//! increasing `eta_e`. Each
//! off-screen stratum gets the view weight `v_k = mean eta / mean eta of the on-screen
//! emitters` (flux-weighted means; cells have `v_k = 1`). Stratum `k` holds the flux `F_k`. The
//! budget `N` is split `n_k = N * lerp(u_k, m_k, alpha)` by largest remainder, with
//! `u_k = lum(F_k) / sum lum(F)` and `m_k` proportional to `lum(F_k) * max(0, predicted dL_k) *
//! v_k` (off-screen strata take the flux-weighted mean prediction of the cells). A dark stratum
//! with flux always keeps one VPL of its own, so its flux never joins another stratum's draw. Strata that hold flux but
//! receive no VPL are pooled into one group drawn jointly (so no flux is ever lost). Inside a
//! group, `n` emitters are drawn by luminance flux with systematic sampling; each VPL carries the
//! luminance `lum(F_group) / n` with its emitter's chromaticity, so the total reflected
//! luminance flux is the same for every allocation: the layout moves accuracy, not energy.
//!
//! The iteration that moves budget toward cells with a high residual is [`crate::layout::refine`].

pub mod refine;
pub mod refit;
pub mod request;
pub mod rsm;

use glam::{Mat4, Vec3};
use rayon::prelude::*;
use std::borrow::Cow;
use std::f32::consts::PI;

use crate::color::{luminance, luminance_f64};
use crate::error::{Result, VplaceError};
use crate::rng::Rng;
use crate::scene::Scene;
use crate::shade::shading::{Batch, VplSoa};
use crate::view::View;
use crate::vpl::{light_path_vpls, Profile, Vpl, MAX_BOUNCES};

/// Off-screen strata with a non-zero view efficiency (plus the dark one).
pub const OFFSCREEN_BINS: usize = 8;
/// About this many covered pixels sample the view for [`view_efficiency`].
pub const VIEW_SAMPLES: usize = 1024;

/// Smallest `|cos|` between a pixel's normal and its view ray used for its footprint: bounds
/// the `1 / cos` of grazing pixels (about 87 degrees).
pub const MIN_VIEW_COSINE: f32 = 0.05;

/// The smallest mean albedo luminance of a cell that the predicted indirect irradiance is
/// divided by ([`emitter_irradiance`]); darker cells get none.
pub const MIN_CELL_ALBEDO: f64 = 1e-3;

/// Settings of the layout. `Copy`, with named presets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayoutParams {
    /// VPL budget `N`, `>= 1`.
    pub budget: usize,
    /// Blend between the uniform (0) and the regression-guided (1) allocation, in `[0, 1]`.
    pub alpha: f32,
    /// Cell size in pixels (`>= 1`); must match the cells of the predicted `dL`.
    pub cell_px: usize,
    /// Light rays hitting geometry traced for the off-screen stratum (0: no off-screen stratum).
    pub light_rays: usize,
    /// Seed of the light rays and the draws.
    pub seed: u64,
    /// Surface hits per light path for the off-screen stratum (1: first bounce only; see
    /// [`light_path_vpls`]).
    pub bounces: usize,
    /// Pixel emitters reflect all the light their surface receives (`DiffDir` plus the captured
    /// `DiffInd` or the predicted indirect irradiance), not only the direct light.
    pub multi_bounce: bool,
}

impl LayoutParams {
    /// 256 VPLs, fully guided, 16-pixel cells, 4096 light rays of every bounce, multi-bounce
    /// pixel emitters.
    pub const DEFAULT: Self = Self {
        budget: 256,
        alpha: 1.0,
        cell_px: 16,
        light_rays: 4096,
        seed: 0,
        bounces: MAX_BOUNCES,
        multi_bounce: true,
    };
}

impl Default for LayoutParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A candidate emitter: a surface point and the flux it reflects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emitter {
    /// Position, offset off the surface like a [`Vpl`].
    pub position: Vec3,
    /// Unit normal, facing the side the light arrives from.
    pub normal: Vec3,
    /// Reflected flux, RGB watts; its luminance is `> 0`.
    pub flux: Vec3,
}

/// Where a view's pixel emitters got their indirect irradiance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IndirectSource {
    /// The view's captured `DiffInd`.
    Captured,
    /// The fit's per-cell prediction (a view without a GI render).
    Predicted,
    /// None: the emitters reflect direct light only.
    None,
}

/// The cell strata of one view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grid {
    /// Cells per row.
    pub cells_x: usize,
    /// Cells per column.
    pub cells_y: usize,
    /// Index of the view's first cell among the strata.
    pub start: usize,
    /// Where the view's emitters got their indirect irradiance.
    pub source: IndirectSource,
}

impl Grid {
    /// Number of cells.
    #[must_use]
    pub fn cells(&self) -> usize {
        self.cells_x * self.cells_y
    }
}

/// The candidate emitters of one or more views grouped in strata.
///
/// Invariants: `start.len() == strata() + 1`, non-decreasing, `start[strata()] ==
/// emitters.len()`; stratum `k` holds `emitters[start[k]..start[k + 1]]` and `flux[k]` is their
/// sum; the grids cover the strata `0..offscreen()` one after the other; the strata from
/// [`Strata::offscreen`] on are the off-screen ones (the last one dark);
/// `view_weight.len() == strata()`.
#[derive(Debug, Clone, PartialEq)]
pub struct Strata {
    /// Cell size, pixels.
    pub cell_px: usize,
    /// The cell grid of each view, in the order of the views.
    pub grids: Vec<Grid>,
    /// Every candidate, grouped by stratum.
    pub emitters: Vec<Emitter>,
    /// Start of each stratum in `emitters`, plus the end.
    pub start: Vec<usize>,
    /// `F_k`: the flux of each stratum, RGB watts.
    pub flux: Vec<Vec3>,
    /// Light-ray hits dropped because a view sees them (its pixels stand for them).
    pub light_hits_on_screen: usize,
    /// Pixel emitters dropped because an earlier view sees their surface (counted once).
    pub shared_pixels: usize,
    /// `v_k`: how efficiently stratum `k` lights the view relative to the on-screen emitters
    /// (1 for cells, 0 for the dark stratum).
    pub view_weight: Vec<f64>,
}

impl Strata {
    /// Number of strata (cells plus the off-screen one).
    #[must_use]
    pub fn strata(&self) -> usize {
        self.flux.len()
    }

    /// Index of the first off-screen stratum (= the number of cells of every view).
    #[must_use]
    pub fn offscreen(&self) -> usize {
        self.grids.iter().map(Grid::cells).sum()
    }

    /// Total flux of the off-screen strata.
    #[must_use]
    pub fn offscreen_flux(&self) -> Vec3 {
        self.flux[self.offscreen()..].iter().copied().sum()
    }

    /// Luminance of each `F_k`.
    #[must_use]
    pub fn luminance(&self) -> Vec<f64> {
        self.flux.iter().map(|&f| f64::from(luminance(f))).collect()
    }
}

#[inline]
fn vec3(arr: &[f32], p: usize) -> Vec3 {
    Vec3::new(arr[3 * p], arr[3 * p + 1], arr[3 * p + 2])
}

/// The unit view direction through the image point `(x, y)` (pixels, y down), as the line
/// through two unprojected depths (so the camera position and the depth range do not enter).
fn corner_direction(inv: &Mat4, x: f32, y: f32, w: usize, h: usize) -> Vec3 {
    let (nx, ny) = (x / w as f32 * 2.0 - 1.0, 1.0 - y / h as f32 * 2.0);
    let near = inv.project_point3(Vec3::new(nx, ny, -0.5));
    let far = inv.project_point3(Vec3::new(nx, ny, 0.5));
    (far - near).normalize_or_zero()
}

/// The solid angle of a pixel from the view directions of its top-left, top-right and
/// bottom-left corners.
fn solid_angle(d00: Vec3, d10: Vec3, d01: Vec3) -> f32 {
    (d10 - d00).cross(d01 - d00).length()
}

/// The irradiance / pi that the pixel emitters of `view` reflect, and where its indirect part
/// came from: `DiffDir` alone without `multi_bounce`; `DiffDir + max(0, DiffInd)` when the
/// view has its `diffuse_indirect` pass; otherwise, with `predicted` (the fit's per-cell `dL`,
/// `cells_y x cells_x`), `DiffDir` plus the grey irradiance `max(0, dL_k) / albedo_k` of each
/// cell (`albedo_k` the mean albedo luminance of its covered pixels; cells darker than
/// [`MIN_CELL_ALBEDO`] get none): on a view without a GI render the prediction stands in for
/// the light the capture did not measure.
///
/// Errors: a prediction of the wrong size.
pub fn emitter_irradiance<'a>(
    view: &'a View,
    predicted: Option<&[f64]>,
    cell_px: usize,
    multi_bounce: bool,
) -> Result<(Cow<'a, [f32]>, IndirectSource)> {
    let direct = &view.diffuse_direct;
    if !multi_bounce {
        return Ok((Cow::Borrowed(direct), IndirectSource::None));
    }
    if let Some(ind) = &view.diffuse_indirect {
        let sum = direct
            .iter()
            .zip(ind)
            .map(|(d, i)| d + i.max(0.0))
            .collect();
        return Ok((Cow::Owned(sum), IndirectSource::Captured));
    }
    let Some(pred) = predicted else {
        return Ok((Cow::Borrowed(direct), IndirectSource::None));
    };
    let (w, h) = (view.width, view.height);
    let (cx, cy) = (w.div_ceil(cell_px), h.div_ceil(cell_px));
    if pred.len() != cx * cy {
        return Err(VplaceError::Shape {
            what: format!("prediction of view {:?}", view.name),
            expected: format!("({cy}, {cx}) cells"),
            got: format!("{} values", pred.len()),
        });
    }
    let mut sum = vec![0.0f64; cx * cy];
    let mut count = vec![0u32; cx * cy];
    for (p, _) in view.covered.iter().enumerate().filter(|(_, &c)| c) {
        let a = &view.albedo[3 * p..3 * p + 3];
        let k = (p / w / cell_px) * cx + (p % w) / cell_px;
        sum[k] += luminance_f64([f64::from(a[0]), f64::from(a[1]), f64::from(a[2])]);
        count[k] += 1;
    }
    let cell: Vec<f32> = (0..cx * cy)
        .map(|k| {
            let mean = if count[k] > 0 {
                sum[k] / f64::from(count[k])
            } else {
                0.0
            };
            if mean > MIN_CELL_ALBEDO {
                (pred[k].max(0.0) / mean.max(MIN_CELL_ALBEDO)) as f32
            } else {
                0.0
            }
        })
        .collect();
    let out = direct
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let p = i / 3;
            d + cell[(p / w / cell_px) * cx + (p % w) / cell_px]
        })
        .collect();
    Ok((Cow::Owned(out), IndirectSource::Predicted))
}

/// The pixel emitters of `view` reflecting `irradiance` (irradiance / pi, `H x W x 3`), each with
/// its cell, in pixel order; `owned(x)` says whether the emitter at `x` belongs to this view (not
/// already held by an earlier one).
fn pixel_emitters(
    view: &View,
    irradiance: &[f32],
    cell_px: usize,
    offset: f32,
    owned: impl Fn(Vec3) -> bool + Sync,
) -> (Vec<(usize, Emitter)>, usize) {
    let (w, h, c) = (view.width, view.height, cell_px);
    let cells_x = w.div_ceil(c);
    let cam = view.camera.position;
    let inv = view.camera.world_to_clip.inverse();
    // Rows in parallel, in bands that share the view directions of their pixel corners; the
    // emitters are then appended in pixel order, as a plain row-major loop would.
    let band = 8;
    let found: Vec<(Vec<(usize, Emitter)>, usize)> = (0..h.div_ceil(band))
        .into_par_iter()
        .map(|b| {
            let (y0, y1) = (b * band, ((b + 1) * band).min(h));
            let corners: Vec<Vec<Vec3>> = (y0..=y1)
                .map(|y| {
                    (0..=w)
                        .map(|x| corner_direction(&inv, x as f32, y as f32, w, h))
                        .collect()
                })
                .collect();
            let mut out = Vec::new();
            let mut shared = 0;
            for y in y0..y1 {
                let (top, below) = (&corners[y - y0], &corners[y - y0 + 1]);
                for x in 0..w {
                    let p = y * w + x;
                    if !view.covered[p] {
                        continue;
                    }
                    let dd = vec3(irradiance, p);
                    let pos = vec3(&view.position, p);
                    let mut n = vec3(&view.normal, p).normalize_or_zero();
                    let to_cam = cam - pos;
                    let r = to_cam.length();
                    if n == Vec3::ZERO || r <= 0.0 {
                        continue;
                    }
                    let mut cos = n.dot(to_cam) / r;
                    if cos < 0.0 {
                        n = -n;
                        cos = -cos;
                    }
                    let omega = solid_angle(top[x], top[x + 1], below[x]);
                    let area = r * r * omega / cos.max(MIN_VIEW_COSINE);
                    let flux = vec3(&view.albedo, p) * (PI * dd.max(Vec3::ZERO)) * area;
                    let lum = luminance(flux);
                    if lum.is_nan() || lum <= 0.0 || !flux.is_finite() {
                        continue;
                    }
                    let emitter = Emitter {
                        position: pos + n * offset,
                        normal: n,
                        flux,
                    };
                    if !owned(emitter.position) {
                        shared += 1;
                        continue;
                    }
                    out.push(((y / c) * cells_x + x / c, emitter));
                }
            }
            (out, shared)
        })
        .collect();
    let shared = found.iter().map(|(_, s)| s).sum();
    (found.into_iter().flat_map(|(e, _)| e).collect(), shared)
}

/// Gathers the candidate emitters of `views` into strata (see the module docs). `predicted`,
/// when given, holds the fit's per-cell `dL` of each view (`cells_y x cells_x`, row-major); a
/// view without a `diffuse_indirect` pass then reflects it ([`emitter_irradiance`]).
///
/// Errors: no views, `cell_px == 0`, a prediction of the wrong size, or failing light rays
/// (see [`light_path_vpls`]). A scene without emitters gets empty off-screen strata (its pixels
/// still emit).
pub fn build_strata(
    scene: &Scene,
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &LayoutParams,
) -> Result<Strata> {
    check_strata_input(views, predicted, params)?;
    let c = params.cell_px;
    let offset = Vpl::SURFACE_OFFSET * scene.diagonal();
    let occluded = |a: Vec3, b: Vec3| scene.occluded(a, b);
    let mut grids = Vec::with_capacity(views.len());
    let mut per: Vec<Vec<Emitter>> = Vec::new();
    let mut shared_pixels = 0;
    for (i, view) in views.iter().enumerate() {
        let pred = predicted.map(|p| p[i].as_slice());
        let (irradiance, source) = emitter_irradiance(view, pred, c, params.multi_bounce)?;
        let earlier = &views[..i];
        let owned = |x: Vec3| !earlier.iter().any(|u| u.sees(x, occluded));
        let (found, shared) = pixel_emitters(view, &irradiance, c, offset, owned);
        shared_pixels += shared;
        let grid = Grid {
            cells_x: view.width.div_ceil(c),
            cells_y: view.height.div_ceil(c),
            start: per.len(),
            source,
        };
        per.resize(grid.start + grid.cells(), Vec::new());
        for (k, e) in found {
            per[grid.start + k].push(e);
        }
        grids.push(grid);
    }
    let cells = per.len();
    let (off, light_hits_on_screen) = offscreen_emitters(scene, views, params)?;
    let samples: Vec<(Vec3, Vec3, f32)> = views.iter().flat_map(|v| view_samples(v)).collect();
    let radius = scene.near_field_radius();
    let on_screen: Vec<&Emitter> = per.iter().flatten().collect();
    let step = on_screen.len().div_ceil(VIEW_SAMPLES).max(1);
    let on_sample: Vec<&Emitter> = on_screen.iter().step_by(step).copied().collect();
    let on_eta = view_efficiency(&on_sample, &samples, radius);
    let on_mean = flux_weighted_mean(&on_sample, &on_eta);
    let off_eta = view_efficiency(&off.iter().collect::<Vec<_>>(), &samples, radius);
    let mut order: Vec<usize> = (0..off.len()).collect();
    order.sort_by(|&a, &b| off_eta[a].total_cmp(&off_eta[b]).then(a.cmp(&b)));
    let dark = order.partition_point(|&i| off_eta[i] <= 0.0);
    // Bins of equal view contribution `lum(flux) * eta`: the efficient emitters, few but bright
    // in the view, get bins of their own.
    let contribution = |i: usize| f64::from(luminance(off[i].flux)) * off_eta[i];
    let total: f64 = order[dark..].iter().map(|&i| contribution(i)).sum();
    let mut bins: Vec<Vec<usize>> = vec![Vec::new(); OFFSCREEN_BINS + 1];
    let mut acc = 0.0;
    for &i in &order[dark..] {
        let mid = acc + 0.5 * contribution(i);
        acc += contribution(i);
        let b = (mid / total * OFFSCREEN_BINS as f64) as usize;
        bins[b.min(OFFSCREEN_BINS - 1)].push(i);
    }
    bins[OFFSCREEN_BINS] = order[..dark].to_vec();
    let mut view_weight = vec![1.0; cells];
    for (b, members) in bins.iter().enumerate() {
        let group: Vec<&Emitter> = members.iter().map(|&i| &off[i]).collect();
        let eta: Vec<f64> = members.iter().map(|&i| off_eta[i]).collect();
        view_weight.push(match (b == OFFSCREEN_BINS, on_mean > 0.0) {
            (true, _) => 0.0,
            (false, true) => flux_weighted_mean(&group, &eta) / on_mean,
            (false, false) => 1.0,
        });
        per.push(group.into_iter().cloned().collect());
    }
    let mut start = Vec::with_capacity(per.len() + 1);
    let mut emitters = Vec::new();
    let mut flux = Vec::with_capacity(per.len());
    for s in per {
        start.push(emitters.len());
        flux.push(s.iter().map(|e| e.flux).sum());
        emitters.extend(s);
    }
    start.push(emitters.len());
    Ok(Strata {
        cell_px: c,
        grids,
        emitters,
        start,
        flux,
        light_hits_on_screen,
        shared_pixels,
        view_weight,
    })
}

/// The argument checks of [`build_strata`].
fn check_strata_input(
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &LayoutParams,
) -> Result<()> {
    if views.is_empty() {
        return Err(VplaceError::Empty {
            what: "views".into(),
            hint: "give at least one view to lay out VPLs for".into(),
        });
    }
    if params.cell_px == 0 {
        return Err(VplaceError::OutOfRange {
            what: "cell_px".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    if let Some(p) = predicted {
        if p.len() != views.len() {
            return Err(VplaceError::Shape {
                what: "predicted".into(),
                expected: format!("one prediction per view ({})", views.len()),
                got: format!("{}", p.len()),
            });
        }
    }
    Ok(())
}

/// The light-path hits no view sees, as emitters of the off-screen strata, and how many hits a
/// view sees (dropped: its pixels stand for them).
fn offscreen_emitters(
    scene: &Scene,
    views: &[&View],
    params: &LayoutParams,
) -> Result<(Vec<Emitter>, usize)> {
    let occluded = |a: Vec3, b: Vec3| scene.occluded(a, b);
    let mut off: Vec<Emitter> = Vec::new();
    let mut light_hits_on_screen = 0;
    if params.light_rays > 0 && scene.has_emitters() {
        for v in light_path_vpls(scene, params.light_rays, params.seed, params.bounces)? {
            if views.iter().any(|view| view.sees(v.position, occluded)) {
                light_hits_on_screen += 1;
            } else if luminance(v.flux) > 0.0 {
                off.push(Emitter {
                    position: v.position,
                    normal: v.normal,
                    flux: v.flux,
                });
            }
        }
    }
    Ok((off, light_hits_on_screen))
}

/// About [`VIEW_SAMPLES`] covered pixels of the view on a regular grid: (position, unit
/// normal facing the camera, albedo luminance).
fn view_samples(view: &View) -> Vec<(Vec3, Vec3, f32)> {
    let g = view.gbuffer();
    let covered = view.covered_count();
    let stride = ((covered as f64 / VIEW_SAMPLES as f64).sqrt().floor() as usize).max(1);
    let mut out = Vec::new();
    for y in (stride / 2..g.height).step_by(stride) {
        for x in (stride / 2..g.width).step_by(stride) {
            let p = y * g.width + x;
            if !g.covered[p] {
                continue;
            }
            let pos = vec3(g.position, p);
            let mut n = vec3(g.normal, p).normalize_or_zero();
            let albedo = luminance(vec3(g.albedo, p));
            if n == Vec3::ZERO || !pos.is_finite() || !albedo.is_finite() {
                continue;
            }
            if n.dot(view.camera.position - pos) < 0.0 {
                n = -n;
            }
            out.push((pos, n, albedo.max(0.0)));
        }
    }
    out
}

/// Emitters per task of [`view_efficiency`], shaded in one batch per sample.
const EMITTER_CHUNK: usize = 256;

/// The view efficiency `eta_e` of each emitter: the mean over `samples` (position, unit normal,
/// albedo) of `albedo / pi * I(cos_e) * max(0, n_p . l) * F(r)`, the shading term of
/// [`crate::shade::shading`] for the cosine profile without shadow rays (the radiance an emitter of
/// unit flux sends back from each sample pixel; `F` the near-field term with radius `radius`).
/// Parallel over chunks of emitters; each sample shades a chunk in one batch.
#[must_use]
pub fn view_efficiency(
    emitters: &[&Emitter],
    samples: &[(Vec3, Vec3, f32)],
    radius: f32,
) -> Vec<f64> {
    if samples.is_empty() {
        return vec![0.0; emitters.len()];
    }
    let radius_sq = radius * radius;
    let norm = samples.len() as f64 * f64::from(PI);
    emitters
        .par_chunks(EMITTER_CHUNK)
        .map(|chunk| {
            let unit: Vec<Vpl> = chunk
                .iter()
                .map(|e| Vpl {
                    position: e.position,
                    normal: e.normal,
                    flux: Vec3::ONE,
                })
                .collect();
            let soa = VplSoa::new(&unit);
            let mut batch = Batch::new(soa.len());
            let mut sum = vec![0.0f64; chunk.len()];
            for &(p, n, albedo) in samples {
                batch.prepare_unshadowed(&soa, p, n, Profile::Cosine, radius_sq);
                for (acc, &s) in sum.iter_mut().zip(batch.scales()) {
                    *acc += f64::from(albedo * s);
                }
            }
            sum.into_iter().map(|s| s / norm).collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>()
        .concat()
}

/// `sum lum(flux_e) * eta_e / sum lum(flux_e)`, 0 for no flux.
fn flux_weighted_mean(emitters: &[&Emitter], eta: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (e, &v) in emitters.iter().zip(eta) {
        let l = f64::from(luminance(e.flux));
        num += l * v;
        den += l;
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// Largest-remainder rounding of `budget * w_k / sum w`: non-negative integers summing to
/// `budget` (ties go to the lower index). All-zero weights give all zeros.
#[must_use]
pub fn largest_remainder(weights: &[f64], budget: usize) -> Vec<usize> {
    let total: f64 = weights.iter().map(|w| w.max(0.0)).sum();
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return vec![0; weights.len()];
    }
    let quota: Vec<f64> = weights
        .iter()
        .map(|w| w.max(0.0) / total * budget as f64)
        .collect();
    let mut counts: Vec<usize> = quota.iter().map(|q| q.floor() as usize).collect();
    let given: usize = counts.iter().sum();
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (quota[a] - quota[a].floor(), quota[b] - quota[b].floor());
        rb.total_cmp(&ra).then(a.cmp(&b))
    });
    for &k in order.iter().take(budget.saturating_sub(given)) {
        counts[k] += 1;
    }
    counts
}

/// The share of each stratum: `lerp(u_k, m_k, alpha)`, summing to 1.
///
/// `predicted` holds the predicted `dL` per cell of each view (`cells_y x cells_x`, row-major,
/// in the order of [`Strata::grids`]) or is `None` (uniform); negative predictions count as 0 and
/// the off-screen strata get the flux-weighted mean prediction of the cells times their view
/// weight. When every `m_k` is 0 the uniform share is used.
pub fn shares(strata: &Strata, predicted: Option<&[Vec<f64>]>, alpha: f32) -> Result<Vec<f64>> {
    if !(0.0..=1.0).contains(&alpha) {
        return Err(VplaceError::OutOfRange {
            what: "alpha".into(),
            value: alpha.to_string(),
            expected: "[0, 1]".into(),
        });
    }
    let lum = strata.luminance();
    let total: f64 = lum.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return Err(VplaceError::Invalid {
            what: "candidate emitters".into(),
            reason: "no surface receives direct light: check the DiffDir pass and the lights"
                .into(),
        });
    }
    let u: Vec<f64> = lum.iter().map(|l| l / total).collect();
    let Some(pred) = predicted else {
        return Ok(u);
    };
    if pred.len() != strata.grids.len() {
        return Err(VplaceError::Shape {
            what: "predicted".into(),
            expected: format!("one prediction per view ({})", strata.grids.len()),
            got: format!("{}", pred.len()),
        });
    }
    for (p, g) in pred.iter().zip(&strata.grids) {
        if p.len() != g.cells() {
            return Err(VplaceError::Shape {
                what: "predicted".into(),
                expected: format!("({}, {})", g.cells_y, g.cells_x),
                got: format!("{} values", p.len()),
            });
        }
    }
    let pred = pred.concat();
    if let Some(index) = pred.iter().position(|v| !v.is_finite()) {
        return Err(VplaceError::NonFinite {
            what: "predicted".into(),
            index,
        });
    }
    Ok(blend(
        &u,
        &importance(&lum, &pred, &strata.view_weight),
        f64::from(alpha),
    ))
}

/// `lum_k * max(0, d_k) * v_k` normalized, with the off-screen strata (after the cells) given
/// the flux-weighted mean of `d` over the cells; all zeros when nothing is positive.
pub(crate) fn importance(lum: &[f64], per_cell: &[f64], view_weight: &[f64]) -> Vec<f64> {
    let cells = per_cell.len();
    let cell_lum: f64 = lum[..cells].iter().sum();
    let mean = if cell_lum > 0.0 {
        per_cell
            .iter()
            .zip(lum)
            .map(|(d, l)| d.max(0.0) * l)
            .sum::<f64>()
            / cell_lum
    } else {
        0.0
    };
    let mut m: Vec<f64> = (0..lum.len())
        .map(|k| {
            let d = if k < cells { per_cell[k] } else { mean };
            d.max(0.0) * lum[k] * view_weight[k]
        })
        .collect();
    let total: f64 = m.iter().sum();
    if total > 0.0 {
        m.iter_mut().for_each(|v| *v /= total);
    }
    m
}

/// `(1 - t) * u + t * m`, or `u` when `m` is all zeros.
pub(crate) fn blend(u: &[f64], m: &[f64], t: f64) -> Vec<f64> {
    if m.iter().sum::<f64>() <= 0.0 {
        return u.to_vec();
    }
    u.iter().zip(m).map(|(a, b)| a + (b - a) * t).collect()
}

/// How a budget is split over the strata.
///
/// Invariant: `counts.iter().sum() + pool_count == budget`; every stratum with flux either has
/// `counts[k] >= 1` or is listed in `pool`, and `pool_count >= 1` when `pool` is non-empty.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Allocation {
    /// VPLs drawn from each stratum alone.
    pub counts: Vec<usize>,
    /// Strata with flux but no VPL of their own, drawn from jointly.
    pub pool: Vec<usize>,
    /// VPLs drawn from the pool.
    pub pool_count: usize,
}

/// The stratum with the most VPLs (the lowest index on ties) and its count.
fn largest(counts: &[usize]) -> (usize, usize) {
    let (k, &most) = counts
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        .expect("at least one stratum");
    (k, most)
}

/// Splits `budget` over the strata by largest remainder of `budget * shares`, then pools the
/// strata that hold flux but got no VPL: the pool gets `max(1, round(budget * their shares))`
/// VPLs, taken one by one from the stratum with the most (the lowest index on ties).
pub fn allocate(strata: &Strata, shares: &[f64], budget: usize) -> Result<Allocation> {
    if budget == 0 {
        return Err(VplaceError::OutOfRange {
            what: "budget".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    if shares.len() != strata.strata() {
        return Err(VplaceError::Shape {
            what: "shares".into(),
            expected: format!("{} values (one per stratum)", strata.strata()),
            got: format!("{} values", shares.len()),
        });
    }
    let lum = strata.luminance();
    // A stratum without flux cannot emit, whatever its share.
    let w: Vec<f64> = shares
        .iter()
        .zip(&lum)
        .map(|(&s, &l)| if l > 0.0 { s } else { 0.0 })
        .collect();
    let mut counts = largest_remainder(&w, budget);
    // A dark stratum (view weight 0) with flux keeps one VPL of its own: pooled, its large flux
    // would swamp the draw of the cells it is pooled with.
    for k in 0..counts.len() {
        if lum[k] > 0.0 && counts[k] == 0 && strata.view_weight[k] == 0.0 {
            let (most, c) = largest(&counts);
            if c >= 2 {
                counts[most] -= 1;
                counts[k] = 1;
            }
        }
    }
    let pool: Vec<usize> = (0..counts.len())
        .filter(|&k| lum[k] > 0.0 && counts[k] == 0)
        .collect();
    let mut pool_count = 0;
    if pool.is_empty() {
        return Ok(Allocation {
            counts,
            pool,
            pool_count,
        });
    }
    let total: f64 = w.iter().sum();
    let want = pool.iter().map(|&k| w[k]).sum::<f64>() / total * budget as f64;
    let want = (want.round() as usize).max(1);
    while pool_count < want {
        let (k, most) = largest(&counts);
        if most >= 2 {
            counts[k] -= 1;
            pool_count += 1;
            continue;
        }
        if most == 1 && pool_count == 0 {
            // No stratum can spare one: this one gives its only VPL and joins the pool.
            counts[k] = 0;
            pool_count = 1;
        }
        break;
    }
    let pool: Vec<usize> = (0..counts.len())
        .filter(|&k| lum[k] > 0.0 && counts[k] == 0)
        .collect();
    Ok(Allocation {
        counts,
        pool,
        pool_count,
    })
}

/// Draws `n` emitters of `group` (stratum ranges) by luminance flux with systematic sampling
/// (one random offset); each VPL carries the luminance `lum(group) / n` with its emitter's colour.
fn draw_group(strata: &Strata, group: &[usize], n: usize, rng: &mut Rng, out: &mut Vec<Vpl>) {
    if n == 0 {
        return;
    }
    let items = || {
        group
            .iter()
            .flat_map(|&k| &strata.emitters[strata.start[k]..strata.start[k + 1]])
    };
    let total: f64 = items().map(|e| f64::from(luminance(e.flux))).sum();
    if total.is_nan() || total <= 0.0 {
        return;
    }
    let per = total / n as f64;
    let r = f64::from(rng.next_f32());
    let mut acc = 0.0f64;
    let mut i = 0usize;
    let mut last = None;
    for e in items() {
        let l = f64::from(luminance(e.flux));
        acc += l;
        last = Some(e);
        while i < n && (i as f64 + r) * per < acc {
            out.push(Vpl {
                position: e.position,
                normal: e.normal,
                flux: e.flux * (per / l) as f32,
            });
            i += 1;
        }
    }
    // Rounding can leave the last target just past the end of the sum.
    if let Some(e) = last {
        let l = f64::from(luminance(e.flux));
        while i < n {
            out.push(Vpl {
                position: e.position,
                normal: e.normal,
                flux: e.flux * (per / l) as f32,
            });
            i += 1;
        }
    }
}

/// Draws the VPLs of `allocation`. Deterministic for `seed`: each stratum has its own random
/// stream, so one stratum's count does not change another's draws.
#[must_use]
pub fn draw(strata: &Strata, allocation: &Allocation, seed: u64) -> Vec<Vpl> {
    let mut out =
        Vec::with_capacity(allocation.counts.iter().sum::<usize>() + allocation.pool_count);
    for (k, &n) in allocation.counts.iter().enumerate() {
        let mut rng = Rng::new(seed, k as u64 + 1);
        draw_group(strata, &[k], n, &mut rng, &mut out);
    }
    let mut rng = Rng::new(seed, 0);
    draw_group(
        strata,
        &allocation.pool,
        allocation.pool_count,
        &mut rng,
        &mut out,
    );
    out
}

/// The one-shot layout for `views`: strata, shares, allocation and draw. `predicted` holds the
/// fit's per-cell `dL` of each view (see [`shares`]). Returns the VPLs, the allocation and the
/// strata.
pub fn layout(
    scene: &Scene,
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &LayoutParams,
) -> Result<(Vec<Vpl>, Allocation, Strata)> {
    let strata = build_strata(scene, views, predicted, params)?;
    let s = shares(&strata, predicted, params.alpha)?;
    let a = allocate(&strata, &s, params.budget)?;
    Ok((draw(&strata, &a, params.seed), a, strata))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Light;
    use crate::test_util::{closed_box, reference_incident, shading_cases, FloorView};

    const LIGHT: Vec3 = Vec3::new(0.3, -0.2, 1.0);

    fn setup() -> (Scene, FloorView) {
        let scene = closed_box(vec![Light::point(LIGHT, Vec3::splat(20.0))]);
        (scene, FloorView::new(32, LIGHT, 20.0))
    }

    fn lum_total(v: &[Vpl]) -> f64 {
        v.iter().map(|v| f64::from(luminance(v.flux))).sum()
    }

    /// A prediction favouring the top-left cells.
    fn prediction(s: &Strata) -> Vec<f64> {
        (0..s.offscreen())
            .map(|c| {
                let cells_x = s.grids[0].cells_x;
                let (x, y) = (c % cells_x, c / cells_x);
                1.0 / (1.0 + (x + y) as f64)
            })
            .collect()
    }

    #[test]
    fn pixel_flux_is_the_reflected_direct_light() {
        // The floor seen whole: sum of pixel flux = albedo-weighted direct flux on the floor.
        let (scene, fv) = setup();
        let params = LayoutParams {
            light_rays: 0,
            cell_px: 8,
            ..LayoutParams::DEFAULT
        };
        let s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
        assert_eq!(s.strata(), 4 * 4 + OFFSCREEN_BINS + 1);
        assert_eq!(s.emitters.len(), 32 * 32);
        // Reference by fine numerical integration over the floor.
        let m = 400;
        let mut expect = Vec3::ZERO;
        for j in 0..m {
            for i in 0..m {
                let p = Vec3::new(
                    (i as f32 + 0.5) / m as f32 * 2.0 - 1.0,
                    (j as f32 + 0.5) / m as f32 * 2.0 - 1.0,
                    0.0,
                );
                let l = LIGHT - p;
                let e = 20.0 / (4.0 * PI) * l.z / l.length().powi(3);
                let a = if p.x < 0.0 {
                    Vec3::new(0.8, 0.2, 0.2)
                } else {
                    Vec3::splat(0.5)
                };
                expect += a * e * (4.0 / (m * m) as f32);
            }
        }
        let got: Vec3 = s.flux.iter().copied().sum();
        assert!(
            (got - expect).abs().max_element() < 0.02 * expect.max_element(),
            "{got} {expect}"
        );
    }

    #[test]
    fn allocation_sums_to_budget_and_conserves_energy() {
        let (scene, fv) = setup();
        for (cell_px, light_rays) in [(8, 500), (4, 500), (32, 0), (1, 200)] {
            let params = LayoutParams {
                cell_px,
                light_rays,
                ..LayoutParams::DEFAULT
            };
            let s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
            let pred = prediction(&s);
            let total = s.luminance().iter().sum::<f64>();
            for budget in [1, 3, 16, 100, 256] {
                for alpha in [0.0, 0.3, 1.0] {
                    let sh = shares(&s, Some(std::slice::from_ref(&pred)), alpha).unwrap();
                    let a = allocate(&s, &sh, budget).unwrap();
                    assert_eq!(a.counts.iter().sum::<usize>() + a.pool_count, budget);
                    let lum = s.luminance();
                    for (k, &l) in lum.iter().enumerate() {
                        assert!(l == 0.0 || a.counts[k] > 0 || a.pool.contains(&k));
                    }
                    let v = draw(&s, &a, 5);
                    assert_eq!(v.len(), budget, "{cell_px} {budget} {alpha}");
                    let got = lum_total(&v);
                    assert!(
                        (got - total).abs() < 1e-4 * total,
                        "{cell_px} {budget} {alpha}: {got} {total}"
                    );
                }
            }
        }
    }

    #[test]
    fn alpha_zero_is_the_uniform_allocation_and_alpha_moves_budget() {
        let (scene, fv) = setup();
        let params = LayoutParams {
            cell_px: 8,
            light_rays: 500,
            bounces: 1,
            ..LayoutParams::DEFAULT
        };
        let s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
        let pred = prediction(&s);
        let uniform = allocate(&s, &shares(&s, None, 1.0).unwrap(), 256).unwrap();
        let a0 = allocate(
            &s,
            &shares(&s, Some(std::slice::from_ref(&pred)), 0.0).unwrap(),
            256,
        )
        .unwrap();
        assert_eq!(a0, uniform);
        // Uniform counts follow the flux.
        let lum = s.luminance();
        let total: f64 = lum.iter().sum();
        for (k, &n) in uniform.counts.iter().enumerate() {
            assert!((n as f64 - 256.0 * lum[k] / total).abs() <= 1.0);
        }
        // Guided: the favoured top-left cell gains, the bottom-right one loses.
        let a1 = allocate(
            &s,
            &shares(&s, Some(std::slice::from_ref(&pred)), 1.0).unwrap(),
            256,
        )
        .unwrap();
        let last = s.offscreen() - 1;
        assert!(a1.counts[0] > uniform.counts[0]);
        assert!(a1.counts[last] < uniform.counts[last]);
    }

    #[test]
    fn deterministic_per_seed() {
        let (scene, fv) = setup();
        let mut params = LayoutParams {
            cell_px: 8,
            light_rays: 300,
            budget: 64,
            ..LayoutParams::DEFAULT
        };
        let (a, _, _) = layout(&scene, &[&fv.view()], None, &params).unwrap();
        let (b, _, _) = layout(&scene, &[&fv.view()], None, &params).unwrap();
        params.seed = 9;
        let (c, _, _) = layout(&scene, &[&fv.view()], None, &params).unwrap();
        assert_eq!(a, b);
        assert_ne!(a, c);
        for v in &a {
            assert!((v.normal.length() - 1.0).abs() < 1e-4);
            assert!(v.flux.min_element() >= 0.0);
        }
    }

    #[test]
    fn offscreen_stratum_holds_what_the_camera_misses() {
        let (scene, fv) = setup();
        let params = LayoutParams {
            cell_px: 8,
            light_rays: 2000,
            bounces: 1,
            ..LayoutParams::DEFAULT
        };
        let s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
        let k = s.offscreen();
        let off = &s.emitters[s.start[k]..s.start[k + 1]];
        assert!(!off.is_empty());
        assert!(s.light_hits_on_screen > 0);
        // The camera sees the whole floor: no first-bounce off-screen emitter lies on it.
        assert!(off.iter().all(|e| e.normal.z < 0.5));
        // Later bounces add the light the walls and the ceiling pass on.
        let all = build_strata(
            &scene,
            &[&fv.view()],
            None,
            &LayoutParams {
                bounces: MAX_BOUNCES,
                ..params
            },
        )
        .unwrap();
        let lum = |s: &Strata| luminance(s.flux[s.offscreen()]);
        assert!(lum(&all) > 1.2 * lum(&s), "{} {}", lum(&all), lum(&s));
    }

    #[test]
    fn view_efficiency_sees_only_what_faces_the_view() {
        let samples = [(Vec3::ZERO, Vec3::Z, 0.5)];
        let e = |z: f32, nz: f32| Emitter {
            position: Vec3::new(0.0, 0.0, z),
            normal: Vec3::new(0.0, 0.0, nz),
            flux: Vec3::ONE,
        };
        let (down1, down2, up) = (e(1.0, -1.0), e(2.0, -1.0), e(1.0, 1.0));
        // Point-like emitters (radius 0): albedo cos cos / (pi^2 r^2).
        let eta = view_efficiency(&[&down1, &down2, &up], &samples, 0.0);
        assert!((eta[0] - 0.5 / (PI * PI) as f64).abs() < 1e-6, "{eta:?}");
        assert!((eta[0] / eta[1] - 4.0).abs() < 1e-4); // inverse square
        assert_eq!(eta[2], 0.0); // faces away: dark
        assert!(view_efficiency(&[&down1], &[], 0.01) == vec![0.0]);
        // A disk of radius 1 at distance 1 on the axis: 1 / (h^2 + R^2) halves the point's.
        let disk = view_efficiency(&[&down1], &samples, 1.0);
        assert!((disk[0] / eta[0] - 0.5).abs() < 1e-5, "{disk:?}");
    }

    /// The view efficiency is the brute-force reference's (a plain scalar loop over emitters x
    /// samples of `albedo / pi * reference_incident` with unit flux, cosine profile, no shadow
    /// ray), bit for bit, on the degenerate cases of [`shading_cases`] (a zero normal, an
    /// emitter at a sample, emitters behind samples, samples behind emitters), with more
    /// emitters than one parallel chunk; and within rounding of the formula it had before it
    /// used the shading module.
    #[test]
    fn view_efficiency_matches_the_brute_force_reference() {
        let (_, g, vpls) = shading_cases();
        let samples: Vec<(Vec3, Vec3, f32)> = (0..144)
            .filter(|&p| g.covered[p])
            .map(|p| {
                let v = |a: &[f32]| Vec3::from_slice(&a[3 * p..3 * p + 3]);
                (
                    v(&g.position),
                    v(&g.normal).normalize_or_zero(),
                    luminance(v(&g.albedo)),
                )
            })
            .collect();
        let mut rng = Rng::new(2, 0);
        let mut emitters: Vec<Emitter> = vpls
            .iter()
            .map(|v| Emitter {
                position: v.position,
                normal: v.normal,
                flux: v.flux,
            })
            .collect();
        while emitters.len() < EMITTER_CHUNK + 50 {
            let k = emitters.len() % vpls.len();
            let jitter = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.02;
            emitters.push(Emitter {
                position: vpls[k].position - jitter,
                ..emitters[k]
            });
        }
        let refs: Vec<&Emitter> = emitters.iter().collect();
        for radius in [0.0, 0.05, 0.4] {
            let eta = view_efficiency(&refs, &samples, radius);
            let mut any_behind = false;
            for (e, &got) in emitters.iter().zip(&eta) {
                let unit = Vpl {
                    position: e.position,
                    normal: e.normal,
                    flux: Vec3::ONE,
                };
                let mut sum = 0.0f64;
                for &(p, n, albedo) in &samples {
                    match reference_incident(None, p, n, &unit, Profile::Cosine, radius) {
                        Some(c) => sum += f64::from(albedo * c.x),
                        None => any_behind |= n != Vec3::ZERO && p != e.position,
                    }
                }
                let n = samples.len() as f64;
                assert_eq!(got, sum / (n * f64::from(PI)), "radius {radius}");
            }
            assert!(any_behind);
            assert!(eta.contains(&0.0) && eta.iter().any(|&e| e > 0.0));
        }
    }

    #[test]
    fn offscreen_strata_by_view_efficiency_and_the_dark_one_keeps_a_vpl() {
        let (scene, fv) = setup();
        let params = LayoutParams {
            cell_px: 8,
            light_rays: 2000,
            ..LayoutParams::DEFAULT
        };
        let mut s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
        let k0 = s.offscreen();
        assert_eq!(s.view_weight.len(), s.strata());
        assert!(s.view_weight[..k0].iter().all(|&v| v == 1.0));
        // Bins by increasing efficiency; the last (dark) one has weight 0.
        let lit = &s.view_weight[k0..k0 + OFFSCREEN_BINS];
        assert!(lit.windows(2).all(|w| w[0] <= w[1]), "{lit:?}");
        assert_eq!(s.view_weight[s.strata() - 1], 0.0);
        // Make a dark stratum with flux: fully guided, it still gets one VPL of its own and
        // the total flux does not change.
        let last = s.strata() - 1;
        let moved = s.start[last] - s.start[k0 + OFFSCREEN_BINS - 1];
        assert!(moved > 0);
        s.start[last] = s.start[k0 + OFFSCREEN_BINS - 1];
        s.flux[last] = s.emitters[s.start[last]..s.start[last + 1]]
            .iter()
            .map(|e| e.flux)
            .sum();
        s.flux[last - 1] = Vec3::ZERO;
        let pred = vec![1.0; k0];
        let a = allocate(
            &s,
            &shares(&s, Some(std::slice::from_ref(&pred)), 1.0).unwrap(),
            64,
        )
        .unwrap();
        assert_eq!(a.counts[last], 1);
        let v = draw(&s, &a, 3);
        let total: f64 = v.iter().map(|v| f64::from(luminance(v.flux))).sum();
        let expect: f64 = s.luminance().iter().sum();
        assert!((total - expect).abs() < 1e-4 * expect, "{total} {expect}");
    }

    #[test]
    fn largest_remainder_rounds() {
        assert_eq!(largest_remainder(&[1.0, 1.0, 1.0], 4), vec![2, 1, 1]);
        assert_eq!(largest_remainder(&[0.0, 0.0], 4), vec![0, 0]);
        assert_eq!(largest_remainder(&[0.2, 0.8], 10), vec![2, 8]);
        assert_eq!(largest_remainder(&[-1.0, 1.0], 3), vec![0, 3]);
    }

    #[test]
    fn bad_input() {
        let (scene, fv) = setup();
        let params = LayoutParams {
            light_rays: 0,
            ..LayoutParams::DEFAULT
        };
        let s = build_strata(&scene, &[&fv.view()], None, &params).unwrap();
        assert!(shares(&s, None, 1.5).is_err());
        assert!(shares(&s, Some(&[vec![1.0]]), 0.5).is_err());
        assert!(shares(&s, Some(&[]), 0.5).is_err());
        let nan = vec![f64::NAN; s.offscreen()];
        assert!(shares(&s, Some(&[nan]), 0.5).is_err());
        assert!(allocate(&s, &[1.0], 5).is_err());
        assert!(allocate(&s, &vec![1.0; s.strata()], 0).is_err());
        assert!(matches!(
            build_strata(&scene, &[], None, &params),
            Err(VplaceError::Empty { .. })
        ));
        let short = vec![vec![1.0; 3]];
        assert!(matches!(
            build_strata(&scene, &[&fv.view()], Some(&short), &params),
            Err(VplaceError::Shape { .. })
        ));
        let dark = FloorView {
            diffuse_direct: vec![0.0; fv.diffuse_direct.len()],
            ..fv.clone()
        };
        let v = dark.view();
        let s = build_strata(&scene, &[&v], None, &params).unwrap();
        assert!(matches!(
            shares(&s, None, 0.0),
            Err(VplaceError::Invalid { .. })
        ));
    }
}
