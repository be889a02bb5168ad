//! Candidate emitters and strata (see the module docs of [`crate::layout`]): the pixel
//! emitters of every view, the off-screen light-path hits grouped by view efficiency, and the
//! strata they fall into.

use super::*;

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
    /// The factor the VPLs drawn from the cells carry their emitters' flux by, so that the
    /// pixels' light matches what the light paths say their surfaces receive
    /// ([`pixel_flux_scale`]; 1 where the two agree). The strata's flux, and with it the
    /// allocation, is the pixels' own ([`draw`]).
    pub pixel_flux_scale: f32,
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
pub(super) fn vec3(arr: &[f32], p: usize) -> Vec3 {
    Vec3::new(arr[3 * p], arr[3 * p + 1], arr[3 * p + 2])
}

/// The unit view direction through the image point `(x, y)` (pixels, y down), as the line
/// through two unprojected depths (so the camera position and the depth range do not enter).
pub(super) fn corner_direction(inv: &Mat4, x: f32, y: f32, w: usize, h: usize) -> Vec3 {
    let (nx, ny) = (x / w as f32 * 2.0 - 1.0, 1.0 - y / h as f32 * 2.0);
    let near = inv.project_point3(Vec3::new(nx, ny, -0.5));
    let far = inv.project_point3(Vec3::new(nx, ny, 0.5));
    (far - near).normalize_or_zero()
}

/// The solid angle of a pixel from the view directions of its top-left, top-right and
/// bottom-left corners.
pub(super) fn solid_angle(d00: Vec3, d10: Vec3, d01: Vec3) -> f32 {
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

/// One band of rows of [`pixel_emitters`]: its emitters with their cells, the emitters an
/// earlier view holds, and the direct light its pixels receive.
type BandEmitters = (Vec<(usize, Emitter)>, usize, f64);

/// The pixel emitters of `view` reflecting `irradiance` (irradiance / pi, `H x W x 3`), each with
/// its cell, in pixel order; `owned(x)` says whether the emitter at `x` belongs to this view (not
/// already held by an earlier one). Also the emitters an earlier view holds, and the direct
/// light the view's own pixels with a diffuse layer receive (`pi * DiffDir * footprint`,
/// luminance, summed, see [`pixel_flux_scale`]).
pub(super) fn pixel_emitters(
    view: &View,
    irradiance: &[f32],
    cell_px: usize,
    offset: f32,
    owned: impl Fn(Vec3) -> bool + Sync,
) -> (Vec<(usize, Emitter)>, usize, f64) {
    let (w, h, c) = (view.width, view.height, cell_px);
    let cells_x = w.div_ceil(c);
    let cam = view.camera.position;
    let inv = view.camera.world_to_clip.inverse();
    // Rows in parallel, in bands that share the view directions of their pixel corners; the
    // emitters are then appended in pixel order, as a plain row-major loop would.
    let band = 8;
    let found: Vec<BandEmitters> = (0..h.div_ceil(band))
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
            let mut received_sum = 0.0f64;
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
                    let reflectance = vec3(&view.albedo, p);
                    let flux = reflectance * (PI * dd.max(Vec3::ZERO)) * area;
                    let received = (PI * vec3(&view.diffuse_direct, p).max(Vec3::ZERO)) * area;
                    let position = pos + n * offset;
                    let lum = luminance(flux);
                    let emits = !(lum.is_nan() || lum <= 0.0 || !flux.is_finite());
                    // The direct light a diffuse surface receives counts whatever it reflects
                    // (a black pixel too), as the light paths' first hits count it.
                    let lum_received = f64::from(luminance(received));
                    // The diffuse layer's share of the surface's whole reflectance, as a light
                    // path's hit reads its material's (`DiffCol` against `DiffCol + GlossCol`).
                    let glossy = view.specular.as_deref().map_or(Vec3::ZERO, |g| vec3(g, p));
                    let diffuse = view.diffuse_color_at(p).max(Vec3::ZERO);
                    let receives = lum_received.is_finite()
                        && lum_received > 0.0
                        && diffuse_share(diffuse, diffuse + glossy) >= DIFFUSE_SHARE;
                    if !emits && !receives {
                        continue;
                    }
                    let mine = owned(position);
                    if receives && mine {
                        received_sum += lum_received;
                    }
                    if !emits {
                        continue;
                    }
                    if !mine {
                        shared += 1;
                        continue;
                    }
                    out.push((
                        (y / c) * cells_x + x / c,
                        Emitter {
                            position,
                            normal: n,
                            flux,
                        },
                    ));
                }
            }
            (out, shared, received_sum)
        })
        .collect();
    let shared = found.iter().map(|(_, s, _)| s).sum();
    let received = found.iter().map(|(_, _, r)| r).sum();
    (
        found.into_iter().flat_map(|(e, _, _)| e).collect(),
        shared,
        received,
    )
}

