//! Optional refit (DESIGN, Layout): non-negative least squares on the VPL powers against the
//! indirect images `I` of one or more views at once.
//!
//! Column `j` of `A` is the contribution of VPL `j` (with its current flux) to the covered pixels
//! of every view's strided grid (every `stride`-th pixel in x and y), RGB stacked, computed by the
//! evaluator's own shading term ([`crate::shade::shading`]) with its shadow ray: entry for entry the
//! evaluator's image before the sum over VPLs. `b` is `I` on the same rows. The refit solves
//!
//! `min_s ||A s - b||^2 + lambda ||s - g||^2  subject to  s >= 0`,
//!
//! one scale per VPL (its colour is kept), `lambda = ridge * trace(A^T A) / n`. With
//! [`RefitParams::group`] above 1 the scales are those of **power groups**: `s = M t`, `M` the
//! membership of groups of about that many neighbouring VPLs, so the problem above is solved
//! for `t` on the normal equations of `A M` (summed from `A`'s, [`project`]), penalty and
//! `lambda` unchanged: `lambda ||M t - g||^2` pulls each group with the weight of its VPLs.
//! (Groups of 8 were the default in stops 47-48. A ridge taken relative
//! to `A M`'s own trace instead pulled a group of 8 VPLs whose columns nearly coincide up to 8
//! times harder than the same ridge pulls its VPLs: on a 48 x 36 closed room whose
//! cross-validation picked the grid's largest ridge, the groups then kept the layout's 6 %
//! excess brightness where single VPLs shed it.) The pull toward
//! `g` keeps VPLs that no strided pixel sees at `g` times their power and makes the problem
//! strictly convex. `g` is 1 (the light-path powers) or, with [`RefitParams::free_gain`] and
//! where the cross-validation prefers it, the captures' **gain**: the luminance of the targets
//! over that of `A 1`, summed over the strided pixels. A layout's light-path powers are a
//! random estimate whose total is off by tens of percent on a few hundred VPLs (measured on
//! `skyroom_afternoon`, 256 VPLs: the captures' gain 0.82 to 1.25 over four frames), and the
//! captures measure that total well; pulling toward 1 made the ridge keep that error.
//!
//! **Surfaces no capture saw** ([`refit_with_coverage`]). The captures say nothing of the
//! light a VPL throws where none of them looks, and a scale fitted to the little of its light
//! they do see can make a hot spot there. The coverage views (ray-traced G-buffers of the
//! region around the cameras, no target read) add `sum_i u_i (s_i - g)^2` to the objective:
//! `u_i` is VPL `i`'s squared contribution summed over the coverage views' strided pixels that
//! no capture sees ([`View::sees`]), scaled so a coverage view weighs as one capture
//! ([`RefitParams::unseen_weight`] times). It is the error the scale would add there were the
//! pulled-toward powers right, counted VPL by VPL: no VPL's change is assumed to cancel its
//! neighbour's. (The full Gram matrix of the coverage views in its place let neighbours cancel,
//! one up and its neighbour off, and made hot spots where a camera came closer.) The
//! cross-validation chooses the ridge with this penalty in place.
//!
//! **A bound on the scales** ([`RefitParams::max_scale`], none by default). `s <= U` beside
//! `s >= 0`, `U` the bound times the larger of 1 and the pull `g`, solved in the refit (in the
//! cross-validation's refits too), not clipped after it: the light a bounded VPL cannot give
//! goes to the others where the captures ask for it. The add-on's job bounds the refit where it
//! fits coverage views rendered by Cycles (`vplace.job.REGION_MAX_SCALE`): those renders show
//! a room's corners brighter than VPLs can light them, and without the hold of traced coverage
//! views the refit scaled the VPLs beside them up to 3.9 times, each a hot spot on a wall a
//! camera saw from elsewhere.
//!
//! **Views of different brightness** ([`RefitParams::balance_views`]). Summed over the pixels
//! of every view, the squared error is that of the brightest view: Sponza's balcony view, lit
//! by bounce light alone at a third of the other captures' mean, was refitted to 0.87 of its
//! light while they came within 3 %. Each view's rows of `A` and `b` are weighted by
//! [`view_weights`]: the inverse of the view's mean target luminance (floored at
//! [`VIEW_WEIGHT_FLOOR`] of the views' mean), scaled so that the weighted targets hold the
//! energy the unweighted ones did. Each view's relative error then counts the same, as each
//! view's image counts the same to whoever looks at it. The weights read a frame's own targets:
//! [`refit_frames`] keeps one Gram matrix per distinct set of weights (frames whose lights
//! differ in where they are bright), so that each frame's result stays its own.
//!
//! **The ridge** is chosen by cross-validation, never by the fitted pixels alone (they always
//! prefer the smallest): the strided pixels fall in [`CV_FOLDS`] folds by blocks of
//! [`CV_BLOCK_PX`] pixels (a hash of the view and the block), each ridge of [`RIDGE_GRID`] is
//! refitted on all folds but one and scored on the one left out, and the ridge with the least
//! summed error is refitted on all pixels. With [`RefitParams::free_gain`] each ridge is tried
//! twice, pulling toward 1 and toward the gain of the folds it is refitted on; the gain is
//! taken only where its error is lower by more than [`GAIN_MARGIN`]. The error is that of the left-out cells' mean light
//! ([`CV_CELL_PX`] cells), not of single pixels: a capture's target is a few-sample render whose
//! per-pixel noise would otherwise decide between ridges whose predictions differ less than it.
//! Blocks, not single pixels, are left out, so the
//! validation asks what the written lights must do: light surfaces the refit did not see with
//! the layout's light-path powers, not interpolate between neighbouring pixels. With
//! [`LOVO_MIN_VIEWS`] or more views (and [`RefitParams::leave_out_views`]) the folds are the
//! views instead (at most [`LOVO_MAX_FOLDS`], view `v` in fold `v mod folds`): each ridge is
//! refitted on the other captures and scored on the one left out, which asks the same of a
//! whole view the refit never saw. Each fold keeps its own normal equations, so the selection
//! traces no extra ray: it costs `folds x grid` solves, and runs up to [`CV_MAX_VPLS`] VPLs.
//! `s = 1` is feasible and scores the error before the refit, so the refitted error is never
//! larger: if rounding ever made it so, the refit returns `s = 1`.
//!
//! **How.** `A` is never stored: the strided pixels are traced in blocks (rayon over chunks of
//! the block's pixels, each chunk with one traversal state for its shadow rays, as the
//! evaluator's tiles), and each block's rows are added to the Gram matrix `A^T A` (f64,
//! blocked GEMM, rayon over column panels of the upper triangle), to `A^T b` and `b^T b`. Memory is
//! `O(n^2 + block * n)`, the time one shadow ray per (pixel, VPL) pair plus `rows * n^2 / 2`
//! multiply-adds (`rows` = 3 x pixels). The errors come from the same quadratic form:
//! `||A s - b||^2 = s^T A^T A s - 2 s^T A^T b + b^T b`.
//!
//! **Frames** ([`refit_frames`]). `A` reads the VPLs, the receivers' G-buffers and the
//! occluders, never the lights: frames of an animation whose sun or lamp alone moves have the
//! same `A` and their own `b`. Their rows are traced once, with `A^T b`, `b^T b` and the cells'
//! target sums kept per frame; each frame is then cross-validated and solved on its own, so its
//! result is, bit for bit, the one it gets alone.
//!
//! **Solver.** Block principal pivoting (Kim and Park 2011) on the KKT conditions of the
//! regularized problem, a linear complementarity problem with the positive definite matrix
//! `A^T A + lambda I`: guess the free set, solve it exactly (Cholesky of the free block, the
//! variables at the upper bound moved to the right-hand side), swap every variable that breaks
//! a sign condition (a free one outside its bounds to that bound, a held one whose gradient
//! points inside to the free set); Murty's single-swap rule after three exchanges
//! that do not shrink the infeasible set guarantees termination without an upper bound (with
//! one, the fallback below stands behind it; the tests find the bounded optimum by pivoting
//! alone). It reaches the exact optimum,
//! usually in a handful of exchanges from the start "every VPL free" (refitted scales are mostly
//! positive), each `O(n^3 / 3)`. Lawson-Hanson (one variable per step, `n` steps) and projected
//! or coordinate descent (slow on the strongly correlated columns of nearby VPLs) were the
//! alternatives. Should the pivoting not settle in [`MAX_EXCHANGES`] exchanges, the clamped
//! iterate is polished by coordinate descent, which only lowers the objective.

use glam::Vec3;
use nalgebra::{Cholesky, DMatrix, DMatrixView, DMatrixViewMut, DVector};
use obvhs::ray::Ray;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Instant;

use crate::color::LUMINANCE_F64;
use crate::error::{Result, VplaceError};
use crate::layout::iterate::targets;
use crate::progress::Progress;
use crate::scene::{Scene, NO_HINT};
use crate::shade::evaluator::{check_radius, validate_vpls};
use crate::shade::shading::{Batch, Receiver, VplSoa};
use crate::view::{GBuffer, View};
use crate::vpl::{near_field_radii, Profile, Vpl};

/// Settings of the refit. `Copy`, with a default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefitParams {
    /// How VPLs radiate, as in the evaluator.
    pub profile: Profile,
    /// The set's near-field radius (metres), as in the evaluator (`EvalParams::radius`).
    pub radius: f32,
    /// Fit on every `stride`-th pixel in x and y (`>= 1`; 4 is quarter resolution).
    pub stride: usize,
    /// Weight of the pull toward scale 1, relative to the mean diagonal `trace(A^T A) / n`
    /// (`>= 0`). Values below [`MIN_RIDGE`] are raised to it, so the system stays definite.
    /// With [`RefitParams::select_ridge`], the ridge used where the selection does not run.
    pub ridge: f64,
    /// Choose the ridge among [`RIDGE_GRID`] by [`CV_FOLDS`]-fold cross-validation over blocks
    /// of pixels (see the module docs), for sets of at most [`CV_MAX_VPLS`] VPLs.
    pub select_ridge: bool,
    /// With [`LOVO_MIN_VIEWS`] or more views, cross-validate by leaving out whole views instead
    /// of blocks of pixels (see the module docs).
    pub leave_out_views: bool,
    /// VPLs per power group (`>= 1`): the refit scales groups of about this many neighbouring
    /// VPLs ([`power_groups`]), one scale per group; 1 (the default) gives every VPL its own
    /// scale.
    pub group: usize,
    /// Weight of the penalty from the coverage views' pixels that no captured view sees
    /// ([`refit_with_coverage`], the module docs' "Surfaces no capture saw"), per coverage view
    /// relative to one captured view (`>= 0`; 0 turns it off).
    pub unseen_weight: f64,
    /// Where the ridge is cross-validated, also try pulling the scales toward the captures'
    /// gain instead of 1 (see the module docs); without the selection the pull is toward 1.
    pub free_gain: bool,
    /// Weigh each view's rows by the inverse of its light ([`view_weights`], the module docs'
    /// "Views of different brightness"), so that a dim view's relative error counts as a
    /// bright one's; without, every pixel's absolute error counts the same.
    pub balance_views: bool,
    /// The largest scale, times the larger of 1 and what the scales are pulled toward (the
    /// captures' gain where it is taken): a bound solved in the refit, as `s >= 0` is
    /// (`>= 1`, so `s = 1` stays feasible; infinite: no bound). See the module docs' "A bound
    /// on the scales".
    pub max_scale: f64,
}

impl RefitParams {
    /// Cosine profile, 1 cm radius, quarter resolution, the ridge chosen by cross-validation
    /// (`0.1` above [`CV_MAX_VPLS`] VPLs).
    pub const DEFAULT: Self = Self {
        profile: Profile::Cosine,
        radius: 0.01,
        stride: 4,
        ridge: 0.1,
        select_ridge: true,
        leave_out_views: true,
        free_gain: true,
        group: REFIT_GROUP,
        unseen_weight: UNSEEN_WEIGHT,
        balance_views: true,
        max_scale: f64::INFINITY,
    };
}

impl Default for RefitParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// VPLs per power group by default ([`RefitParams::group`]): one scale per VPL. Groups of 8
/// (stops 47-48) held the rooms' VPLs that light surfaces no capture saw, but cost Sponza,
/// whose captures pin each VPL down, .002-.009 SSIM; the coverage views' penalty
/// ([`UNSEEN_WEIGHT`]) holds those VPLs one by one, and one scale per VPL with it scored
/// higher than groups with it on every view of the built-in scenes (ARCHITECTURE.md, "The
/// refit's power groups").
pub const REFIT_GROUP: usize = 1;

/// The coverage views' penalty by default ([`RefitParams::unseen_weight`]): a coverage view
/// counts as one captured view. 4 measured within .0015 SSIM of 1 on every view of the sky
/// room and Sponza (8 seeds).
pub const UNSEEN_WEIGHT: f64 = 1.0;

/// The dimmest a view counts as in [`view_weights`], relative to the views' mean light: a view
/// ten times darker than the mean weighs as one that is exactly ten times darker, a black view
/// no more.
pub const VIEW_WEIGHT_FLOOR: f64 = 0.1;

/// Rounds of Lloyd's k-means in [`power_groups`].
pub const GROUP_ROUNDS: usize = 16;

/// Weight of the normal against the position in [`power_groups`], times the diagonal of the
/// VPLs' bounding box: VPLs whose normals differ by 90 degrees are as far apart as positions
/// 0.14 diagonals apart.
pub const GROUP_NORMAL_WEIGHT: f32 = 0.1;

/// The smallest relative ridge used: keeps the Gram matrix definite when columns coincide.
pub const MIN_RIDGE: f64 = 1e-9;

/// The ridges the cross-validation tries (relative, as [`RefitParams::ridge`]): from a refit
/// that follows the pixels to one that barely leaves the layout's powers.
pub const RIDGE_GRID: [f64; 5] = [0.01, 0.1, 1.0, 10.0, 100.0];