/// Gathers the candidate emitters of `views` into strata (see the module docs). `predicted`,
/// when given, holds the fit's per-cell `dL` of each view (`cells_y x cells_x`, row-major); a
/// view without a `diffuse_indirect` pass then reflects it ([`emitter_irradiance`]).
///
/// Errors: no views, `cell_px == 0`, a prediction of the wrong size, or failing light rays
/// (see [`light_path_vpls`](crate::vpl::light_path_vpls)). A scene without emitters gets empty
/// off-screen strata (its pixels still emit).
pub fn build_strata(
    scene: &Scene,
    views: &[&View],
    predicted: Option<&[Vec<f64>]>,
    params: &LayoutParams,
) -> Result<Strata> {
    check_strata_input(views, predicted, params)?;
    let c = params.cell_px;
    let offset = Vpl::SURFACE_OFFSET * scene.scale();
    let occluded = |a: Vec3, b: Vec3| scene.occluded(a, b);
    let mut grids = Vec::with_capacity(views.len());
    let mut per: Vec<Vec<Emitter>> = Vec::new();
    let mut shared_pixels = 0;
    let mut pixels_received = 0.0f64;
    for (i, view) in views.iter().enumerate() {
        let pred = predicted.map(|p| p[i].as_slice());
        let (irradiance, source) = emitter_irradiance(view, pred, c, params.multi_bounce)?;
        let earlier = &views[..i];
        let owned = |x: Vec3| !earlier.iter().any(|u| u.sees(x, occluded));
        let (found, shared, received) = pixel_emitters(view, &irradiance, c, offset, owned);
        shared_pixels += shared;
        pixels_received += received;
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
    let (off, seen) = offscreen_emitters(scene, views, params)?;
    let pixel_flux_scale = pixel_flux_scale(&seen, pixels_received);
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
    // Inside each bin, the emitters along a space-filling curve (see [`order_along_curve`]).
    let (lo, hi) = off.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), e| (lo.min(e.position), hi.max(e.position)),
    );
    for members in &mut bins {
        order_along_curve(members, &off, lo, hi);
    }
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
        light_hits_on_screen: seen.count,
        pixel_flux_scale,
        shared_pixels,
        view_weight,
    })
}

/// Orders `members` (indices into `emitters`, in increasing view efficiency) along a Morton
/// (Z-order) curve through their position in the box `lo..hi` and their rank among `members`
/// ([`curve_key`]).
///
/// The draw's systematic sampling ([`super::draw::draw_group`]) takes a bin's emitters in this
/// order, so that it spreads the bin's VPLs over space as its flux lies, as well as over view
/// efficiency: a part of the scene that holds a tenth of a bin's flux gets about a tenth of its
/// VPLs on every seed. In the order of view efficiency alone, the VPLs in a room behind a door
/// that no capture sees (a porch of mine, 256 VPLs, seeds 0-5) numbered 2 to 9, and a camera
/// inside it saw 0.66-1.24 of the truth's brightness (0.77-1.05 in this order).
pub(super) fn order_along_curve(
    members: &mut Vec<usize>,
    emitters: &[Emitter],
    lo: Vec3,
    hi: Vec3,
) {
    let n = members.len().max(1) as f32;
    let mut keyed: Vec<(u64, usize)> = members
        .iter()
        .enumerate()
        .map(|(r, &i)| (curve_key(emitters[i].position, lo, hi, r as f32 / n), i))
        .collect();
    keyed.sort_unstable();
    *members = keyed.into_iter().map(|(_, i)| i).collect();
}

/// The Morton code of `p` in the box `lo..hi` and of `rank` in `[0, 1)`: 16 bits of each,
/// interleaved (x lowest, then y, z, rank).
#[must_use]
pub(super) fn curve_key(p: Vec3, lo: Vec3, hi: Vec3, rank: f32) -> u64 {
    let spread = |t: f32| -> u64 {
        let mut x = (t.clamp(0.0, 1.0) * 65535.0) as u64;
        x = (x | (x << 24)) & 0x0000_00ff_0000_00ff;
        x = (x | (x << 12)) & 0x000f_000f_000f_000f;
        x = (x | (x << 6)) & 0x0303_0303_0303_0303;
        x = (x | (x << 3)) & 0x1111_1111_1111_1111;
        x
    };
    let unit = |v: f32, a: f32, b: f32| if b > a { (v - a) / (b - a) } else { 0.0 };
    spread(unit(p.x, lo.x, hi.x))
        | (spread(unit(p.y, lo.y, hi.y)) << 1)
        | (spread(unit(p.z, lo.z, hi.z)) << 2)
        | (spread(rank) << 3)
}

/// The argument checks of [`build_strata`].
pub(super) fn check_strata_input(
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

/// The light-path hits that some view sees (dropped from the off-screen strata: its pixels
/// stand for them): how many, and over the first hits on surfaces with a diffuse layer
/// ([`DIFFUSE_SHARE`]), the sums of the luminance flux that arrived and of its square.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SeenHits {
    /// Hits a view sees.
    pub count: usize,
    /// The luminance flux that arrived straight from the emitters at the first hits a view
    /// sees on a surface with a diffuse layer, summed (watts).
    pub flux: f64,
    /// The squares of those fluxes, summed: `sqrt(flux_sq)` is the standard error of `flux` as
    /// an estimate of the direct light those surfaces receive, the hits taken as independent.
    pub flux_sq: f64,
}

/// The factor that gives the views' pixel emitters the light the light paths say their surfaces
/// receive: `seen.flux / received`, `received` the direct light the owned pixels with a diffuse
/// layer receive (`pi * DiffDir * footprint`, luminance, summed); 1 where the two agree within
/// [`PIXEL_FLUX_SIGMAS`] standard errors of the hits' sum (`sqrt(flux_sq)`), where either is
/// not positive or the ratio is not finite.
///
/// Both measure the direct light arriving on the surfaces the views see: a pixel as Cycles'
/// `DiffDir` times its footprint `r^2 omega / |cos|`, a light path's first hit as the flux its
/// ray brings. The irradiance is measured; the footprint is not: where the camera sees a
/// surface at grazing angles through bent shading normals, `cos` is wrong and clamped (on
/// Sponza's main view, 0.41 m above a normal-mapped floor, the footprints summed to 450 m^2 of
/// the floor's 641). Direct light and diffuse surfaces only: there Cycles' passes measure what
/// arrives (glass, metal and lamps have no diffuse pass), and no model of the light paths'
/// later bounces enters. The error is one of area, so the factor holds for the indirect light
/// the pixels reflect too. The refit pulls every VPL toward one gain of the captures: fitted
/// to pixel emitters short by a factor, it multiplied the light paths' VPLs, which light what
/// no capture sees, by it too. One factor for all pixels, not one per pixel (footprints that
/// follow the geometry pixel by pixel stretch a leaf seen edge on into a hot spot: README,
/// "Why the pixel emitters carry less") nor per view (the hits a dim view sees are too few).
#[must_use]
pub fn pixel_flux_scale(seen: &SeenHits, pixels: f64) -> f32 {
    let k = seen.flux / pixels;
    if !(seen.flux > 0.0 && pixels > 0.0 && k.is_finite()) {
        return 1.0;
    }
    let se = seen.flux_sq.sqrt() / pixels;
    if (k - 1.0).abs() <= PIXEL_FLUX_SIGMAS * se {
        return 1.0;
    }
    k as f32
}

/// The diffuse part's share of a surface's reflectance (luminance), 0 where it reflects nothing.
fn diffuse_share(diffuse: Vec3, reflectance: Vec3) -> f32 {
    let total = luminance(reflectance);
    if total > 0.0 {
        luminance(diffuse) / total
    } else {
        0.0
    }
}

/// The least share of a surface's reflectance its diffuse layer must hold for its light to
/// count in [`pixel_flux_scale`] (the add-on's `capture.passes.DIFFUSE_SHARE`): Cycles' diffuse
/// passes measure the light a surface receives only where it has a diffuse layer, and glass,
/// metal and lamps have none; the light paths' hits there are left out with the pixels. A
/// pixel's share reads its diffuse layer ([`View::diffuse_color_at`]: Cycles `DiffCol`) against
/// that plus its Glossy Color, whether or not its reflectance models the glossy layer: before,
/// it read the reflectance less the Glossy Color, which is the diffuse layer only where the
/// reflectance adds the glossy one, and a sunlit floor of a sharp glossy finish (Glossy Color
/// 0.41 over a diffuse 0.22, the layer left to EEVEE) counted as no diffuse surface: its light
/// paths' hits still counted, and the factor read 11.5.
pub const DIFFUSE_SHARE: f32 = 0.1;