/// The pull toward the captures' gain is taken where its validation RMSE is below this
/// fraction less than the pull toward 1's (each at its best ridge). Between two pulls that
/// predict equally well the validation's own noise decides: on the Cornell box, where the
/// light-path totals are right, the two differed by -0.3 % to +0.5 % (seeds 0-2, one and three
/// captures), and taking the gain on such a draw lowered the demo's SSIM by .002; on Sponza,
/// whose light-path totals hold half the captures' light, the gain's error was 8 to 25 % lower.
pub const GAIN_MARGIN: f64 = 0.02;

/// Folds of the ridge's cross-validation.
pub const CV_FOLDS: usize = 4;

/// The fewest views whose cross-validation leaves out whole views
/// ([`RefitParams::leave_out_views`]): with two, each ridge would be judged on one view alone.
pub const LOVO_MIN_VIEWS: usize = 3;

/// The most folds of a leave-one-view-out validation (each keeps an `n x n` Gram matrix).
pub const LOVO_MAX_FOLDS: usize = 8;

/// Side of the square blocks of pixels (full-resolution pixels) that go to one fold.
pub const CV_BLOCK_PX: usize = 32;

/// Side of the cells (full-resolution pixels, inside the blocks) whose mean light the
/// cross-validation compares: the regression's cell size.
pub const CV_CELL_PX: usize = 16;

/// The most VPLs for which the ridge is cross-validated: the folds keep one `n x n` Gram matrix
/// each and one for the sum of the others (2 x 4 x 8 MB at 1,024 with block folds), and each
/// fold, ridge and pull is a solve.
pub const CV_MAX_VPLS: usize = 1024;

/// At most this many block exchanges before the solver falls back to coordinate descent.
pub const MAX_EXCHANGES: usize = 64;

/// The most VPLs one refit takes: its `n x n` matrices (three of them at once, f64) stay below
/// about 1.6 GB.
pub const MAX_VPLS: usize = 8192;

/// The result of [`refit`].
#[derive(Debug, Clone, PartialEq)]
pub struct Refitted {
    /// The VPLs with their flux scaled (positions and normals unchanged).
    pub vpls: Vec<Vpl>,
    /// The scale of each VPL's flux, `>= 0`.
    pub scales: Vec<f64>,
    /// RMSE (RGB, linear) of `A s - b` over the covered strided pixels with `s = 1`, each
    /// view's rows weighted by [`Refitted::view_weights`].
    pub error_before: f64,
    /// The same with the refitted scales; never above `error_before`.
    pub error_after: f64,
    /// Covered pixels on the strided grid (the rows of `A` are three times as many).
    pub pixels: usize,
    /// Shadow rays traced (pixel-VPL pairs with a non-zero unshadowed contribution).
    pub shadow_rays: u64,
    /// Block exchanges the solver made (0 when the unconstrained optimum was non-negative).
    pub exchanges: usize,
    /// The ridge used (relative, as [`RefitParams::ridge`]).
    pub ridge: f64,
    /// The cross-validation: each ridge of [`RIDGE_GRID`] with its RMSE on the held-out folds
    /// (empty where the ridge was not selected), pulling toward 1.
    pub cv: Vec<(f64, f64)>,
    /// The same pulling toward the gain (empty without [`RefitParams::free_gain`]).
    pub gain_cv: Vec<(f64, f64)>,
    /// What the scales were pulled toward: 1, or the captures' gain (see the module docs).
    pub gain: f64,
    /// Power groups the scales were fitted for (one scale each; `n` with group 1).
    pub groups: usize,
    /// Strided pixels of the coverage views that no captured view sees: where the penalty of
    /// [`refit_with_coverage`] comes from (0 without coverage views).
    pub unseen_pixels: usize,
    /// The weight of each view's rows ([`view_weights`]; all 1 without
    /// [`RefitParams::balance_views`] or with one view). The errors above are of the weighted
    /// rows.
    pub view_weights: Vec<f64>,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// The normal equations of the strided problem: `A^T A` (column-major `n x n`, upper triangle
/// filled, then mirrored), `A^T b`, `b^T b`.
#[derive(Clone)]
struct Normal {
    gram: Vec<f64>,
    atb: Vec<f64>,
    btb: f64,
    rays: u64,
    /// Per VPL, the luminance of its column of `A` summed over the rows; and of `b`.
    lum_a: Vec<f64>,
    lum_b: f64,
    /// The trace of the VPLs' own Gram matrix (before [`project`]): the ridge's scale.
    vpl_trace: f64,
    /// Per scale, the VPLs it multiplies (1 each, or a power group's size): the ridge's weight,
    /// so that a group's pull is its VPLs' pulls summed.
    size: Vec<f64>,
    /// Per scale, the weight of its pull from the surfaces no capture saw ([`unseen_weights`];
    /// a group's is its VPLs' summed): the same in every fold.
    unseen: Vec<f64>,
    /// With cross-validation: per cell of [`CV_CELL_PX`] pixels (view, cell x, cell y), the
    /// sums of its pixels' rows (R, G, B: `3 n`), of their targets, and the pixel count.
    cells: BTreeMap<(usize, usize, usize), Cell>,
}

/// One cell's sums (see [`Normal::cells`]).
#[derive(Clone)]
struct Cell {
    a: Vec<f64>,
    b: [f64; 3],
    pixels: usize,
}

/// Columns of the Gram matrix one task updates.
const PANEL: usize = 32;

/// Pixels one rayon task traces, with one traversal state and one shading batch.
const PIXELS_PER_TASK: usize = 16;

/// Fills the three rows of `A` of receiver `recv` (`rows`: R, G then B, `n` values each, `n`
/// the VPLs of `soa`): `brdf * Phi_j * scale_j` where VPL `j`'s shadow ray is not blocked, 0
/// elsewhere. `occluded` answers VPL `j`'s shadow ray. Returns the rays traced.
fn pixel_rows(
    recv: &Receiver,
    soa: &VplSoa,
    profile: Profile,
    batch: &mut Batch,
    mut occluded: impl FnMut(&Ray, usize) -> bool,
    rows: &mut [f64],
) -> u64 {
    let n = soa.len();
    rows.fill(0.0);
    let (red, rest) = rows.split_at_mut(n);
    let (green, blue) = rest.split_at_mut(n);
    batch.prepare(soa, recv, profile);
    let mut rays = 0u64;
    for (j, c) in batch.unshadowed(soa) {
        rays += 1;
        let lit = !batch.occluded(j, |ray| occluded(ray, j));
        let a = recv.brdf * if lit { c } else { Vec3::ZERO };
        red[j] = f64::from(a.x);
        green[j] = f64::from(a.y);
        blue[j] = f64::from(a.z);
    }
    rays
}

impl Normal {
    fn zero(n: usize) -> Self {
        Self {
            gram: vec![0.0; n * n],
            atb: vec![0.0; n],
            btb: 0.0,
            rays: 0,
            lum_a: vec![0.0; n],
            lum_b: 0.0,
            vpl_trace: 0.0,
            size: vec![1.0; n],
            unseen: vec![0.0; n],
            cells: BTreeMap::new(),
        }
    }

    /// The squared error of the cells' mean light, summed over cells and channels: how far the
    /// refitted VPLs put each cell's light level from its target's (the pixels' noise averages
    /// out in a cell).
    fn cell_error(&self, s: &[f64]) -> f64 {
        let n = s.len();
        self.cells
            .values()
            .map(|cell| {
                (0..3)
                    .map(|c| {
                        let a = &cell.a[c * n..(c + 1) * n];
                        let got: f64 = a.iter().zip(s).map(|(x, y)| x * y).sum();
                        ((got - cell.b[c]) / cell.pixels as f64).powi(2)
                    })
                    .sum::<f64>()
            })
            .sum()
    }

    /// The captures' gain: the targets' luminance over that of `A 1`; 1 where either is not
    /// positive or the ratio is not finite.
    fn gain(&self) -> f64 {
        let lit: f64 = self.lum_a.iter().sum();
        let g = self.lum_b / lit;
        if lit > 0.0 && self.lum_b > 0.0 && g.is_finite() {
            g
        } else {
            1.0
        }
    }