/// How many standard errors of the light-path hits' sum the pixel emitters' flux must differ
/// from it by before [`pixel_flux_scale`] rescales them: within that the two agree, and the
/// layout keeps the pixels' own flux.
pub const PIXEL_FLUX_SIGMAS: f64 = 2.0;

/// The light-path hits no view sees, as emitters of the off-screen strata, and the hits a view
/// sees (dropped: its pixels stand for them).
pub(super) fn offscreen_emitters(
    scene: &Scene,
    views: &[&View],
    params: &LayoutParams,
) -> Result<(Vec<Emitter>, SeenHits)> {
    let occluded = |a: Vec3, b: Vec3| scene.occluded(a, b);
    let mut off: Vec<Emitter> = Vec::new();
    let mut seen = SeenHits::default();
    if params.light_rays > 0 && scene.has_emitters() {
        for hit in light_path_hits(scene, params.light_rays, params.seed, params.bounces)? {
            let v = hit.vpl;
            if views.iter().any(|view| view.sees(v.position, occluded)) {
                seen.count += 1;
                let lum = f64::from(luminance(hit.arriving));
                let diffuse = diffuse_share(hit.albedo, hit.albedo + hit.gloss) >= DIFFUSE_SHARE;
                if hit.bounce == 0 && diffuse && lum.is_finite() && lum > 0.0 {
                    seen.flux += lum;
                    seen.flux_sq += lum * lum;
                }
            } else if luminance(v.flux) > 0.0 {
                off.push(Emitter {
                    position: v.position,
                    normal: v.normal,
                    flux: v.flux,
                });
            }
        }
    }
    Ok((off, seen))
}

/// The stride whose grid sets a view's weight in the view efficiency:
/// `floor(sqrt(covered / VIEW_SAMPLES))`, at least 1. Its grid holds [`VIEW_SAMPLES`] to 4x as
/// many pixels (all 2,304 of a 48 x 48 coverage view).
pub(super) fn weight_stride(covered: usize) -> usize {
    ((covered as f64 / VIEW_SAMPLES as f64).sqrt().floor() as usize).max(1)
}

/// The stride the view is sampled with: [`weight_stride`], made wider where its grid would
/// hold more than twice [`VIEW_SAMPLES`] pixels (stride 2 and 576 samples for a 48 x 48
/// view; at least 1, as [`weight_stride`] is). The captures' strides at 192x108, 160x160 and
/// 320x180 (4, 5, 7) are [`weight_stride`]'s.
pub(super) fn sample_stride(covered: usize) -> usize {
    let least = (covered as f64 / (2 * VIEW_SAMPLES) as f64).sqrt().ceil() as usize;
    weight_stride(covered).max(least)
}

/// About [`VIEW_SAMPLES`] covered pixels of the view on the grid of [`sample_stride`]:
/// (position, unit normal facing the camera, albedo luminance times the sample's weight). The
/// weight, `(sample_stride / weight_stride)^2`, makes the view weigh as the grid of
/// [`weight_stride`] would in [`view_efficiency`]'s mean over every view's samples: a
/// coverage view sampled 1 in 4 weighs what its every pixel did.
pub(super) fn view_samples(view: &View) -> Vec<(Vec3, Vec3, f32)> {
    let g = view.gbuffer();
    let covered = view.covered_count();
    let stride = sample_stride(covered);
    let weight = ((stride * stride) as f64 / weight_stride(covered).pow(2) as f64) as f32;
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
            out.push((pos, n, albedo.max(0.0) * weight));
        }
    }
    out
}

/// Emitters per task of [`view_efficiency`], shaded in one batch per sample.
pub(super) const EMITTER_CHUNK: usize = 256;

/// The view efficiency `eta_e` of each emitter: the mean over `samples` (position, unit normal,
/// albedo times the sample's weight, [`view_samples`]; only ratios and signs of `eta` are read,
/// so the weights need not average 1) of `albedo / pi * I(cos_e) * max(0, n_p . l) * F(r)`, the
/// shading term of [`crate::shade::shading`] for the cosine profile without shadow rays (the
/// radiance an emitter of unit flux sends back from each sample pixel; `F` the near-field term
/// with radius `radius`).
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
            let soa = VplSoa::new(&unit, &vec![radius; unit.len()]);
            let mut batch = Batch::new(soa.len());
            let mut sum = vec![0.0f64; chunk.len()];
            for &(p, n, albedo) in samples {
                batch.prepare_unshadowed(&soa, p, n, Profile::Cosine);
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
pub(super) fn flux_weighted_mean(emitters: &[&Emitter], eta: &[f64]) -> f64 {
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