    /// `||A s - b||^2` from the normal equations, clamped at 0 against rounding (NaN stays).
    fn sq_error(&self, s: &[f64]) -> f64 {
        let dot: f64 = s.iter().zip(&self.atb).map(|(a, b)| a * b).sum();
        let e = quadratic(&self.gram, s) - 2.0 * dot + self.btb;
        if e < 0.0 {
            0.0
        } else {
            e
        }
    }
}

/// The normal equations of each group of strided pixels (`groups`: the folds; with more than
/// one, each keeps its cells' sums too), traced block by block, per group one per target
/// (`targets[t][v]`: target `t`'s indirect image of view `v`, all read on the G-buffers
/// `gbuffers`): the rows of `A` are traced once for every target. The progress counts the
/// blocks of all groups and one step per target for the solve. `soa`: the VPLs with their
/// near-field radii.
#[allow(clippy::too_many_arguments)]
fn normal_equations(
    scene: &Scene,
    gbuffers: &[GBuffer<'_>],
    targets: &[Vec<&[f32]>],
    weights: &[Vec<f64>],
    soa: &VplSoa,
    groups: &[Vec<(usize, usize)>],
    params: &RefitParams,
    progress: Option<&Progress>,
) -> Result<Vec<Vec<Normal>>> {
    let n = soa.len();
    // About 24 MB of rows per block (3 rows of n f64 per pixel), 128..1024 pixels.
    let block = ((1usize << 20) / n).clamp(128, 1024);
    let blocks: usize = groups.iter().map(|g| g.len().div_ceil(block)).sum();
    if let Some(p) = progress {
        p.total.store(blocks + targets.len(), Ordering::Relaxed);
        p.done.store(0, Ordering::Relaxed);
    }
    let mut rows = vec![0.0f64; 3 * block * n];
    // A second block of rows where targets weigh their views differently (see [`Classes`]).
    let classes = Classes::of(weights);
    let mut spare = vec![
        0.0f64;
        if classes.weights.len() > 1 {
            3 * block * n
        } else {
            0
        }
    ];
    groups
        .iter()
        .map(|pixels| {
            let cells = groups.len() > 1;
            let buffers = (&mut rows[..], &mut spare[..]);
            group_equations(
                scene, gbuffers, targets, &classes, soa, pixels, block, buffers, params, cells,
                progress,
            )
        })
        .collect()
}

/// The targets grouped by their views' weights ([`view_weights`]): targets whose weights are
/// the same, bit for bit, share one class and its weighted rows of `A` (one Gram matrix).
struct Classes {
    /// Each class's per-view weights.
    weights: Vec<Vec<f64>>,
    /// Each target's class.
    of_target: Vec<usize>,
}

impl Classes {
    fn of(per_target: &[Vec<f64>]) -> Self {
        let mut weights: Vec<Vec<f64>> = Vec::new();
        let of_target = per_target
            .iter()
            .map(|w| {
                let same = |c: &Vec<f64>| c.iter().zip(w).all(|(a, b)| a.to_bits() == b.to_bits());
                weights.iter().position(same).unwrap_or_else(|| {
                    weights.push(w.clone());
                    weights.len() - 1
                })
            })
            .collect();
        Self { weights, of_target }
    }
}

/// Per view of `gbuffers`, the weight of its rows of `A` and `b` in the refit against `target`
/// (its indirect images): the inverse of the view's mean target luminance over its covered
/// pixels, floored at [`VIEW_WEIGHT_FLOOR`] times the views' mean (over their covered pixels),
/// scaled so that the weighted targets' energy `sum_v N_v (w_v m_v)^2` is the unweighted
/// `sum_v N_v m_v^2`. All 1 without `balance`, with one view, where the views are equally
/// bright, or where they hold no light.
pub fn view_weights(gbuffers: &[GBuffer<'_>], target: &[&[f32]], balance: bool) -> Vec<f64> {
    let ones = vec![1.0; gbuffers.len()];
    if !balance || gbuffers.len() < 2 {
        return ones;
    }
    let (count, mean): (Vec<f64>, Vec<f64>) = gbuffers
        .iter()
        .zip(target)
        .map(|(g, image)| {
            let (mut sum, mut k) = (0.0f64, 0usize);
            for (p, _) in g.covered.iter().enumerate().filter(|(_, &c)| c) {
                sum += (0..3)
                    .map(|c| LUMINANCE_F64[c] * f64::from(image[3 * p + c]))
                    .sum::<f64>();
                k += 1;
            }
            (k as f64, if k > 0 { sum / k as f64 } else { 0.0 })
        })
        .unzip();
    let total: f64 = count.iter().sum();
    let avg = count.iter().zip(&mean).map(|(n, m)| n * m).sum::<f64>() / total;
    if !(avg > 0.0 && avg.is_finite()) {
        return ones;
    }
    let raw: Vec<f64> = mean
        .iter()
        .map(|&m| 1.0 / m.max(VIEW_WEIGHT_FLOOR * avg))
        .collect();
    if raw.iter().all(|&w| w == raw[0]) {
        return ones; // views of one brightness: nothing to balance, exactly
    }
    let energy = |w: &[f64]| -> f64 {
        (0..mean.len())
            .map(|v| count[v] * (w[v] * mean[v]).powi(2))
            .sum()
    };
    let (before, after) = (energy(&ones), energy(&raw));
    let scale = (before / after).sqrt();
    if !(scale > 0.0 && scale.is_finite()) {
        return ones;
    }
    raw.iter().map(|w| w * scale).collect()
}

/// One target's sums in [`group_equations`]: what of [`Normal`] reads `b`.
struct TargetSums {
    atb: Vec<f64>,
    btb: f64,
    lum_b: f64,
    cells: BTreeMap<(usize, usize, usize), [f64; 3]>,
}

/// The normal equations of `pixels` for each target, traced `block` pixels at a time into the
/// first of `buffers`: `A^T A` once per class of `classes` (its views' rows weighted), `A^T b`
/// and `b^T b` per target. The second buffer holds the weighted rows of every class but the
/// last (which weighs the traced rows in place): empty with one class.
#[allow(clippy::too_many_arguments)]
fn group_equations(
    scene: &Scene,
    gbuffers: &[GBuffer<'_>],
    targets: &[Vec<&[f32]>],
    classes: &Classes,
    soa: &VplSoa,
    pixels: &[(usize, usize)],
    block: usize,
    buffers: (&mut [f64], &mut [f64]),
    params: &RefitParams,
    cells: bool,
    progress: Option<&Progress>,
) -> Result<Vec<Normal>> {
    let n = soa.len();
    let cancelled = || progress.is_some_and(|p| p.cancel.load(Ordering::Relaxed));
    let eps = scene.ray_epsilon();
    let (traced_rows, spare) = buffers;
    let mut outs: Vec<Normal> = classes.weights.iter().map(|_| Normal::zero(n)).collect();
    let mut sums: Vec<TargetSums> = targets
        .iter()
        .map(|_| TargetSums {
            atb: vec![0.0; n],
            btb: 0.0,
            lum_b: 0.0,
            cells: BTreeMap::new(),
        })
        .collect();
    for chunk in pixels.chunks(block) {
        if cancelled() {
            return Err(VplaceError::Cancelled);
        }
        let r = 3 * chunk.len();
        let rows = &mut traced_rows[..r * n];
        // Rows 3k..3k+3 are pixel k's R, G and B: every VPL's shaded contribution.
        let rays = rows
            .par_chunks_mut(3 * n * PIXELS_PER_TASK)
            .zip(chunk.par_chunks(PIXELS_PER_TASK))
            .map(|(task_rows, task_pixels)| {
                let mut state = scene.shadow_state();
                let mut batch = Batch::new(n);
                // Per VPL, the triangle that last blocked its ray in this task's pixels.
                let mut hints = vec![NO_HINT; n];
                task_rows
                    .chunks_mut(3 * n)
                    .zip(task_pixels)
                    .map(|(px_rows, &(v, p))| {
                        let recv = Receiver::of_pixel(&gbuffers[v], p, eps);
                        let occluded = |ray: &_, j: usize| {
                            scene.occluded_ray_hinted(&mut state, ray, &mut hints[j])
                        };
                        pixel_rows(&recv, soa, params.profile, &mut batch, occluded, px_rows)
                    })
                    .sum::<u64>()
            })
            .sum::<u64>();
        let last = classes.weights.len() - 1;
        for (class, (weights, out)) in classes.weights.iter().zip(&mut outs).enumerate() {
            out.rays += rays;
            // The class's rows: the traced ones times their view's weight (the last class
            // weighs them in place, the others a copy; rows of weight 1 stay as traced).
            let rows: &[f64] = if weights.iter().all(|&w| w == 1.0) {
                rows
            } else {
                let dst: &mut [f64] = if class == last {
                    rows
                } else {
                    let dst = &mut spare[..r * n];
                    dst.copy_from_slice(rows);
                    dst
                };
                for (k, &(v, _)) in chunk.iter().enumerate() {
                    let w = weights[v];
                    if w != 1.0 {
                        dst[3 * k * n..3 * (k + 1) * n]
                            .iter_mut()
                            .for_each(|x| *x *= w);
                    }
                }
                dst
            };
            for (k, &(v, p)) in chunk.iter().enumerate() {
                let w = gbuffers[v].width;
                let key = (v, (p % w) / CV_CELL_PX, (p / w) / CV_CELL_PX);
                let mut cell = cells.then(|| {
                    out.cells.entry(key).or_insert_with(|| Cell {
                        a: vec![0.0; 3 * n],
                        b: [0.0; 3],
                        pixels: 0,
                    })
                });
                if let Some(cell) = cell.as_mut() {
                    cell.pixels += 1;
                }
                for (c, &y) in LUMINANCE_F64.iter().enumerate() {
                    let row = &rows[(3 * k + c) * n..(3 * k + c + 1) * n];
                    for (lum, &a) in out.lum_a.iter_mut().zip(row) {
                        *lum += y * a;
                    }
                    if let Some(cell) = cell.as_mut() {
                        let sums = &mut cell.a[c * n..(c + 1) * n];
                        sums.iter_mut().zip(row).for_each(|(acc, &a)| *acc += a);
                    }
                    let in_class = sums.iter_mut().zip(targets).zip(&classes.of_target);
                    for ((t, target), _) in in_class.filter(|(_, &k)| k == class) {
                        let b = f64::from(target[v][3 * p + c]) * weights[v];
                        t.btb += b * b;
                        t.lum_b += y * b;
                        t.atb
                            .iter_mut()
                            .zip(row)
                            .for_each(|(acc, &a)| *acc += a * b);
                        if cells {
                            t.cells.entry(key).or_insert([0.0; 3])[c] += b;
                        }
                    }
                }
            }
            // The block's rows are row-major `r x n`: read as column-major they are `A_blk^T`.
            let at = DMatrixView::from_slice_with_strides(rows, n, r, 1, n);
            let a = DMatrixView::from_slice_with_strides(rows, r, n, n, 1);
            out.gram
                .par_chunks_mut(PANEL * n)
                .enumerate()
                .for_each(|(k, panel)| {
                    let j0 = k * PANEL;
                    let cols = panel.len() / n;
                    let j1 = j0 + cols;
                    // Rows 0..j1 of columns j0..j1: the upper triangle and the diagonal block.
                    let mut g = DMatrixViewMut::from_slice_with_strides_mut(panel, j1, cols, 1, n);
                    g.gemm(1.0, &at.rows(0, j1), &a.columns(j0, cols), 1.0);
                });
        }
        if let Some(p) = progress {
            p.done.fetch_add(1, Ordering::Relaxed);
        }
    }
    for out in &mut outs {
        for j in 0..n {
            for i in j + 1..n {
                out.gram[j * n + i] = out.gram[i * n + j];
            }
        }
        out.vpl_trace = (0..n).map(|i| out.gram[i * n + i]).sum();
    }
    // One copy of its class's sums per target, with that target's own (the class's last
    // target takes them).
    let mut per_target = Vec::with_capacity(sums.len());
    for (t, target) in sums.into_iter().enumerate() {
        let class = classes.of_target[t];
        let later = classes.of_target[t + 1..].contains(&class);
        let mut ne = if later {
            outs[class].clone()
        } else {
            std::mem::replace(&mut outs[class], Normal::zero(0))
        };
        ne.atb = target.atb;
        ne.btb = target.btb;
        ne.lum_b = target.lum_b;
        for (key, cell) in &mut ne.cells {
            cell.b = target.cells.get(key).copied().unwrap_or([0.0; 3]);
        }
        per_target.push(ne);
    }
    Ok(per_target)
}

/// `s^T Q s` for the column-major `n x n` matrix `q`.
fn quadratic(q: &[f64], s: &[f64]) -> f64 {
    let n = s.len();
    (0..n)
        .map(|j| s[j] * (0..n).map(|i| q[j * n + i] * s[i]).sum::<f64>())
        .sum()
}

/// What the solver returns: the minimizer and how many block exchanges it took.
struct Solved {
    s: Vec<f64>,
    exchanges: usize,
}

/// Where a variable of [`nnls_bpp`] stands: free, or held at its lower (0) or upper bound.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    Free,
    Lower,
    Upper,
}

/// Minimizes `1/2 s^T Q s - c^T s` over `0 <= s <= upper` for positive definite `Q`
/// (column-major) by block principal pivoting, with a coordinate-descent fallback (see the
/// module docs); `upper` may be infinite (no upper bound). `full`: the Cholesky factor of all
/// of `Q`, when the caller has it (the first step, every variable free, then factors nothing).
fn nnls_bpp(
    q: &[f64],
    c: &[f64],
    upper: f64,
    full: Option<&Cholesky<f64, nalgebra::Dyn>>,
    max_exchanges: usize,
    cancelled: &dyn Fn() -> bool,
) -> Result<Solved> {
    let n = c.len();
    let diag: Vec<f64> = (0..n).map(|i| q[i * n + i]).collect();
    // Sign tests with a little slack, so rounding cannot make the pivoting cycle.
    let tol_x = 1e-12;
    let tol_y: Vec<f64> = (0..n).map(|i| 1e-12 * (c[i].abs() + diag[i])).collect();
    let mut side = vec![Side::Free; n];
    let mut x = vec![0.0f64; n];
    let (mut best_infeasible, mut tries) = (n + 1, 3usize);
    let mut exchanges = 0;
    loop {
        if cancelled() {
            return Err(VplaceError::Cancelled);
        }
        let f: Vec<usize> = (0..n).filter(|&i| side[i] == Side::Free).collect();
        let at_upper: Vec<usize> = (0..n).filter(|&i| side[i] == Side::Upper).collect();
        for i in 0..n {
            x[i] = if side[i] == Side::Upper { upper } else { 0.0 };
        }
        if !f.is_empty() {
            // Q_ff x_f = c_f - Q_fu upper.
            let rhs = DVector::from_iterator(
                f.len(),
                f.iter()
                    .map(|&i| c[i] - at_upper.iter().map(|&k| q[k * n + i] * upper).sum::<f64>()),
            );
            let xf = match full {
                Some(chol) if f.len() == n => chol.solve(&rhs),
                _ => {
                    let qff = DMatrix::from_fn(f.len(), f.len(), |a, b| q[f[b] * n + f[a]]);
                    let Some(chol) = Cholesky::new(qff) else {
                        break; // Not definite in floating point: polish below.
                    };
                    chol.solve(&rhs)
                }
            };
            for (k, &i) in f.iter().enumerate() {
                x[i] = xf[k];
            }
        }
        // y = Q x - c on the bound set; the infeasible variables: a free one outside its
        // bounds, a held one whose gradient pulls it inside.
        let infeasible: Vec<(usize, Side)> = (0..n)
            .filter_map(|i| {
                let y = || {
                    (f.iter().chain(&at_upper))
                        .map(|&k| q[k * n + i] * x[k])
                        .sum::<f64>()
                        - c[i]
                };
                match side[i] {
                    Side::Free if x[i] < -tol_x => Some((i, Side::Lower)),
                    Side::Free if x[i] > upper * (1.0 + tol_x) => Some((i, Side::Upper)),
                    Side::Lower if y() < -tol_y[i] => Some((i, Side::Free)),
                    Side::Upper if y() > tol_y[i] => Some((i, Side::Free)),
                    _ => None,
                }
            })
            .collect();
        if infeasible.is_empty() {
            x.iter_mut().for_each(|v| *v = v.clamp(0.0, upper));
            return Ok(Solved { s: x, exchanges });
        }
        if exchanges == max_exchanges {
            break;
        }
        exchanges += 1;
        if infeasible.len() < best_infeasible {
            best_infeasible = infeasible.len();
            tries = 3;
            infeasible.iter().for_each(|&(i, to)| side[i] = to);
        } else if tries > 0 {
            tries -= 1;
            infeasible.iter().for_each(|&(i, to)| side[i] = to);
        } else {
            let (i, to) = *infeasible.last().expect("not empty");
            side[i] = to;
        }
    }
    // Fallback: coordinate descent from the clamped iterate; every step lowers the objective.
    x.iter_mut().for_each(|v| *v = v.clamp(0.0, upper));
    let mut grad: Vec<f64> = (0..n)
        .map(|i| (0..n).map(|k| q[k * n + i] * x[k]).sum::<f64>() - c[i])
        .collect();
    for _ in 0..200 {
        if cancelled() {
            return Err(VplaceError::Cancelled);
        }
        let mut moved = 0.0f64;
        for i in 0..n {
            if diag[i] <= 0.0 {
                continue;
            }
            let new = (x[i] - grad[i] / diag[i]).clamp(0.0, upper);
            let d = new - x[i];
            if d != 0.0 {
                x[i] = new;
                let col = &q[i * n..(i + 1) * n];
                grad.iter_mut().zip(col).for_each(|(g, &qi)| *g += qi * d);
                moved = moved.max(d.abs());
            }
        }
        if moved < 1e-10 {
            break;
        }
    }
    Ok(Solved { s: x, exchanges })
}

/// The fold of block `(bx, by)` of view `v`: a hash of the block, so neighbouring blocks fall
/// in different folds and every fold spreads over the image.
fn fold_of(v: usize, bx: usize, by: usize, folds: usize) -> usize {
    let mut h = (v as u64) << 42 ^ (by as u64) << 21 ^ bx as u64;
    // splitmix64's finalizer.
    h ^= h >> 30;
    h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 27;
    h = h.wrapping_mul(0x94d4_049b_b133_111e);
    h ^= h >> 31;
    (h % folds as u64) as usize
}

/// `acc += part` (Gram matrix, `A^T b`, `b^T b`, rays).
fn add_to(acc: &mut Normal, part: &Normal) {
    acc.gram
        .iter_mut()
        .zip(&part.gram)
        .for_each(|(a, b)| *a += b);
    acc.atb.iter_mut().zip(&part.atb).for_each(|(a, b)| *a += b);
    acc.btb += part.btb;
    acc.lum_a
        .iter_mut()
        .zip(&part.lum_a)
        .for_each(|(a, b)| *a += b);
    acc.lum_b += part.lum_b;
    acc.rays += part.rays;
    acc.vpl_trace += part.vpl_trace;
    acc.size.clone_from(&part.size);
    acc.unseen.clone_from(&part.unseen);
}

/// Groups of about `per` neighbouring VPLs: k-means (`k = ceil(n / per)`, [`GROUP_ROUNDS`]
/// rounds of Lloyd's) on the position and the normal, the normal weighted by
/// [`GROUP_NORMAL_WEIGHT`] times the diagonal of the VPLs' bounding box, so that a floor's and a
/// wall's VPLs by one corner fall apart. Seeded by farthest points from VPL 0: deterministic.
/// Returns each VPL's group and the number of groups (none empty).
fn power_groups(vpls: &[Vpl], per: usize) -> (Vec<usize>, usize) {
    let n = vpls.len();
    let k = n.div_ceil(per.max(1)).max(1);
    let (lo, hi) = vpls.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), v| (a.min(v.position), b.max(v.position)),
    );
    let w = GROUP_NORMAL_WEIGHT * (hi - lo).length();
    let points: Vec<(Vec3, Vec3)> = vpls.iter().map(|v| (v.position, v.normal * w)).collect();
    let d2 = |a: &(Vec3, Vec3), b: &(Vec3, Vec3)| {
        f64::from((a.0 - b.0).length_squared()) + f64::from((a.1 - b.1).length_squared())
    };
    let mut centres = vec![points[0]];
    let mut nearest: Vec<f64> = points.iter().map(|p| d2(p, &points[0])).collect();
    while centres.len() < k {
        let far = (0..n)
            .max_by(|&i, &j| nearest[i].total_cmp(&nearest[j]).then(j.cmp(&i)))
            .unwrap_or(0);
        if nearest[far] <= 0.0 {
            break; // every VPL coincides with a centre
        }
        centres.push(points[far]);
        for (d, p) in nearest.iter_mut().zip(&points) {
            *d = d.min(d2(p, &points[far]));
        }
    }
    let k = centres.len();
    let mut member = vec![0usize; n];
    for _ in 0..GROUP_ROUNDS {
        member = points
            .par_iter()
            .map(|p| {
                (0..k)
                    .min_by(|&a, &b| d2(p, &centres[a]).total_cmp(&d2(p, &centres[b])))
                    .unwrap_or(0)
            })
            .collect();
        let mut sum = vec![(Vec3::ZERO, Vec3::ZERO, 0usize); k];
        for (p, &m) in points.iter().zip(&member) {
            sum[m].0 += p.0;
            sum[m].1 += p.1;
            sum[m].2 += 1;
        }
        for (c, s) in centres.iter_mut().zip(&sum) {
            if s.2 > 0 {
                *c = (s.0 / s.2 as f32, s.1 / s.2 as f32);
            }
        }
    }
    // Numbered in order of first appearance; a centre no VPL chose is dropped.
    let mut map = vec![usize::MAX; k];
    let mut next = 0;
    for m in &mut member {
        if map[*m] == usize::MAX {
            map[*m] = next;
            next += 1;
        }
        *m = map[*m];
    }
    (member, next)
}

/// The normal equations of the groups' scales: those of `A M` (`M` the `n x k` membership of
/// `member`), from `ne`'s own sums without tracing again.
fn project(ne: &Normal, member: &[usize], k: usize) -> Normal {
    let n = member.len();
    let mut out = Normal::zero(k);
    for j in 0..n {
        for i in 0..n {
            out.gram[member[j] * k + member[i]] += ne.gram[j * n + i];
        }
        out.atb[member[j]] += ne.atb[j];
        out.lum_a[member[j]] += ne.lum_a[j];
    }
    out.btb = ne.btb;
    out.lum_b = ne.lum_b;
    out.rays = ne.rays;
    out.vpl_trace = ne.vpl_trace;
    out.size = vec![0.0; k];
    out.unseen = vec![0.0; k];
    for (&m, &u) in member.iter().zip(&ne.unseen) {
        out.size[m] += 1.0;
        out.unseen[m] += u;
    }
    for (key, cell) in &ne.cells {
        let mut a = vec![0.0; 3 * k];
        for c in 0..3 {
            for j in 0..n {
                a[c * k + member[j]] += cell.a[c * n + j];
            }
        }
        let cell = Cell {
            a,
            b: cell.b,
            pixels: cell.pixels,
        };
        out.cells.insert(*key, cell);
    }
    out
}

/// The refitted scales of the normal equations `ne` with relative ridge `ridge`
/// (`lambda = ridge * trace / n` of the VPLs' own Gram matrix, each scale's pull weighted by
/// the VPLs it multiplies: the per-VPL penalty `lambda ||M t - g||^2` of the module docs, plus
/// the unseen surfaces' weights `u`: `sum_i u_i (s_i - g)^2`), one solution per pull of `pulls`
/// (what the scales are pulled toward), each bounded above by `max_scale` times the larger of
/// its pull and 1 ([`RefitParams::max_scale`]); all 1 where the trace is 0 (no pixel sees a
/// VPL). The pulls share `Q` and its factor: a second pull costs no factorization where its
/// solution keeps every VPL free.
fn solve(
    ne: &Normal,
    ridge: f64,
    pulls: &[f64],
    max_scale: f64,
    cancelled: &dyn Fn() -> bool,
) -> Result<Vec<Solved>> {
    let n = ne.atb.len();
    let trace = ne.vpl_trace;
    if trace <= 0.0 {
        let ones = || Solved {
            s: vec![1.0; n],
            exchanges: 0,
        };
        return Ok(pulls.iter().map(|_| ones()).collect());
    }
    let vpls: f64 = ne.size.iter().sum();
    let lambda = ridge.max(MIN_RIDGE) * trace / vpls;
    let mut q = ne.gram.clone();
    let weight: Vec<f64> = (ne.size.iter().zip(&ne.unseen))
        .map(|(&size, &u)| lambda * size + u)
        .collect();
    for (i, w) in weight.iter().enumerate() {
        q[i * n + i] += w;
    }
    let full = if pulls.len() > 1 {
        Cholesky::new(DMatrix::from_column_slice(n, n, &q))
    } else {
        None
    };
    pulls
        .iter()
        .map(|&pull| {
            let c: Vec<f64> = (ne.atb.iter().zip(&weight))
                .map(|(&v, &w)| v + w * pull)
                .collect();
            let upper = max_scale * pull.max(1.0);
            nnls_bpp(&q, &c, upper, full.as_ref(), MAX_EXCHANGES, cancelled)
        })
        .collect()
}

/// The covered pixels of every `stride`-th row and column of each view: `(view, pixel)`.
fn strided_pixels(views: &[&View], stride: usize) -> Vec<(usize, usize)> {
    views
        .iter()
        .enumerate()
        .flat_map(|(v, view)| {
            let w = view.width;
            (0..view.height)
                .step_by(stride)
                .flat_map(move |y| (0..w).step_by(stride).map(move |x| (v, y * w + x)))
                .filter(|&(_, p)| view.covered[p])
        })
        .collect()
}

/// The weight of each VPL's pull from the surfaces no capture saw, and how many strided pixels
/// of `coverage` show them: per VPL, `unseen_weight * k * sum_p ||a_p||^2` over the covered
/// strided pixels `p` of the coverage views that no view of `captures` sees ([`View::sees`]),
/// `a_p` the VPL's shaded RGB contribution there (as a row of `A`), `k` the captures' strided
/// pixels per view over the coverage views' (so a coverage view weighs as one capture).
fn unseen_weights(
    scene: &Scene,
    captures: &[&View],
    coverage: &[&View],
    soa: &VplSoa,
    params: &RefitParams,
    capture_pixels: usize,
    cancelled: &(dyn Fn() -> bool + Sync),
) -> Result<(Vec<f64>, usize)> {
    let n = soa.len();
    if coverage.is_empty() || params.unseen_weight == 0.0 {
        return Ok((vec![0.0; n], 0));
    }
    let eps = scene.ray_epsilon();
    // Stops short of the surface, so the point does not hide itself.
    let occluded = |a: Vec3, b: Vec3| {
        let d = b - a;
        let len = d.length();
        len > 4.0 * eps && scene.occluded(a, a + d * ((len - 4.0 * eps) / len))
    };
    let strided = strided_pixels(coverage, params.stride);
    let unseen: Vec<(usize, usize)> = strided
        .par_iter()
        .copied()
        .filter(|&(v, p)| {
            let x = coverage[v].position_at(p);
            !captures.iter().any(|c| c.sees(x, occluded))
        })
        .collect();
    if cancelled() {
        return Err(VplaceError::Cancelled);
    }
    let gbuffers: Vec<GBuffer<'_>> = coverage.iter().map(|v| v.gbuffer()).collect();
    let sums = unseen
        .par_chunks(PIXELS_PER_TASK)
        .map(|task| {
            let mut state = scene.shadow_state();
            let mut batch = Batch::new(n);
            let mut rows = vec![0.0f64; 3 * n];
            let mut sum = vec![0.0f64; n];
            let mut hints = vec![NO_HINT; n];
            if cancelled() {
                return sum;
            }
            for &(v, p) in task {
                let recv = Receiver::of_pixel(&gbuffers[v], p, eps);
                let occluded =
                    |ray: &_, j: usize| scene.occluded_ray_hinted(&mut state, ray, &mut hints[j]);
                pixel_rows(&recv, soa, params.profile, &mut batch, occluded, &mut rows);
                for channel in rows.chunks(n) {
                    sum.iter_mut().zip(channel).for_each(|(s, a)| *s += a * a);
                }
            }
            sum
        })
        .reduce(
            || vec![0.0f64; n],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    if cancelled() {
        return Err(VplaceError::Cancelled);
    }
    let per_capture = capture_pixels as f64 / captures.len().max(1) as f64;
    let per_coverage = strided.len() as f64 / coverage.len() as f64;
    let k = if per_coverage > 0.0 {
        params.unseen_weight * per_capture / per_coverage
    } else {
        0.0
    };
    Ok((sums.iter().map(|x| k * x).collect(), unseen.len()))
}

/// Checks that frame `f` (`scene`, `views`) has the first frame's occluders and G-buffers
/// ([`refit_frames`]): then its rows of `A` are the first frame's.
fn same_transport(
    first: &Scene,
    first_views: &[&View],
    scene: &Scene,
    views: &[&View],
    f: usize,
) -> Result<()> {
    if views.len() != first_views.len() {
        return Err(VplaceError::Shape {
            what: format!("frame {f}'s views"),
            expected: format!("{} views, as the first frame", first_views.len()),
            got: format!("{} views", views.len()),
        });
    }
    if !first.same_occluders(scene) {
        return Err(VplaceError::Invalid {
            what: format!("frame {f}'s scene"),
            reason: "its triangles or surfaces differ from the first frame's: refit the frames \
                     one by one"
                .into(),
        });
    }
    for (a, b) in first_views.iter().zip(views) {
        let (ga, gb) = (a.gbuffer(), b.gbuffer());
        let same = ga.width == gb.width
            && ga.height == gb.height
            && ga.position == gb.position
            && ga.normal == gb.normal
            && ga.albedo == gb.albedo
            && ga.covered == gb.covered;
        if !same {
            return Err(VplaceError::Invalid {
                what: format!("frame {f}'s view {:?}", b.name),
                reason: format!(
                    "its G-buffer differs from the first frame's view {:?}: refit the frames \
                     one by one",
                    a.name
                ),
            });
        }
    }
    Ok(())
}

/// Refits the flux of `vpls` against the indirect image `indirect` (`I = G - D`, `H x W x 3`,
/// finite on covered pixels) over the covered pixels of the strided grid of `gbuffer`.
/// [`refit_with_coverage`] without coverage views.
///
/// Errors: shape mismatches, non-finite values on covered pixels, no VPLs or more than
/// [`MAX_VPLS`], `stride == 0`, a negative or non-finite `ridge` or `radius`,
/// [`VplaceError::Cancelled`]. A grid without a covered pixel leaves every scale at 1 with both
/// errors 0.
pub fn refit(
    scene: &Scene,
    views: &[&View],
    vpls: &[Vpl],
    params: &RefitParams,
    progress: Option<&Progress>,
) -> Result<Refitted> {
    refit_with_coverage(scene, views, &[], vpls, params, progress)
}

/// [`refit`], each VPL also pulled toward its light-path power (or the captures' gain times it)
/// with the weight of its light on what `coverage` shows and no view of `views` sees (the
/// module docs' "Surfaces no capture saw"). The coverage views need no indirect image: only
/// their G-buffers are read.
///
/// Errors: those of [`refit`], and a negative or non-finite [`RefitParams::unseen_weight`].
pub fn refit_with_coverage(
    scene: &Scene,
    views: &[&View],
    coverage: &[&View],
    vpls: &[Vpl],
    params: &RefitParams,
    progress: Option<&Progress>,
) -> Result<Refitted> {
    let mut refits = refit_frames(&[scene], &[views], coverage, vpls, params, progress)?;
    Ok(refits.remove(0))
}

/// [`refit_with_coverage`] of the same VPLs on several frames at once, where only the light
/// differs: `frames[f]` are frame `f`'s views, each with its own indirect image, on the first
/// frame's G-buffers bit for bit (size, position, normal, albedo, covered pixels), and
/// `scenes[f]` its scene, whose occluders are the first's ([`Scene::same_occluders`]; its
/// lights may differ: the refit does not read them). Every frame's rows of `A` are then the
/// same, so they are traced once: F frames cost one frame's shadow rays and Gram matrix, and
/// F solves. Each frame's result is the one [`refit_with_coverage`] gives it alone, bit for
/// bit (the ridge's cross-validation, the gain and the solve are per frame). Each result's
/// `seconds` is the tracing's share (over the frames) plus its own solve, its `shadow_rays`
/// the rays traced for all of them.
///
/// Errors: those of [`refit_with_coverage`]; no frame; `scenes` and `frames` of different
/// lengths; a frame with another number of views than the first, or whose G-buffers or
/// occluders are not the first frame's.
pub fn refit_frames(
    scenes: &[&Scene],
    frames: &[&[&View]],
    coverage: &[&View],
    vpls: &[Vpl],
    params: &RefitParams,
    progress: Option<&Progress>,
) -> Result<Vec<Refitted>> {
    let start = Instant::now();
    let (Some(&scene), Some(&views)) = (scenes.first(), frames.first()) else {
        return Err(VplaceError::Empty {
            what: "frames".into(),
            hint: "the refit needs at least one frame's scene and views".into(),
        });
    };
    if scenes.len() != frames.len() {
        return Err(VplaceError::Shape {
            what: "frames".into(),
            expected: format!("one scene per frame of views ({})", frames.len()),
            got: format!("{} scenes", scenes.len()),
        });
    }
    if views.is_empty() {
        return Err(VplaceError::Empty {
            what: "views".into(),
            hint: "the refit needs at least one view with its indirect image".into(),
        });
    }
    for (f, (other, frame)) in scenes.iter().zip(frames).enumerate().skip(1) {
        same_transport(scene, views, other, frame, f)?;
    }
    let targets: Vec<Vec<&[f32]>> = frames.iter().map(|f| targets(f)).collect::<Result<_>>()?;
    validate_vpls(vpls)?;
    check_radius(params.radius)?;
    if vpls.is_empty() {
        return Err(VplaceError::Empty {
            what: "VPLs".into(),
            hint: "the refit needs at least one VPL".into(),
        });
    }
    if vpls.len() > MAX_VPLS {
        return Err(VplaceError::OutOfRange {
            what: "number of VPLs".into(),
            value: vpls.len().to_string(),
            expected: format!("<= {MAX_VPLS} for the refit"),
        });
    }
    if params.stride == 0 {
        return Err(VplaceError::OutOfRange {
            what: "stride".into(),
            value: "0".into(),
            expected: ">= 1".into(),
        });
    }
    if params.group == 0 {
        return Err(VplaceError::OutOfRange {
            what: "group".into(),
            value: "0".into(),
            expected: ">= 1 (VPLs per power group)".into(),
        });
    }
    if !(params.ridge >= 0.0 && params.ridge.is_finite()) {
        return Err(VplaceError::OutOfRange {
            what: "ridge".into(),
            value: params.ridge.to_string(),
            expected: ">= 0 and finite".into(),
        });
    }
    if !(params.unseen_weight >= 0.0 && params.unseen_weight.is_finite()) {
        return Err(VplaceError::OutOfRange {
            what: "unseen_weight".into(),
            value: params.unseen_weight.to_string(),
            expected: ">= 0 and finite".into(),
        });
    }
    // NaN fails the comparison too.
    if params.max_scale.is_nan() || params.max_scale < 1.0 {
        return Err(VplaceError::OutOfRange {
            what: "max_scale".into(),
            value: params.max_scale.to_string(),
            expected: ">= 1 (or infinite: no bound)".into(),
        });
    }
    let gbuffers: Vec<GBuffer<'_>> = views.iter().map(|v| v.gbuffer()).collect();
    let pixels = strided_pixels(views, params.stride);
    let n = vpls.len();
    let by_view = params.leave_out_views && views.len() >= LOVO_MIN_VIEWS;
    let folds = match (params.select_ridge && n <= CV_MAX_VPLS, by_view) {
        (false, _) => 1,
        (true, true) => views.len().min(LOVO_MAX_FOLDS),
        (true, false) => CV_FOLDS,
    };
    let mut groups = vec![Vec::new(); folds];
    for &(v, p) in &pixels {
        let w = gbuffers[v].width;
        let fold = if by_view {
            v % folds
        } else {
            fold_of(v, (p % w) / CV_BLOCK_PX, (p / w) / CV_BLOCK_PX, folds)
        };
        groups[fold].push((v, p));
    }
    // The VPLs with their near-field radii, once for the captures and the coverage views.
    let soa = VplSoa::new(vpls, &near_field_radii(vpls, params.radius));
    // Per frame, its views' weights, read on its own targets.
    let weights: Vec<Vec<f64>> = targets
        .iter()
        .map(|t| view_weights(&gbuffers, t, params.balance_views))
        .collect();
    let per_fold = normal_equations(
        scene, &gbuffers, &targets, &weights, &soa, &groups, params, progress,
    )?;
    let cancelled = || progress.is_some_and(|p| p.cancel.load(Ordering::Relaxed));
    let (unseen, unseen_pixels) = unseen_weights(
        scene,
        views,
        coverage,
        &soa,
        params,
        pixels.len(),
        &cancelled,
    )?;
    let traced = start.elapsed().as_secs_f64() / frames.len() as f64;
    // Power groups: the solve runs on one scale per group ([`RefitParams::group`]).
    let (member, n) = if params.group > 1 {
        power_groups(vpls, params.group)
    } else {
        ((0..n).collect(), n)
    };
    // The ridge: the one of the grid whose refits on all folds but one predict the left-out
    // fold best (summed squared error); ties to the larger ridge. Folds without pixels are
    // skipped; with fewer than two usable folds the ridge is not selected.
    let usable: Vec<usize> = (0..folds).filter(|&k| !groups[k].is_empty()).collect();
    // Per frame, its folds' normal equations (traced per fold, one per frame each).
    let mut by_frame: Vec<Vec<Normal>> = frames.iter().map(|_| Vec::new()).collect();
    for fold in per_fold {
        for (parts, part) in by_frame.iter_mut().zip(fold) {
            parts.push(part);
        }
    }
    let solve_frame = |(mut parts, view_weights): (Vec<Normal>, Vec<f64>)| -> Result<Refitted> {
        let begun = Instant::now();
        for part in &mut parts {
            part.unseen.clone_from(&unseen);
        }
        if params.group > 1 {
            parts = parts.iter().map(|p| project(p, &member, n)).collect();
        }
        let mut ne = Normal::zero(n);
        for part in &parts {
            add_to(&mut ne, part);
        }
        let (mut cv, mut gain_cv) = (Vec::new(), Vec::new());
        let (mut ridge, mut free) = (params.ridge, false);
        if usable.len() >= 2 {
            let mut best = f64::INFINITY;
            let trains: Vec<Normal> = usable
                .iter()
                .map(|&k| {
                    let mut train = Normal::zero(n);
                    for part in (0..folds).filter(|&j| j != k).map(|j| &parts[j]) {
                        add_to(&mut train, part);
                    }
                    train
                })
                .collect();
            let cells: usize = usable.iter().map(|&k| parts[k].cells.len()).sum();
            // Per ridge, the summed error pulling toward 1 and (free gain) toward the gain.
            let mut errs = vec![[0.0f64; 2]; RIDGE_GRID.len()];
            for (train, &k) in trains.iter().zip(&usable) {
                let pulls: &[f64] = if params.free_gain {
                    &[1.0, train.gain()]
                } else {
                    &[1.0]
                };
                for (e, &r) in errs.iter_mut().zip(&RIDGE_GRID) {
                    for (m, solved) in solve(train, r, pulls, params.max_scale, &cancelled)?
                        .iter()
                        .enumerate()
                    {
                        e[m] += parts[k].cell_error(&solved.s);
                    }
                }
            }
            let rmse = |err: f64| (err / (3.0 * cells.max(1) as f64)).sqrt();
            // Ties: to the larger ridge.
            for (e, &r) in errs.iter().zip(&RIDGE_GRID) {
                cv.push((r, rmse(e[0])));
                if e[0] <= best {
                    (best, ridge) = (e[0], r);
                }
            }
            if params.free_gain {
                let mut best_gain = (f64::INFINITY, params.ridge);
                for (e, &r) in errs.iter().zip(&RIDGE_GRID) {
                    gain_cv.push((r, rmse(e[1])));
                    if e[1] <= best_gain.0 {
                        best_gain = (e[1], r);
                    }
                }
                if rmse(best_gain.0) < (1.0 - GAIN_MARGIN) * rmse(best) {
                    (ridge, free) = (best_gain.1, true);
                }
            }
        }
        let gain = if free { ne.gain() } else { 1.0 };
        let ones = vec![1.0f64; n];
        let solved = solve(&ne, ridge, &[gain], params.max_scale, &cancelled)?.remove(0);
        let (mut scales, exchanges) = (solved.s, solved.exchanges);
        let rows = 3.0 * pixels.len().max(1) as f64;
        let before = ne.sq_error(&ones);
        let mut after = ne.sq_error(&scales);
        // Worse than no refit (rounding), or not a number: keep the original powers.
        if !scales.iter().all(|s| s.is_finite()) || after.is_nan() || after > before {
            scales = ones;
            after = before;
        }
        if let Some(p) = progress {
            p.done.fetch_add(1, Ordering::Relaxed);
        }
        let scales: Vec<f64> = member.iter().map(|&m| scales[m]).collect();
        let refitted = vpls
            .iter()
            .zip(&scales)
            .map(|(v, &s)| Vpl {
                flux: v.flux * s as f32,
                ..*v
            })
            .collect();
        Ok(Refitted {
            vpls: refitted,
            scales,
            error_before: (before / rows).sqrt(),
            error_after: (after / rows).sqrt(),
            pixels: pixels.len(),
            shadow_rays: ne.rays,
            exchanges,
            ridge,
            cv,
            gain_cv,
            gain,
            groups: n,
            unseen_pixels,
            view_weights,
            seconds: traced + begun.elapsed().as_secs_f64(),
        })
    };
    by_frame.into_iter().zip(weights).map(solve_frame).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The refit with one scale per VPL: what most tests below check.
    const PER_VPL: RefitParams = RefitParams {
        group: 1,
        ..RefitParams::DEFAULT
    };
    use crate::shade::evaluator::{evaluate, EvalParams};
    use crate::test_util::{closed_box, reference_incident, shading_cases, FloorView};
    use std::collections::HashMap;

    /// VPLs on the ceiling and the walls of the test box, facing in, and one on the floor facing
    /// up that no floor pixel sees.
    fn vpls() -> Vec<Vpl> {
        let v = |p: [f32; 3], n: [f32; 3], f: [f32; 3]| Vpl {
            position: Vec3::from_array(p),
            normal: Vec3::from_array(n),
            flux: Vec3::from_array(f),
        };
        vec![
            v([0.5, 0.5, 1.99], [0.0, 0.0, -1.0], [1.0, 1.0, 1.0]),
            v([-0.6, 0.2, 1.99], [0.0, 0.0, -1.0], [0.5, 0.8, 1.0]),
            v([0.0, -0.7, 1.99], [0.0, 0.0, -1.0], [1.2, 0.6, 0.3]),
            v([-0.99, 0.0, 0.6], [1.0, 0.0, 0.0], [0.8, 0.8, 0.8]),
            v([0.99, -0.4, 1.0], [-1.0, 0.0, 0.0], [0.4, 1.0, 0.4]),
            v([0.2, 0.99, 0.3], [0.0, -1.0, 0.0], [1.0, 0.5, 0.5]),
            v([0.0, 0.0, 0.01], [0.0, 0.0, 1.0], [2.0, 2.0, 2.0]),
        ]
    }

    /// Scales of [`vpls`] that the refit recovers: six seen VPLs' and the unseen seventh's.
    const KNOWN_SCALES: [f32; 7] = [0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0];

    /// The known-scales tests' setting: the closed box, a floor view `size` pixels wide, the
    /// base VPLs ([`vpls`]) and the floor they light at [`KNOWN_SCALES`] (the target).
    fn known_scales_floor(size: usize) -> (Scene, FloorView, Vec<Vpl>, Vec<f32>) {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(size, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let target = render(&scene, &fv, &scaled(&base, &KNOWN_SCALES));
        (scene, fv, base, target)
    }

    fn scaled(vpls: &[Vpl], s: &[f32]) -> Vec<Vpl> {
        vpls.iter()
            .zip(s)
            .map(|(v, &s)| Vpl {
                flux: v.flux * s,
                ..*v
            })
            .collect()
    }

    fn render(scene: &Scene, fv: &FloorView, vpls: &[Vpl]) -> Vec<f32> {
        evaluate(
            scene,
            &fv.view().gbuffer(),
            vpls,
            &EvalParams::PREVIEW,
            None,
        )
        .unwrap()
        .0
    }

    fn params(stride: usize, ridge: f64) -> RefitParams {
        RefitParams {
            stride,
            ridge,
            select_ridge: false,
            ..PER_VPL
        }
    }

    #[test]
    fn recovers_known_scales() {
        let (scene, fv, base, target) = known_scales_floor(32);
        let truth = KNOWN_SCALES;
        for (stride, ridge, tol) in [
            (1, 0.0, 1e-4),
            (3, 0.0, 1e-4),
            (2, 1e-5, 1e-3),
            (2, 1e-3, 5e-2),
        ] {
            let v = fv.view_with(Some(&target));
            let r = refit(&scene, &[&v], &base, &params(stride, ridge), None).unwrap();
            assert_eq!(r.pixels, 32usize.div_ceil(stride).pow(2));
            for (s, &t) in r.scales.iter().zip(&truth).take(6) {
                assert!(
                    (s - f64::from(t)).abs() < tol,
                    "{stride} {ridge} {:?}",
                    r.scales
                );
            }
            // Unseen: the ridge keeps it at its power.
            assert!((r.scales[6] - 1.0).abs() < 1e-9, "{:?}", r.scales);
            assert!(r.error_after < 1e-2 * r.error_before);
            assert!(r.scales.iter().all(|&s| s >= 0.0));
            for (v, (b, &s)) in r.vpls.iter().zip(base.iter().zip(&r.scales)) {
                assert_eq!((v.position, v.normal), (b.position, b.normal));
                assert!((v.flux - b.flux * s as f32).abs().max_element() < 1e-6);
            }
        }
    }

    /// The bound on the scales ([`RefitParams::max_scale`]): the known scales of
    /// [`recovers_known_scales`] refitted with a bound of 1.6, which one seen VPL's scale (2)
    /// is above. It ends at the bound, every scale stays within it, and the error lies between
    /// the unbounded refit's and the error before.
    #[test]
    fn max_scale_bounds_the_scales() {
        let (scene, fv, base, target) = known_scales_floor(32);
        let v = fv.view_with(Some(&target));
        let free = refit(&scene, &[&v], &base, &params(1, 0.0), None).unwrap();
        let bound = RefitParams {
            max_scale: 1.6,
            ..params(1, 0.0)
        };
        let r = refit(&scene, &[&v], &base, &bound, None).unwrap();
        let upper = 1.6 * r.gain.max(1.0);
        assert!(
            r.scales.iter().all(|&s| (0.0..=upper).contains(&s)),
            "{:?}",
            r.scales
        );
        // VPL 1 (truth 2) cannot reach its scale: it ends at the bound.
        assert!((r.scales[1] - upper).abs() < 1e-9, "{:?}", r.scales);
        assert!(r.error_after > free.error_after && r.error_after < r.error_before);
    }

    /// Two far clusters of VPLs on two walls: groups of their size keep each cluster whole,
    /// every VPL gets a group, none is empty, and a second call gives the same groups.
    #[test]
    fn power_groups_keep_neighbours_together() {
        let v = |x: f32, y: f32, normal: Vec3| Vpl {
            position: Vec3::new(x, y, 1.0),
            normal,
            flux: Vec3::ONE,
        };
        let mut set: Vec<Vpl> = (0..8)
            .map(|i| v(0.1 * i as f32, 0.05 * (i % 3) as f32, Vec3::Z))
            .collect();
        set.extend((0..8).map(|i| v(5.0 + 0.1 * i as f32, 0.05 * (i % 2) as f32, Vec3::X)));
        let (member, k) = power_groups(&set, 8);
        assert_eq!(k, 2);
        assert!(member[..8].iter().all(|&m| m == member[0]), "{member:?}");
        assert!(member[8..].iter().all(|&m| m == member[8]), "{member:?}");
        assert_ne!(member[0], member[8]);
        assert_eq!(power_groups(&set, 8), (member.clone(), k));
        let (member, k) = power_groups(&set, 3);
        assert_eq!(k, 6);
        assert!((0..k).all(|g| member.contains(&g)), "{member:?}");
        // One VPL, or every VPL at one point: one group.
        assert_eq!(power_groups(&set[..1], 8), (vec![0], 1));
        let same = vec![set[0]; 5];
        assert_eq!(power_groups(&same, 2), (vec![0; 5], 1));
    }

    /// With power groups the refit solves for one scale per group: a target that scales each
    /// group by its own factor is recovered, every VPL of a group gets its group's scale, and
    /// the error matches the evaluator's image of the refitted VPLs.
    #[test]
    fn grouped_refit_recovers_group_scales() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(32, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let (member, k) = power_groups(&base, 2);
        assert_eq!(k, 4);
        let factor = [0.5, 2.0, 1.5, 0.8];
        let truth: Vec<f32> = member.iter().map(|&m| factor[m]).collect();
        let target = render(&scene, &fv, &scaled(&base, &truth));
        let v = fv.view_with(Some(&target));
        let grouped = RefitParams {
            group: 2,
            ..params(1, 0.0)
        };
        let r = refit(&scene, &[&v], &base, &grouped, None).unwrap();
        assert_eq!(r.groups, k);
        for (i, &s) in r.scales.iter().enumerate() {
            let peers = member
                .iter()
                .zip(&r.scales)
                .filter(|(&m, _)| m == member[i]);
            assert!(peers.clone().all(|(_, &t)| t == s), "{:?}", r.scales);
            // The floor VPL (6) lights no floor pixel: it only follows its group.
            if i != 6 {
                assert!(
                    (s - f64::from(truth[i])).abs() < 1e-3,
                    "{i}: {:?}",
                    r.scales
                );
            }
        }
        assert!(r.error_after < 1e-2 * r.error_before);
        let img = render(&scene, &fv, &r.vpls);
        let rmse = (img
            .iter()
            .zip(&target)
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum::<f64>()
            / img.len() as f64)
            .sqrt();
        assert!(
            (rmse - r.error_after).abs() < 1e-3 * r.error_before,
            "{rmse} {}",
            r.error_after
        );
        let single = refit(&scene, &[&v], &base, &params(1, 0.0), None).unwrap();
        assert_eq!(single.groups, base.len());
    }

    /// A group is its VPLs under one scale, ridge and all: with every VPL of the test set
    /// copied four times (each group the four copies), the grouped refit gives the scales the
    /// per-VPL refit does at the same ridge (whose solution gives copies one scale). A ridge
    /// relative to the groups' own Gram matrix pulled each group up to four times harder.
    #[test]
    fn a_group_of_coinciding_vpls_refits_as_its_vpls() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(32, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let copies: Vec<Vpl> = vpls()
            .iter()
            .flat_map(|v| {
                std::iter::repeat_n(
                    Vpl {
                        flux: v.flux * 0.25,
                        ..*v
                    },
                    4,
                )
            })
            .collect();
        let (member, k) = power_groups(&copies, 4);
        assert_eq!(k, vpls().len());
        assert!(member.chunks(4).all(|g| g.iter().all(|&m| m == g[0])));
        let target = render(
            &scene,
            &fv,
            &scaled(&vpls(), &[0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0]),
        );
        let v = fv.view_with(Some(&target));
        for ridge in [0.1, 1.0, 10.0] {
            let single = refit(&scene, &[&v], &copies, &params(1, ridge), None).unwrap();
            let grouped = RefitParams {
                group: 4,
                ..params(1, ridge)
            };
            let r = refit(&scene, &[&v], &copies, &grouped, None).unwrap();
            assert_eq!(r.groups, k);
            for (a, b) in r.scales.iter().zip(&single.scales) {
                assert!((a - b).abs() < 1e-6 * b.max(1.0), "{ridge}: {a} {b}");
            }
            assert!((r.error_after - single.error_after).abs() < 1e-9 + 1e-6 * r.error_after);
        }
    }

    /// The floor view's pixels lifted onto the test box's ceiling (facing down): a view of
    /// surfaces the floor camera, at z = 1.9 looking down, cannot see.
    fn ceiling_view(fv: &FloorView) -> View {
        let mut up = fv.clone();
        up.gbuffer.position.chunks_mut(3).for_each(|p| p[2] = 2.0);
        up.gbuffer.normal = [0.0, 0.0, -1.0].repeat(up.gbuffer.width * up.gbuffer.height);
        up.view()
    }

    /// A wall VPL that lights the ceiling more than the floor, its power tripled in the floor's
    /// target: without coverage the refit follows the floor and triples it (lighting the
    /// ceiling no capture saw three times too bright); with a coverage view of the ceiling it
    /// is held nearer its light-path power, and the VPLs that light the floor alone are fitted
    /// as before.
    #[test]
    fn coverage_holds_a_vpl_that_lights_what_no_capture_saw() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(32, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let mut truth = [1.0f32; 7];
        truth[4] = 3.0;
        let target = render(&scene, &fv, &scaled(&base, &truth));
        let capture = fv.view_with(Some(&target));
        let up = ceiling_view(&fv);
        let p = params(2, 1e-3);
        let alone = refit(&scene, &[&capture], &base, &p, None).unwrap();
        let held = refit_with_coverage(&scene, &[&capture], &[&up], &base, &p, None).unwrap();
        assert_eq!(alone.unseen_pixels, 0);
        assert_eq!(held.unseen_pixels, 16 * 16);
        assert!((alone.scales[4] - 3.0).abs() < 0.05, "{:?}", alone.scales);
        assert!(
            held.scales[4] > 1.0 && held.scales[4] < 2.5,
            "{:?}",
            held.scales
        );
        assert!(held.error_after > alone.error_after);
        assert!(held.error_after < held.error_before);
        // The ceiling VPLs face down: they light no ceiling pixel, are not held, and take up
        // the floor's light the held wall VPL no longer gives.
        for i in 0..3 {
            assert!((alone.scales[i] - 1.0).abs() < 0.05, "{:?}", alone.scales);
            assert!(held.scales[i] > alone.scales[i], "{:?}", held.scales);
        }
        // What the captures see is not unseen: the floor as coverage changes nothing, nor does
        // a weight of 0.
        let floor = refit_with_coverage(&scene, &[&capture], &[&capture], &base, &p, None).unwrap();
        assert_eq!((floor.unseen_pixels, &floor.scales), (0, &alone.scales));
        let off = RefitParams {
            unseen_weight: 0.0,
            ..p
        };
        let zero = refit_with_coverage(&scene, &[&capture], &[&up], &base, &off, None).unwrap();
        assert_eq!(zero.scales, alone.scales);
        // A heavier weight holds it nearer 1; the cross-validated ridge sees the same penalty.
        let heavy = RefitParams {
            unseen_weight: 10.0,
            ..p
        };
        let h = refit_with_coverage(&scene, &[&capture], &[&up], &base, &heavy, None).unwrap();
        assert!(
            h.scales[4] < held.scales[4],
            "{} {}",
            h.scales[4],
            held.scales[4]
        );
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let q = RefitParams {
                unseen_weight: bad,
                ..p
            };
            let e = refit_with_coverage(&scene, &[&capture], &[&up], &base, &q, None);
            assert!(matches!(e, Err(VplaceError::OutOfRange { .. })), "{bad}");
        }
    }

    /// The captures' gain: on a target that is every VPL at 2.5 times its power, the refit
    /// pulling toward the gain (taken by the cross-validation) gives every VPL 2.5, the one no
    /// pixel sees too; pulling toward 1 leaves that one at 1. On a target the powers already
    /// match, the gain is 1.
    #[test]
    fn the_gain_carries_the_captures_total_to_unseen_vpls() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(128, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let target = render(&scene, &fv, &scaled(&base, &[2.5; 7]));
        let v = fv.view_with(Some(&target));
        let free = RefitParams {
            stride: 2,
            ..PER_VPL
        };
        let r = refit(&scene, &[&v], &base, &free, None).unwrap();
        assert_eq!(r.cv.len(), RIDGE_GRID.len());
        assert_eq!(r.gain_cv.len(), RIDGE_GRID.len());
        assert!((r.gain - 2.5).abs() < 1e-5, "{}", r.gain);
        assert!(
            r.scales.iter().all(|s| (s - 2.5).abs() < 1e-3),
            "{:?}",
            r.scales
        );
        assert!(r.error_after < 1e-3 * r.error_before);
        let fixed = RefitParams {
            free_gain: false,
            ..free
        };
        let r = refit(&scene, &[&v], &base, &fixed, None).unwrap();
        assert!(r.gain == 1.0 && r.gain_cv.is_empty());
        assert!((r.scales[6] - 1.0).abs() < 1e-9, "{:?}", r.scales);
        let same = fv.view_with(Some(&render(&scene, &fv, &base)));
        let r = refit(&scene, &[&same], &base, &free, None).unwrap();
        assert!((r.gain - 1.0).abs() < 1e-5, "{}", r.gain);
    }

    /// The ridge is chosen on held-out blocks: on a target the VPLs reproduce exactly, the
    /// smallest ridge of the grid predicts the left-out blocks best and the largest (which barely
    /// leaves the powers) far worse; every ridge is listed with its error; a given ridge skips the
    /// selection; a view of one block (one usable fold) keeps the given ridge.
    #[test]
    fn cross_validation_picks_the_ridge() {
        let (scene, fv, base, target) = known_scales_floor(128);
        let v = fv.view_with(Some(&target));
        let chosen = RefitParams {
            stride: 2,
            free_gain: false, // compared below with a given ridge, which pulls toward 1
            ..PER_VPL
        };
        let r = refit(&scene, &[&v], &base, &chosen, None).unwrap();
        let ridges: Vec<f64> = r.cv.iter().map(|c| c.0).collect();
        assert_eq!(ridges, RIDGE_GRID);
        assert_eq!(r.ridge, RIDGE_GRID[0], "{:?}", r.cv);
        assert!(r.cv.iter().all(|c| c.1 >= r.cv[0].1), "{:?}", r.cv);
        assert!(r.cv[4].1 > 10.0 * r.cv[0].1, "{:?}", r.cv);
        assert!(r.error_after < 0.1 * r.error_before);
        // The same ridge given: the same scales (the folds only split the sums).
        let given = refit(&scene, &[&v], &base, &params(2, RIDGE_GRID[0]), None).unwrap();
        assert!(given.cv.is_empty() && given.ridge == RIDGE_GRID[0]);
        for (a, b) in given.scales.iter().zip(&r.scales) {
            assert!((a - b).abs() < 1e-9, "{:?} {:?}", given.scales, r.scales);
        }
        let small = FloorView::new(24, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let target = render(&scene, &small, &base);
        let one_block = refit(
            &scene,
            &[&small.view_with(Some(&target))],
            &base,
            &chosen,
            None,
        );
        let one_block = one_block.unwrap();
        assert!(one_block.cv.is_empty() && one_block.ridge == chosen.ridge);
    }

    /// The error before is the RMSE of the evaluator's image on the strided grid: the columns
    /// are the evaluator's contributions.
    #[test]
    fn error_before_is_the_evaluator_rmse() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(24, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let target = render(
            &scene,
            &fv,
            &scaled(&base, &[2.0, 1.0, 0.5, 1.0, 0.0, 1.0, 1.0]),
        );
        let image = render(&scene, &fv, &base);
        let stride = 5;
        let (mut sq, mut count) = (0.0f64, 0usize);
        for y in (0..24).step_by(stride) {
            for x in (0..24).step_by(stride) {
                let p = y * 24 + x;
                for c in 0..3 {
                    sq += f64::from(image[3 * p + c] - target[3 * p + c]).powi(2);
                }
                count += 1;
            }
        }
        let rmse = (sq / (3.0 * count as f64)).sqrt();
        let v = fv.view_with(Some(&target));
        let r = refit(&scene, &[&v], &base, &params(stride, 1e-3), None).unwrap();
        assert!(
            (r.error_before - rmse).abs() < 1e-5 * rmse,
            "{} {rmse}",
            r.error_before
        );
        let (_, stats) = evaluate(
            &scene,
            &fv.view().gbuffer(),
            &base,
            &EvalParams::PREVIEW,
            None,
        )
        .unwrap();
        // Every floor pixel sees the six inward VPLs; the upward one costs no ray.
        assert_eq!(stats.shadow_rays, 24 * 24 * 6);
        assert_eq!(r.shadow_rays, (count * 6) as u64);
    }

    #[test]
    fn scales_stay_non_negative() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(24, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        // The target asks for negative light: all of VPL 1 taken away twice over, and a
        // negative image everywhere in the second case.
        let all = render(&scene, &fv, &base);
        let one = render(&scene, &fv, &base[1..2]);
        let minus: Vec<f32> = all.iter().zip(&one).map(|(a, o)| a - 2.0 * o).collect();
        let negative: Vec<f32> = all.iter().map(|a| -a).collect();
        for (target, ridge) in [(&minus, 0.0), (&minus, 1e-2), (&negative, 1e-3)] {
            let v = fv.view_with(Some(target));
            let r = refit(&scene, &[&v], &base, &params(2, ridge), None).unwrap();
            assert!(r.scales.iter().all(|&s| s >= 0.0), "{:?}", r.scales);
            assert!(r.vpls.iter().all(|v| v.flux.min_element() >= 0.0));
            assert!(r.error_after <= r.error_before);
            assert_eq!(r.scales[1], 0.0, "{:?}", r.scales);
        }
    }

    #[test]
    fn never_worse_and_deterministic() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(20, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let mut rng = crate::rng::Rng::new(9, 0);
        for ridge in [0.0, 1e-3, 1.0, 1e6] {
            let target: Vec<f32> = (0..20 * 20 * 3)
                .map(|_| rng.next_f32() * 0.05 - 0.01)
                .collect();
            let p = params(3, ridge);
            let v = fv.view_with(Some(&target));
            let r = refit(&scene, &[&v], &base, &p, None).unwrap();
            assert!(r.error_after <= r.error_before, "{ridge}: {r:?}");
            // Same result on one thread and on three.
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let again = pool
                    .install(|| refit(&scene, &[&v], &base, &p, None))
                    .unwrap();
                assert_eq!(again.scales, r.scales);
                assert_eq!(again.error_after, r.error_after);
                assert_eq!(again.shadow_rays, r.shadow_rays);
            }
        }
    }

    /// The refit's matrix rows are bit for bit the brute-force reference's entries
    /// (`albedo / pi * reference_incident`, a plain scalar loop with shadow rays against every
    /// triangle) on the degenerate cases of [`shading_cases`], with one ray per pair the
    /// reference traces; and its normal equations are those of the reference's rows.
    #[test]
    fn matrix_rows_match_the_brute_force_reference() {
        let (scene, arrays, vpls) = shading_cases();
        let g = arrays.gbuffer();
        let n = vpls.len();
        let eps = scene.ray_epsilon();
        let vec3 = |a: &[f32], p: usize| Vec3::from_slice(&a[3 * p..3 * p + 3]);
        for profile in [Profile::Cosine, Profile::Omni] {
            for radius in [0.0, 0.05, 0.4] {
                let params = RefitParams {
                    profile,
                    radius,
                    stride: 1,
                    ridge: 0.1,
                    select_ridge: false,
                    free_gain: false,
                    leave_out_views: false,
                    group: 1,
                    unseen_weight: 0.0,
                    balance_views: true,
                    max_scale: f64::INFINITY,
                };
                let pixels: Vec<usize> = (0..144).filter(|&p| g.covered[p]).collect();
                let radii = near_field_radii(&vpls, radius);
                let soa = VplSoa::new(&vpls, &radii);
                let mut expect = Vec::new();
                let mut expect_rays = 0;
                let (mut state, mut batch) = (scene.shadow_state(), Batch::new(n));
                let mut rows = vec![0.0; 3 * n];
                for &p in &pixels {
                    let (x, nrm) = (vec3(g.position, p), vec3(g.normal, p).normalize_or_zero());
                    let brdf = vec3(g.albedo, p) / std::f32::consts::PI;
                    let mut pixel_rays = 0;
                    let a: Vec<Vec3> = vpls
                        .iter()
                        .zip(&radii)
                        .map(|(v, &r)| {
                            let c = reference_incident(Some(&scene), x, nrm, v, profile, r);
                            pixel_rays += u64::from(c.is_some());
                            brdf * c.unwrap_or(Vec3::ZERO)
                        })
                        .collect();
                    expect_rays += pixel_rays;
                    let rays = pixel_rows(
                        &Receiver::of_pixel(&g, p, eps),
                        &soa,
                        profile,
                        &mut batch,
                        |ray, _| scene.occluded_ray(&mut state, ray),
                        &mut rows,
                    );
                    assert_eq!(rays, pixel_rays, "pixel {p}");
                    for c in 0..3 {
                        let want: Vec<f64> = a.iter().map(|v| f64::from(v[c])).collect();
                        assert_eq!(
                            &rows[c * n..(c + 1) * n],
                            &want[..],
                            "pixel {p} channel {c}"
                        );
                    }
                    expect.extend(a);
                }
                // The normal equations of the reference rows (pixel-major, R G B per pixel).
                let target: Vec<f32> = (0..3 * 144).map(|i| 0.01 * (i % 7) as f32).collect();
                let targets = [vec![&target[..]]];
                let pairs: Vec<(usize, usize)> = pixels.iter().map(|&p| (0, p)).collect();
                let groups = [pairs];
                let weights = [vec![1.0]];
                let ne = normal_equations(
                    &scene,
                    &[g],
                    &targets,
                    &weights,
                    &soa,
                    &groups,
                    &params,
                    None,
                )
                .unwrap()
                .remove(0)
                .remove(0);
                assert_eq!(ne.rays, expect_rays);
                let (mut atb, mut gram) = (vec![0.0f64; n], vec![0.0f64; n * n]);
                for (k, &p) in pixels.iter().enumerate() {
                    for c in 0..3 {
                        let row: Vec<f64> =
                            (0..n).map(|j| f64::from(expect[k * n + j][c])).collect();
                        for i in 0..n {
                            atb[i] += row[i] * f64::from(target[3 * p + c]);
                            for j in 0..n {
                                gram[j * n + i] += row[i] * row[j];
                            }
                        }
                    }
                }
                let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
                for i in 0..n {
                    assert!(close(ne.atb[i], atb[i]), "{i}: {} {}", ne.atb[i], atb[i]);
                    for j in 0..n {
                        let (got, want) = (ne.gram[j * n + i], gram[j * n + i]);
                        assert!(close(got, want), "{i} {j}: {got} {want}");
                    }
                }
            }
        }
    }

    #[test]
    fn solver_matches_kkt_on_random_problems() {
        let mut rng = crate::rng::Rng::new(3, 0);
        for n in [1, 5, 40, 150] {
            let m = 2 * n + 3;
            let a: Vec<f64> = (0..m * n).map(|_| f64::from(rng.next_f32())).collect();
            let b: Vec<f64> = (0..m).map(|_| f64::from(rng.next_f32()) - 0.6).collect();
            let mut q = vec![0.0; n * n];
            let (mut c, mut c_up) = (vec![0.0; n], vec![0.0; n]);
            for i in 0..n {
                for j in 0..n {
                    q[j * n + i] = (0..m).map(|r| a[r * n + i] * a[r * n + j]).sum();
                }
                q[i * n + i] += 1e-6;
                c[i] = (0..m).map(|r| a[r * n + i] * b[r]).sum();
                // Targets all positive, for the bounded case: scales above the bound.
                c_up[i] = (0..m).map(|r| a[r * n + i] * (b[r] + 1.0)).sum();
            }
            // Pivoting, and the coordinate-descent fallback alone (no exchange allowed); the
            // full factor computed here or given (as `solve` shares it between pulls); without
            // an upper bound and with one that holds some variables.
            let chol = Cholesky::new(DMatrix::from_column_slice(n, n, &q)).unwrap();
            let mut held = 0;
            // The bound at half the largest unbounded scale.
            let free_max = nnls_bpp(&q, &c_up, f64::INFINITY, None, MAX_EXCHANGES, &|| false)
                .unwrap()
                .s
                .into_iter()
                .fold(0.0, f64::max);
            assert!(free_max > 0.0);
            for (upper, c) in [(f64::INFINITY, &c), (0.5 * free_max, &c_up)] {
                for (cap, tol, full) in [
                    (MAX_EXCHANGES, 1e-8, None),
                    (MAX_EXCHANGES, 1e-8, Some(&chol)),
                    (0, 1e-4, None),
                ] {
                    // The fallback's 200 sweeps do not reach the bounded optimum of these
                    // ill-conditioned problems (ridge 1e-6): the pivoting alone is held to it.
                    if cap == 0 && upper.is_finite() {
                        continue;
                    }
                    let r = nnls_bpp(&q, c, upper, full, cap, &|| false).unwrap();
                    let s = r.s;
                    let scale = c.iter().map(|v| v.abs()).fold(1.0, f64::max);
                    for i in 0..n {
                        let y: f64 = (0..n).map(|k| q[k * n + i] * s[k]).sum::<f64>() - c[i];
                        assert!((0.0..=upper).contains(&s[i]), "n {n}: s[{i}] = {}", s[i]);
                        // KKT: y >= 0 off the upper bound, y <= 0 off the lower bound.
                        let at_upper = s[i] >= upper - tol;
                        held += usize::from(at_upper && cap > 0);
                        if !at_upper {
                            assert!(y >= -tol * scale, "n {n} cap {cap}: y[{i}] = {y}");
                        }
                        assert!(
                            (s[i] * y).abs() <= tol * scale || (at_upper && y <= tol * scale),
                            "n {n} cap {cap} upper {upper}: s {} y {y}",
                            s[i]
                        );
                    }
                    assert!(r.exchanges <= cap);
                }
            }
            // The bound did hold variables: this tested the upper side.
            assert!(held > 0, "n {n}: no variable at the upper bound");
        }
    }

    #[test]
    fn bad_input_and_cancel() {
        let scene = closed_box(vec![]);
        let fv = FloorView::new(8, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let target = vec![0.1f32; 8 * 8 * 3];
        let v = fv.view_with(Some(&target));
        let ok = PER_VPL;
        assert!(refit(&scene, &[&v], &base, &ok, None).is_ok());
        assert!(matches!(
            refit(&scene, &[], &base, &ok, None),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            refit(&scene, &[&fv.view()], &base, &ok, None),
            Err(VplaceError::Invalid { .. })
        ));
        assert!(matches!(
            refit(&scene, &[&v], &[], &ok, None),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            refit(&scene, &[&v], &vec![base[0]; MAX_VPLS + 1], &ok, None),
            Err(VplaceError::OutOfRange { .. })
        ));
        for p in [
            RefitParams { stride: 0, ..ok },
            RefitParams { group: 0, ..ok },
            RefitParams { ridge: -1.0, ..ok },
            RefitParams {
                ridge: f64::NAN,
                ..ok
            },
            RefitParams { radius: -1.0, ..ok },
            RefitParams {
                max_scale: 0.5,
                ..ok
            },
            RefitParams {
                max_scale: f64::NAN,
                ..ok
            },
        ] {
            assert!(matches!(
                refit(&scene, &[&v], &base, &p, None),
                Err(VplaceError::OutOfRange { .. })
            ));
        }
        // A NaN in the target masks its pixel when the view is made; no covered pixel at all
        // leaves the scales at 1.
        let mut nan = target.clone();
        nan[7] = f32::NAN;
        let masked = fv.view_with(Some(&nan));
        assert_eq!(masked.masked_pixels, 1);
        let r = refit(
            &scene,
            &[&masked],
            &base,
            &RefitParams { stride: 1, ..ok },
            None,
        )
        .unwrap();
        assert_eq!(r.pixels, 63);
        let mut empty = v.clone();
        empty.covered.fill(false);
        let r = refit(&scene, &[&empty], &base, &ok, None).unwrap();
        assert!(r.scales.iter().all(|&s| s == 1.0));
        assert_eq!((r.pixels, r.error_before, r.error_after), (0, 0.0, 0.0));
        let progress = Progress::default();
        progress.cancel.store(true, Ordering::Relaxed);
        assert_eq!(
            refit(&scene, &[&v], &base, &ok, Some(&progress)).unwrap_err(),
            VplaceError::Cancelled
        );
        let progress = Progress::default();
        refit(&scene, &[&v], &base, &ok, Some(&progress)).unwrap();
        let total = progress.total.load(Ordering::Relaxed);
        assert!(total >= 2);
        assert_eq!(progress.done.load(Ordering::Relaxed), total);
    }

    #[test]
    fn leave_one_view_out_scores_each_view_with_the_others_refit() {
        // Three views of the floor: two agree, the third's target has other powers. Each ridge's
        // validation error is the one the explicit refit on the other two views makes on the
        // left-out view's cells (16 px, strided pixels); with two views the blocks decide.
        let w = 64; // four blocks of CV_BLOCK_PX a view: the block folds mix the views
        let scene = closed_box(vec![]);
        let fv = FloorView::new(w, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let a = render(
            &scene,
            &fv,
            &scaled(&base, &[0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0]),
        );
        let b = render(
            &scene,
            &fv,
            &scaled(&base, &[1.5, 0.5, 1.0, 2.0, 0.5, 0.8, 3.0]),
        );
        let views = [
            fv.view_with(Some(&a)),
            fv.view_with(Some(&a)),
            fv.view_with(Some(&b)),
        ];
        let targets = [&a, &a, &b];
        let stride = 2;
        // The pull toward 1 alone, as recomputed below; unweighted views (balanced, the folds
        // keep the weights of all three views, which a refit on two would not).
        let lovo = RefitParams {
            stride,
            free_gain: false,
            balance_views: false,
            ..PER_VPL
        };
        let all: Vec<&View> = views.iter().collect();
        let r = refit(&scene, &all, &base, &lovo, None).unwrap();
        let mut cells_total = 0;
        for (i, &(ridge, got)) in r.cv.iter().enumerate() {
            assert_eq!(ridge, RIDGE_GRID[i]);
            let mut err = 0.0;
            cells_total = 0;
            for (k, target) in targets.iter().enumerate() {
                let others: Vec<&View> = (0..3).filter(|&j| j != k).map(|j| &views[j]).collect();
                let fold = RefitParams {
                    balance_views: false,
                    ..params(stride, ridge)
                };
                let s = refit(&scene, &others, &base, &fold, None).unwrap();
                let s32: Vec<f32> = s.scales.iter().map(|&x| x as f32).collect();
                let img = render(&scene, &fv, &scaled(&base, &s32));
                let mut cells: HashMap<(usize, usize), ([f64; 3], usize)> = HashMap::new();
                for y in (0..w).step_by(stride) {
                    for x in (0..w).step_by(stride) {
                        let cell = cells.entry((x / CV_CELL_PX, y / CV_CELL_PX)).or_default();
                        for c in 0..3 {
                            let i = 3 * (y * w + x) + c;
                            cell.0[c] += f64::from(img[i]) - f64::from(target[i]);
                        }
                        cell.1 += 1;
                    }
                }
                cells_total += cells.len();
                err += cells
                    .values()
                    .map(|(d, m)| d.iter().map(|x| (x / *m as f64).powi(2)).sum::<f64>())
                    .sum::<f64>();
            }
            let want = (err / (3.0 * cells_total as f64)).sqrt();
            assert!(
                (got - want).abs() <= 1e-6 * want.max(1e-12),
                "{ridge}: {got} {want}"
            );
        }
        assert_eq!(cells_total, 3 * (w / CV_CELL_PX).pow(2));
        let best = r.cv.iter().min_by(|x, y| x.1.total_cmp(&y.1)).unwrap().0;
        assert_eq!(r.ridge, best, "{:?}", r.cv);
        // Blocks instead (asked for, or only two views): another validation.
        let blocks = RefitParams {
            leave_out_views: false,
            ..lovo
        };
        let by_blocks = refit(&scene, &all, &base, &blocks, None).unwrap();
        assert_ne!(by_blocks.cv, r.cv);
        let two = refit(&scene, &all[..2], &base, &lovo, None).unwrap();
        let two_blocks = refit(&scene, &all[..2], &base, &blocks, None).unwrap();
        assert_eq!(two.ridge, two_blocks.ridge);
        for (x, y) in two.cv.iter().zip(&two_blocks.cv) {
            assert!(
                x.0 == y.0 && (x.1 - y.1).abs() <= 1e-9 * y.1,
                "{:?} {:?}",
                two.cv,
                two_blocks.cv
            );
        }
    }

    #[test]
    fn two_views_stack_their_pixels() {
        // The same floor seen twice is the one-view problem with every row twice: the same
        // scales, twice the pixels.
        let scene = closed_box(vec![]);
        let fv = FloorView::new(16, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let target = render(
            &scene,
            &fv,
            &scaled(&base, &[0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0]),
        );
        let v = fv.view_with(Some(&target));
        let p = params(2, 1e-3);
        let one = refit(&scene, &[&v], &base, &p, None).unwrap();
        let two = refit(&scene, &[&v, &v], &base, &p, None).unwrap();
        assert_eq!(two.pixels, 2 * one.pixels);
        for (a, b) in one.scales.iter().zip(&two.scales) {
            assert!((a - b).abs() < 1e-6, "{:?} {:?}", one.scales, two.scales);
        }
    }

    #[test]
    fn view_weights_count_each_views_light_as_relative_error() {
        let fv = FloorView::new(8, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let v = fv.view();
        let g = [v.gbuffer(), v.gbuffer()];
        let bright = vec![0.4f32; 3 * 64];
        let dim = vec![0.1f32; 3 * 64];
        let black = vec![0.0f32; 3 * 64];
        let w = view_weights(&g, &[&bright, &dim], true);
        // Inverse to the light: the dim view weighs four times the bright one, and the weighted
        // targets keep the energy of the unweighted (both views the same size here).
        assert!((w[1] / w[0] - 4.0).abs() < 1e-9, "{w:?}");
        let energy = |w: &[f64]| (w[0] * 0.4).powi(2) + (w[1] * 0.1).powi(2);
        assert!((energy(&w) - energy(&[1.0, 1.0])).abs() < 1e-9, "{w:?}");
        // Nothing to balance: one view, the balance off, views equally bright, no light.
        assert_eq!(view_weights(&g[..1], &[&dim], true), vec![1.0]);
        assert_eq!(view_weights(&g, &[&bright, &dim], false), vec![1.0; 2]);
        assert_eq!(view_weights(&g, &[&dim, &dim], true), vec![1.0; 2]);
        assert_eq!(view_weights(&g, &[&black, &black], true), vec![1.0; 2]);
        // A black view counts as one at the floor: a tenth of the views' mean.
        let w = view_weights(&g, &[&bright, &black], true);
        let floor = VIEW_WEIGHT_FLOOR * 0.2;
        assert!((w[1] / w[0] - 0.4 / floor).abs() < 1e-6, "{w:?}");
        // Uncovered pixels do not count toward a view's light.
        let mut half = fv.view();
        half.covered[..32].iter_mut().for_each(|c| *c = false);
        let mut lit = dim.clone();
        lit[..96].iter_mut().for_each(|x| *x = 5.0);
        let w = view_weights(&[v.gbuffer(), half.gbuffer()], &[&bright, &lit], true);
        assert!((w[1] / w[0] - 4.0).abs() < 1e-9, "{w:?}");
    }

    #[test]
    fn a_dim_view_is_refitted_to_its_own_light() {
        // Two captures of one floor that disagree: the bright one lit by some powers, the dim
        // one (a quarter as bright) by others. Summed pixel errors fit the bright one and leave
        // the dim one's relative error high; balanced, each view's relative error counts.
        let scene = closed_box(vec![]);
        let fv = FloorView::new(32, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let bright = render(
            &scene,
            &fv,
            &scaled(&base, &[0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0]),
        );
        let dim: Vec<f32> = render(
            &scene,
            &fv,
            &scaled(&base, &[2.0, 0.2, 1.0, 2.5, 0.1, 1.2, 0.5]),
        )
        .iter()
        .map(|x| 0.25 * x)
        .collect();
        let (vb, vd) = (fv.view_with(Some(&bright)), fv.view_with(Some(&dim)));
        let relative = |r: &Refitted, target: &[f32]| -> f64 {
            let got = render(&scene, &fv, &r.vpls);
            let err: f64 = got
                .iter()
                .zip(target)
                .map(|(a, b)| f64::from(a - b).powi(2))
                .sum();
            let norm: f64 = target.iter().map(|b| f64::from(*b).powi(2)).sum();
            (err / norm).sqrt()
        };
        let on = params(2, 1e-3);
        let off = RefitParams {
            balance_views: false,
            ..on
        };
        let balanced = refit(&scene, &[&vb, &vd], &base, &on, None).unwrap();
        let plain = refit(&scene, &[&vb, &vd], &base, &off, None).unwrap();
        assert_eq!(plain.view_weights, vec![1.0, 1.0]);
        let covered = fv.view().covered;
        let mean = |t: &[f32]| -> f64 {
            let lum = |p: usize| (0..3).map(move |c| LUMINANCE_F64[c] * f64::from(t[3 * p + c]));
            (0..covered.len())
                .filter(|&p| covered[p])
                .flat_map(lum)
                .sum()
        };
        let ratio = balanced.view_weights[1] / balanced.view_weights[0];
        assert!(
            (ratio - mean(&bright) / mean(&dim)).abs() < 1e-3 * ratio,
            "{ratio}"
        );
        let (dim_on, dim_off) = (relative(&balanced, &dim), relative(&plain, &dim));
        let (bright_on, bright_off) = (relative(&balanced, &bright), relative(&plain, &bright));
        assert!(
            dim_on < 0.8 * dim_off,
            "dim view: {dim_on} balanced, {dim_off} not"
        );
        assert!(
            bright_on > bright_off,
            "bright view: {bright_on} balanced, {bright_off} not"
        );
        // The worse of the two views' relative errors is lower balanced.
        assert!(dim_on.max(bright_on) < dim_off.max(bright_off));
    }

    #[test]
    fn frames_on_the_same_gbuffers_refit_as_each_alone() {
        // Three frames of one floor, each lit by other powers (a moving lamp): refitted at
        // once, each is what its refit alone gives, bit for bit, for every fold mode and group.
        let scene = closed_box(vec![crate::scene::Light::point(
            Vec3::new(0.2, 0.1, 1.5),
            Vec3::ONE,
        )]);
        let moved = closed_box(vec![crate::scene::Light::point(
            Vec3::new(-0.5, 0.3, 1.2),
            Vec3::ONE,
        )]);
        let fv = FloorView::new(64, Vec3::new(0.0, 0.0, 1.0), 10.0);
        let base = vpls();
        let powers: [&[f32]; 3] = [
            &[0.5, 2.0, 1.0, 0.0, 1.5, 0.8, 3.0],
            &[1.5, 0.5, 1.0, 2.0, 0.5, 0.8, 3.0],
            &[1.0, 1.0, 0.2, 0.5, 2.5, 0.1, 1.0],
        ];
        let views: Vec<View> = powers
            .iter()
            .map(|p| fv.view_with(Some(&render(&scene, &fv, &scaled(&base, p)))))
            .collect();
        let scenes = [&scene, &moved, &scene];
        // Each frame's second view a copy of its first dimmed by its own factor: the frames
        // weigh their views differently, and each keeps its own weights together as alone.
        let dimmed: Vec<View> = views
            .iter()
            .zip([0.3f32, 0.5, 0.3])
            .map(|(v, k)| {
                let target: Vec<f32> = v.indirect.as_ref().unwrap().iter().map(|x| k * x).collect();
                fv.view_with(Some(&target))
            })
            .collect();
        let pairs: Vec<Vec<&View>> = views.iter().zip(&dimmed).map(|(a, b)| vec![a, b]).collect();
        let refs: Vec<&[&View]> = pairs.iter().map(Vec::as_slice).collect();
        let together = refit_frames(&scenes, &refs, &[], &base, &PER_VPL, None).unwrap();
        for (f, got) in together.iter().enumerate() {
            let alone = refit(scenes[f], refs[f], &base, &PER_VPL, None).unwrap();
            assert_eq!(got.scales, alone.scales, "frame {f}");
            assert_eq!(got.view_weights, alone.view_weights);
            assert_eq!((got.cv.clone(), got.ridge), (alone.cv, alone.ridge));
            assert_eq!(got.error_after, alone.error_after);
        }
        let ratio = |r: &Refitted| r.view_weights[1] / r.view_weights[0];
        assert!((ratio(&together[0]) - 1.0 / 0.3).abs() < 1e-4);
        assert!((ratio(&together[1]) - 1.0 / 0.5).abs() < 1e-4);
        for params in [
            PER_VPL,
            RefitParams {
                stride: 2,
                group: 3,
                ..RefitParams::DEFAULT
            },
            params(3, 0.1),
        ] {
            for n_views in [1, 3] {
                // Frame f sees the floor n_views times (the leave-one-view-out folds at 3).
                let frames: Vec<Vec<&View>> = views.iter().map(|v| vec![v; n_views]).collect();
                let refs: Vec<&[&View]> = frames.iter().map(Vec::as_slice).collect();
                let together = refit_frames(&scenes, &refs, &[], &base, &params, None).unwrap();
                assert_eq!(together.len(), 3);
                for (f, got) in together.iter().enumerate() {
                    let alone = refit(scenes[f], refs[f], &base, &params, None).unwrap();
                    assert_eq!(got.scales, alone.scales, "frame {f}");
                    assert_eq!(got.vpls, alone.vpls);
                    assert_eq!(got.cv, alone.cv);
                    assert_eq!(got.gain_cv, alone.gain_cv);
                    assert_eq!(got.ridge, alone.ridge);
                    assert_eq!(got.error_after, alone.error_after);
                    assert_eq!(got.shadow_rays, alone.shadow_rays);
                }
                assert_ne!(together[0].scales, together[1].scales);
            }
        }
        // Another floor (a G-buffer that differs), other occluders, other view counts: errors.
        let mut elsewhere = views[1].clone();
        elsewhere.albedo[0] = 0.1;
        let p = PER_VPL;
        let err = refit_frames(
            &[&scene, &scene],
            &[&[&views[0]], &[&elsewhere]],
            &[],
            &base,
            &p,
            None,
        );
        assert!(matches!(err, Err(VplaceError::Invalid { .. })), "{err:?}");
        let (walled, _, _) = crate::test_util::emissive_cube_in_box();
        let err = refit_frames(
            &[&scene, &walled],
            &[&[&views[0]], &[&views[1]]],
            &[],
            &base,
            &p,
            None,
        );
        assert!(matches!(err, Err(VplaceError::Invalid { .. })), "{err:?}");
        let err = refit_frames(
            &[&scene, &scene],
            &[&[&views[0]], &[&views[1], &views[1]]],
            &[],
            &base,
            &p,
            None,
        );
        assert!(matches!(err, Err(VplaceError::Shape { .. })), "{err:?}");
        let err = refit_frames(
            &[&scene],
            &[&[&views[0]], &[&views[1]]],
            &[],
            &base,
            &p,
            None,
        );
        assert!(matches!(err, Err(VplaceError::Shape { .. })), "{err:?}");
        assert!(matches!(
            refit_frames(&[], &[], &[], &base, &p, None),
            Err(VplaceError::Empty { .. })
        ));
    }
}
