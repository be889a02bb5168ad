//! Multiple linear regression of the label on the features (DESIGN: Regression; paper 1, steps
//! 5-6), numerically sound and modelling only what the data needs.
//!
//! Model: `y = b0 + sum_j b_j x_j`, fitted by least squares on *standardized* columns
//! (`(x - mean) / std`); the coefficients are reported on the scale of the input columns.
//!
//! How it is solved (never the normal equations):
//! 1. Constant columns (`std <= 1e-13 max|x|`) are dropped ([`DropReason::Constant`]). A constant
//!    label makes every feature useless ([`DropReason::ConstantLabel`]).
//! 2. The rows are split into `folds` deterministic pseudo-random folds (fixed seed). Each fold's
//!    rows `[1 | X_std | y]` are reduced by a Householder QR (nalgebra; a tall-skinny QR over
//!    chunks of rows, in parallel) to a small triangular `R_f`; stacking and re-factoring the
//!    `R_f` gives the `R` of all rows, or of all rows but one fold. Since `Q` is orthogonal,
//!    `||A c - y|| = ||R (c, -1)||`: every later least-squares problem, for any subset of
//!    columns, is solved exactly on these small matrices.
//! 3. Collinear columns: in registry order, a column whose residual after projection on the
//!    columns already kept (and the intercept) is below `collinear_rtol` of its norm is dropped
//!    ([`DropReason::Collinear`]).
//! 4. Selection: backward elimination on k-fold cross-validated R^2 (pooled out-of-fold squared
//!    error over the total sum of squares). While some feature can be removed without lowering
//!    the CV R^2 by more than `min_cv_gain`, the one whose removal gives the highest CV R^2 is
//!    dropped ([`DropReason::NoCvGain`]). These many small fits use a column-pivoted QR with the
//!    rank read from its diagonal, and no ridge.
//! 5. The final fit: an SVD of the centered, standardized design of the kept columns gives the
//!    condition number and the rank (singular values below `rank_rtol * s_max` are zero); the
//!    solution comes from a column-pivoted QR (see `solve_small` for why not the SVD's
//!    vectors). Above `ridge_above` a ridge term `lambda` is added, chosen so that the
//!    regularized condition number `sqrt((s_max^2 + lambda) / (s_min^2 + lambda))` equals
//!    `ridge_above`.
//!
//! Weights `w_j = |b_j| / sum_k |b_k|` over the kept columns; all zero when every coefficient is
//! zero. `R^2 = 1 - SSE / SST`; for a constant label `R^2 = 1` when the fit is exact and `0`
//! otherwise (the scikit-learn convention). Adjusted R^2 is `None` when `n <= k + 1` (`k` kept
//! columns). Ridge threshold: `1e6` by default, since features computed from `f32` images carry
//! relative errors near `1e-7` and a condition number `c` amplifies them `c` times.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::error::{Result, VplaceError};
use crate::rng::Rng;

/// Largest magnitude accepted in a design or label: squares and sums of up to 1e8 rows of
/// such values stay finite in `f64`.
pub const MAX_MAGNITUDE: f64 = 1e150;

/// Relative spread below which a column (or the label) is constant: `std <= 1e-13 max|x|`.
pub const CONSTANT_RTOL: f64 = 1e-13;

/// Settings of [`fit`]. `Copy`, with named presets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitParams {
    /// Number of cross-validation folds for feature selection (`min(folds, rows)` are used);
    /// below 2 there is no CV selection. Default 5.
    pub folds: usize,
    /// Drop features by backward elimination on CV R^2 (step 4). Default true.
    pub select: bool,
    /// A feature is kept only if removing it lowers the CV R^2 by more than this (absolute R^2
    /// points, `>= 0`). Default `1e-3`.
    pub min_cv_gain: f64,
    /// Relative residual norm below which a column is collinear with the earlier ones, in
    /// `[0, 1)`; 0 turns the check off. Default `1e-6` (features come from `f32` images).
    pub collinear_rtol: f64,
    /// Relative singular value cut-off of the solve; `None` uses `max(n, p + 1) * eps` like
    /// LAPACK `gelsd` and `numpy.linalg.lstsq`.
    pub rank_rtol: Option<f64>,
    /// Condition number (of the standardized design) above which the ridge fallback is used;
    /// `> 1`, `f64::INFINITY` turns it off. Default `1e6`.
    pub ridge_above: f64,
    /// Seed of the fold assignment.
    pub seed: u64,
}

impl FitParams {
    /// The pipeline of the issue: constant, collinear and CV-useless features dropped.
    pub const DEFAULT: Self = Self {
        folds: 5,
        select: true,
        min_cv_gain: 1e-3,
        collinear_rtol: 1e-6,
        rank_rtol: None,
        ridge_above: 1e6,
        seed: 0x5eed,
    };
    /// Plain OLS as `numpy.linalg.lstsq` computes it (constant columns still dropped, since
    /// standardization needs a spread): no collinearity check, no selection, no ridge. On a
    /// rank-deficient design the fitted values equal lstsq's, the coefficients are the basic
    /// solution (dependent columns get 0) rather than the minimum-norm one.
    pub const PLAIN_OLS: Self = Self {
        folds: 0,
        select: false,
        min_cv_gain: 0.0,
        collinear_rtol: 0.0,
        rank_rtol: None,
        ridge_above: f64::INFINITY,
        seed: 0x5eed,
    };
}

impl Default for FitParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a feature is not in the model.
#[derive(Debug, Clone, PartialEq)]
pub enum DropReason {
    /// The input needed for it was not given (set by the caller, e.g. no light).
    Unavailable(&'static str),
    /// Left out by the caller's choice (e.g. a feature of the view when the model must hold
    /// from other views).
    Excluded(&'static str),
    /// Its values do not vary over the rows.
    Constant,
    /// The label is constant: no feature can explain anything.
    ConstantLabel,
    /// Its residual after projection on the kept columns `with` (indices) is `residual` of its
    /// norm, below `collinear_rtol`.
    Collinear {
        /// Relative residual norm.
        residual: f64,
        /// The columns kept before it, which explain it.
        with: Vec<usize>,
    },
    /// Removing it did not lower the cross-validated R^2 by more than `min_cv_gain`.
    NoCvGain {
        /// CV R^2 with it.
        cv_r2_with: f64,
        /// CV R^2 without it.
        cv_r2_without: f64,
    },
}

/// A fitted linear model and its diagnostics. Vectors indexed by input column.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// Number of input columns.
    pub p: usize,
    /// Number of rows fitted.
    pub n: usize,
    /// `b0`, on the input scale.
    pub intercept: f64,
    /// `b_j` on the input scale; 0 for dropped columns.
    pub coefficients: Vec<f64>,
    /// `|b_j| / sum |b_k|`; sums to 1, or all zero when every coefficient is zero.
    pub weights: Vec<f64>,
    /// Kept columns, ascending.
    pub kept: Vec<usize>,
    /// Dropped columns with the reason, in the order they were dropped.
    pub dropped: Vec<(usize, DropReason)>,
    /// Coefficient of determination on the fitted rows.
    pub r2: f64,
    /// `1 - (1 - R^2)(n - 1)/(n - k - 1)`, `None` when `n <= k + 1` (`k` kept columns).
    pub adjusted_r2: Option<f64>,
    /// Cross-validated R^2 of the final column set, when CV ran.
    pub cv_r2: Option<f64>,
    /// Folds used by CV (0 when it did not run).
    pub folds: usize,
    /// `s_max / s_min` of the centered standardized design of the kept columns (1 when none
    /// is kept; infinite when it is rank-deficient).
    pub condition_number: f64,
    /// Numerical rank of that design.
    pub rank: usize,
    /// Ridge term added to `s_i^2` (0 when the fallback was not used).
    pub ridge_lambda: f64,
    /// Fitted value of every row.
    pub fitted: Vec<f64>,
}

impl Fit {
    /// The prediction for each row of the row-major `x` (`rows x p`).
    pub fn predict(&self, x: &[f64]) -> Result<Vec<f64>> {
        if self.p == 0 || x.len() % self.p != 0 {
            return Err(VplaceError::Shape {
                what: "x".into(),
                expected: format!("a multiple of {} values", self.p),
                got: format!("{} values", x.len()),
            });
        }
        Ok(x.chunks_exact(self.p)
            .map(|row| self.predict_row(row))
            .collect())
    }

    /// The prediction for one row of `p` values (extra values are ignored, missing ones are 0).
    #[must_use]
    pub fn predict_row(&self, row: &[f64]) -> f64 {
        self.kept.iter().fold(self.intercept, |acc, &j| {
            acc + self.coefficients[j] * row.get(j).copied().unwrap_or(0.0)
        })
    }
}

/// A least-squares solution of a small problem.
struct Solved {
    b: DVector<f64>,
    cond: f64,
    rank: usize,
    lambda: f64,
}

/// Least squares `min ||m b - rhs||` (plus `lambda ||b||^2` for the ridge fallback).
///
/// The singular values (nalgebra SVD, values only) give the condition number and the rank. The
/// solution comes from a column-pivoted Householder QR (nalgebra `ColPivQR`), which stays
/// accurate to `cond * eps` where the SVD's singular vectors did not (measured: a 1e12-conditioned
/// 4 x 3 problem solved through `SVD::solve` was off by 1e9). For a numerically rank-deficient
/// `m` the leading `rank` pivoted columns are solved and the others get 0 (the basic solution;
/// its fitted values equal the minimum-norm solution's). The ridge solves the augmented problem
/// `[m; sqrt(lambda) I] b = [rhs; 0]` the same way, never the normal equations.
fn solve_small(m: DMatrix<f64>, rhs: &DVector<f64>, rtol: f64, ridge_above: f64) -> Result<Solved> {
    let s = m.ncols();
    if s == 0 {
        return Ok(Solved {
            b: DVector::zeros(0),
            cond: 1.0,
            rank: 0,
            lambda: 0.0,
        });
    }
    let r = m.nrows();
    let svd =
        nalgebra::SVD::try_new(m.clone(), false, false, f64::EPSILON, 10_000).ok_or_else(|| {
            VplaceError::Invalid {
                what: "least squares".into(),
                reason: "the SVD did not converge (the design holds extreme values)".into(),
            }
        })?;
    let sv = &svd.singular_values;
    let smax = sv.iter().copied().fold(0.0, f64::max);
    let smin = if r < s {
        0.0
    } else {
        sv.iter().copied().fold(f64::INFINITY, f64::min)
    };
    let tol = rtol * smax;
    let rank = sv.iter().filter(|&&x| x > tol && x > 0.0).count();
    // Numerically rank-deficient: the condition number is infinite, not `s_max / rounding`.
    let cond = if rank < s { f64::INFINITY } else { smax / smin };
    let lambda = if cond > ridge_above && smax > 0.0 {
        let t2 = ridge_above * ridge_above;
        ((smax * smax - t2 * smin * smin) / (t2 - 1.0)).max(0.0)
    } else {
        0.0
    };
    let b = if lambda > 0.0 {
        let mut aug = DMatrix::zeros(r + s, s);
        aug.rows_mut(0, r).copy_from(&m);
        for i in 0..s {
            aug[(r + i, i)] = lambda.sqrt();
        }
        let mut rhs_aug = DVector::zeros(r + s);
        rhs_aug.rows_mut(0, r).copy_from(rhs);
        pivoted_solve(aug, rhs_aug, Some(s), 0.0).0
    } else {
        pivoted_solve(m, rhs.clone(), Some(rank), 0.0).0
    };
    Ok(Solved {
        b,
        cond,
        rank,
        lambda,
    })
}

/// Solves `min ||m b - rhs||` on the first `rank` pivoted columns of a column-pivoted QR of
/// `m`. With `rank = None` the rank is read from the QR's diagonal (`|R_ii| > rtol |R_00|`):
/// the many small fits of cross-validation use that, where an SVD would dominate the cost.
/// Returns the solution and the rank used.
fn pivoted_solve(
    m: DMatrix<f64>,
    mut rhs: DVector<f64>,
    rank: Option<usize>,
    rtol: f64,
) -> (DVector<f64>, usize) {
    let s = m.ncols();
    let mut b = DVector::zeros(s);
    if s == 0 || m.nrows() == 0 || rank == Some(0) {
        return (b, 0);
    }
    let qr = nalgebra::ColPivQR::new(m);
    qr.q_tr_mul(&mut rhs);
    let r = qr.r();
    let diag = r.nrows().min(s);
    let rank = rank.unwrap_or_else(|| {
        let d0 = r[(0, 0)].abs();
        (0..diag)
            .take_while(|&i| r[(i, i)].abs() > rtol * d0 && r[(i, i)] != 0.0)
            .count()
    });
    let rank = rank.min(diag);
    if rank == 0 {
        return (b, 0);
    }
    let tri = r.view((0, 0), (rank, rank));
    let mut top = rhs.rows(0, rank).clone_owned();
    if tri.solve_upper_triangular_mut(&mut top) {
        b.rows_mut(0, rank).copy_from(&top);
    }
    qr.p().inv_permute_rows(&mut b);
    (b, rank)
}

/// Rows per chunk of the tall-skinny QR (256 x 16 doubles = 32 KiB, about L1 size; measured
/// faster than 1024 on the 8,100 x 14 benchmark).
const CHUNK: usize = 256;

/// The `R` of a Householder QR of `a` (at most `a.ncols()` rows).
fn r_of(a: DMatrix<f64>) -> DMatrix<f64> {
    if a.nrows() == 0 {
        return DMatrix::zeros(0, a.ncols());
    }
    nalgebra::QR::new(a).r()
}

fn stack(blocks: &[&DMatrix<f64>], ncols: usize) -> DMatrix<f64> {
    let rows: usize = blocks.iter().map(|b| b.nrows()).sum();
    let mut out = DMatrix::zeros(rows, ncols);
    let mut at = 0;
    for b in blocks {
        out.rows_mut(at, b.nrows()).copy_from(b);
        at += b.nrows();
    }
    out
}

/// `m[.., cols]` restricted to rows `from..`.
fn columns(m: &DMatrix<f64>, from: usize, cols: &[usize]) -> DMatrix<f64> {
    let rows = m.nrows().saturating_sub(from);
    DMatrix::from_fn(rows, cols.len(), |i, k| m[(from + i, cols[k])])
}

/// Fits the intercept and columns `set` (indices into the `[1 | X | y]` block layout, i.e.
/// column `j` of X is block column `j + 1`) on the rows summarized by `r`. Returns
/// `(c0, b, solved)`.
fn fit_on(
    r: &DMatrix<f64>,
    set: &[usize],
    ycol: usize,
    params: &Params,
    cv: bool,
) -> Result<(f64, DVector<f64>, Solved)> {
    let m = columns(r, 1, set);
    let rhs = DVector::from_fn(r.nrows().saturating_sub(1), |i, _| r[(i + 1, ycol)]);
    let solved = if cv {
        let (b, rank) = pivoted_solve(m, rhs, None, params.rtol);
        Solved {
            b,
            cond: f64::NAN,
            rank,
            lambda: 0.0,
        }
    } else {
        solve_small(m, &rhs, params.rtol, params.ridge_above)?
    };
    let mut top = r[(0, ycol)];
    for (k, &c) in set.iter().enumerate() {
        top -= r[(0, c)] * solved.b[k];
    }
    let c0 = if r[(0, 0)] != 0.0 {
        top / r[(0, 0)]
    } else {
        0.0
    };
    let b = solved.b.clone();
    Ok((c0, b, solved))
}

struct Params {
    rtol: f64,
    ridge_above: f64,
}

/// Pooled out-of-fold R^2 of the column set `set`.
fn cv_r2(
    train: &[DMatrix<f64>],
    test: &[DMatrix<f64>],
    set: &[usize],
    ycol: usize,
    sst: f64,
    params: &Params,
) -> Result<f64> {
    let mut sse = 0.0;
    for (tr, te) in train.iter().zip(test) {
        let (c0, b, _) = fit_on(tr, set, ycol, params, true)?;
        for i in 0..te.nrows() {
            let mut r = te[(i, 0)] * c0 - te[(i, ycol)];
            for (k, &c) in set.iter().enumerate() {
                r += te[(i, c)] * b[k];
            }
            sse += r * r;
        }
    }
    Ok(1.0 - sse / sst)
}

fn validate(x: &[f64], y: &[f64], p: usize, params: &FitParams) -> Result<usize> {
    let n = y.len();
    if n == 0 {
        return Err(VplaceError::Empty {
            what: "rows".into(),
            hint: "fit needs at least one row".into(),
        });
    }
    if p == 0 || x.len() != n * p {
        return Err(VplaceError::Shape {
            what: "x".into(),
            expected: format!("({n}, p) with p >= 1 ({n} labels)"),
            got: format!("{} values for p = {p}", x.len()),
        });
    }
    if let Some(index) = x.iter().position(|v| !v.is_finite()) {
        return Err(VplaceError::NonFinite {
            what: "x".into(),
            index,
        });
    }
    if let Some(index) = y.iter().position(|v| !v.is_finite()) {
        return Err(VplaceError::NonFinite {
            what: "y".into(),
            index,
        });
    }
    // Sums of squares of larger values overflow f64 (found by the fuzzer: labels of 1e300
    // gave NaN coefficients): refuse them with a clear message rather than return NaN.
    for (what, values) in [("x", x), ("y", y)] {
        if let Some(index) = values.iter().position(|v| v.abs() > MAX_MAGNITUDE) {
            return Err(VplaceError::OutOfRange {
                what: format!("{what}[{index}]"),
                value: values[index].to_string(),
                expected: format!("|value| <= {MAX_MAGNITUDE:e}: rescale the data"),
            });
        }
    }
    let range = |what: &str, v: f64, ok: bool, expected: &str| {
        if ok {
            Ok(())
        } else {
            Err(VplaceError::OutOfRange {
                what: what.into(),
                value: v.to_string(),
                expected: expected.into(),
            })
        }
    };
    let g = params.min_cv_gain;
    range(
        "min_cv_gain",
        g,
        g.is_finite() && g >= 0.0,
        "finite and >= 0",
    )?;
    let c = params.collinear_rtol;
    range("collinear_rtol", c, (0.0..1.0).contains(&c), "in [0, 1)")?;
    if let Some(t) = params.rank_rtol {
        range("rank_rtol", t, (0.0..1.0).contains(&t), "in [0, 1)")?;
    }
    let ra = params.ridge_above;
    range(
        "ridge_above",
        ra,
        ra > 1.0,
        "> 1 (inf turns the ridge fallback off)",
    )?;
    Ok(n)
}

fn mean_std(values: impl Iterator<Item = f64> + Clone, n: usize) -> (f64, f64, f64) {
    let mean = values.clone().sum::<f64>() / n as f64;
    let var = values.clone().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64;
    let max_abs = values.map(f64::abs).fold(0.0, f64::max);
    (mean, var.sqrt(), max_abs)
}

/// `(mean, std, max |x|)` of every column of the row-major `x`, two passes over the rows.
fn column_stats(x: &[f64], p: usize, n: usize) -> Vec<(f64, f64, f64)> {
    let mut mean = vec![0.0; p];
    let mut max_abs = vec![0.0f64; p];
    for row in x.chunks_exact(p) {
        for j in 0..p {
            mean[j] += row[j];
            max_abs[j] = max_abs[j].max(row[j].abs());
        }
    }
    mean.iter_mut().for_each(|m| *m /= n as f64);
    let mut var = vec![0.0; p];
    for row in x.chunks_exact(p) {
        for j in 0..p {
            let d = row[j] - mean[j];
            var[j] += d * d;
        }
    }
    (0..p)
        .map(|j| (mean[j], (var[j] / n as f64).sqrt(), max_abs[j]))
        .collect()
}

fn is_constant(std: f64, max_abs: f64) -> bool {
    std <= CONSTANT_RTOL * max_abs
}

/// Fits `y` on the `p` columns of the row-major `x` (`n x p`, `n = y.len()`); see the module
/// doc for the steps. Errors on bad shapes, non-finite values and out-of-range settings.
pub fn fit(x: &[f64], y: &[f64], p: usize, params: &FitParams) -> Result<Fit> {
    let n = validate(x, y, p, params)?;
    let stats = column_stats(x, p, n);
    let (ymean, ystd, ymax) = mean_std(y.iter().copied(), n);
    let sst: f64 = y.iter().map(|v| (v - ymean) * (v - ymean)).sum();

    // Step 1: constant columns (and every column when the label is constant).
    let label_constant = is_constant(ystd, ymax);
    let (cand, mut dropped) = screen_columns(&stats, label_constant);
    let c = cand.len();
    let solve_params = Params {
        rtol: params
            .rank_rtol
            .unwrap_or(n.max(c + 1) as f64 * f64::EPSILON),
        ridge_above: params.ridge_above,
    };

    // Step 2: fold assignment and per-fold QR of [1 | X_std | y].
    let k = if params.select && !cand.is_empty() {
        params.folds.min(n)
    } else {
        1
    };
    let k = if k < 2 { 1 } else { k };
    let fold_rows = assign_folds(n, k, params.seed);
    let scale: Vec<(f64, f64)> = cand.iter().map(|&j| (stats[j].0, stats[j].1)).collect();
    let design = Design {
        x,
        y,
        p,
        cand: &cand,
        scale: &scale,
    };
    let (blocks, r_full) = fold_factors(&design, &fold_rows);

    // Step 3: collinear columns, in order.
    let set = drop_collinear(&r_full, &cand, params, &solve_params, &mut dropped)?;

    // Step 4: backward elimination on CV R^2.
    let (set, cv) = if k >= 2 && sst > 0.0 {
        let (set, current) = select_by_cv(
            &blocks,
            set,
            &cand,
            sst,
            params,
            &solve_params,
            &mut dropped,
        )?;
        (set, Some(current))
    } else {
        (set, None)
    };

    // Step 5: the final fit.
    let (c0, b, solved) = fit_on(&r_full, &set, c + 1, &solve_params, false)?;
    let (intercept, coefficients, kept) = unscale(c0, &b, &set, &design, ymean);
    let total: f64 = kept.iter().map(|&j| coefficients[j].abs()).sum();
    let weights: Vec<f64> = coefficients
        .iter()
        .map(|b| if total > 0.0 { b.abs() / total } else { 0.0 })
        .collect();
    let mut model = Fit {
        p,
        n,
        intercept,
        coefficients,
        weights,
        kept,
        dropped,
        r2: 0.0,
        adjusted_r2: None,
        cv_r2: cv,
        folds: if k >= 2 && sst > 0.0 { k } else { 0 },
        condition_number: if set.is_empty() { 1.0 } else { solved.cond },
        rank: solved.rank,
        ridge_lambda: solved.lambda,
        fitted: Vec::new(),
    };
    score(&mut model, x, y, sst, label_constant, ymax);
    // A safety net: never hand back a silent NaN.
    let finite = model.intercept.is_finite()
        && model.coefficients.iter().all(|v| v.is_finite())
        && model.fitted.iter().all(|v| v.is_finite())
        && model.r2.is_finite();
    if !finite {
        return Err(VplaceError::Invalid {
            what: "fit".into(),
            reason: "the solution overflowed f64: rescale x and y to moderate magnitudes".into(),
        });
    }
    Ok(model)
}

/// The design of one fit: `x` (`n x p`, row-major), `y`, the candidate columns and their
/// `(mean, std)` standardization.
struct Design<'a> {
    x: &'a [f64],
    y: &'a [f64],
    p: usize,
    cand: &'a [usize],
    scale: &'a [(f64, f64)],
}

/// Step 1: the candidate columns, and the constant ones (every one with a constant label)
/// dropped in column order.
fn screen_columns(
    stats: &[(f64, f64, f64)],
    label_constant: bool,
) -> (Vec<usize>, Vec<(usize, DropReason)>) {
    let mut dropped: Vec<(usize, DropReason)> = Vec::new();
    let mut cand: Vec<usize> = Vec::new();
    for (j, &(_, std, max_abs)) in stats.iter().enumerate() {
        if is_constant(std, max_abs) {
            dropped.push((j, DropReason::Constant));
        } else if label_constant {
            dropped.push((j, DropReason::ConstantLabel));
        } else {
            cand.push(j);
        }
    }
    (cand, dropped)
}

/// The rows of each of `k` folds: a seeded shuffle of `0..n`, dealt round robin.
fn assign_folds(n: usize, k: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..n).collect();
    let mut rng = Rng::new(seed, 11);
    for i in (1..n).rev() {
        let r = (rng.next_u32() as usize) % (i + 1);
        order.swap(i, r);
    }
    let mut fold_rows: Vec<Vec<usize>> = vec![Vec::new(); k];
    for (pos, &row) in order.iter().enumerate() {
        fold_rows[pos % k].push(row);
    }
    fold_rows
}

/// Step 2: the `R` factor of `[1 | X_std | y]` over each fold's rows and over all rows.
/// Tall-skinny QR: chunks of at most [`CHUNK`] rows are factored in parallel, then their `R`s.
fn fold_factors(d: &Design<'_>, fold_rows: &[Vec<usize>]) -> (Vec<DMatrix<f64>>, DMatrix<f64>) {
    let (c, k) = (d.cand.len(), fold_rows.len());
    let ycol = c + 1;
    let chunks: Vec<(usize, &[usize])> = fold_rows
        .iter()
        .enumerate()
        .flat_map(|(f, rows)| rows.chunks(CHUNK).map(move |ch| (f, ch)))
        .collect();
    let chunk_r: Vec<(usize, DMatrix<f64>)> = chunks
        .par_iter()
        .map(|&(f, rows)| {
            let mut a = DMatrix::zeros(rows.len(), c + 2);
            for (i, &row) in rows.iter().enumerate() {
                a[(i, 0)] = 1.0;
                a[(i, ycol)] = d.y[row];
                let xr = &d.x[row * d.p..(row + 1) * d.p];
                for (ci, &j) in d.cand.iter().enumerate() {
                    let (m, s) = d.scale[ci];
                    a[(i, ci + 1)] = (xr[j] - m) / s;
                }
            }
            (f, r_of(a))
        })
        .collect();
    let blocks: Vec<DMatrix<f64>> = (0..k)
        .map(|f| {
            let mine: Vec<&DMatrix<f64>> = chunk_r
                .iter()
                .filter(|(g, _)| *g == f)
                .map(|(_, r)| r)
                .collect();
            if mine.len() == 1 {
                mine[0].clone()
            } else {
                r_of(stack(&mine, c + 2))
            }
        })
        .collect();
    let all: Vec<&DMatrix<f64>> = blocks.iter().collect();
    let r_full = if k == 1 {
        blocks[0].clone()
    } else {
        r_of(stack(&all, c + 2))
    };
    (blocks, r_full)
}

/// Step 3: the block columns (`candidate index + 1`) kept after dropping, in order, each
/// candidate whose residual on the kept ones is below `collinear_rtol`.
fn drop_collinear(
    r_full: &DMatrix<f64>,
    cand: &[usize],
    params: &FitParams,
    solve_params: &Params,
    dropped: &mut Vec<(usize, DropReason)>,
) -> Result<Vec<usize>> {
    let mut set: Vec<usize> = Vec::new(); // block columns (j + 1)
    for (ci, &j) in cand.iter().enumerate() {
        let bc = ci + 1;
        if params.collinear_rtol > 0.0 {
            let target =
                DVector::from_fn(r_full.nrows().saturating_sub(1), |i, _| r_full[(i + 1, bc)]);
            let norm = target.norm();
            let residual = if set.is_empty() || norm == 0.0 {
                if norm == 0.0 {
                    0.0
                } else {
                    1.0
                }
            } else {
                let m = columns(r_full, 1, &set);
                let solved = solve_small(m.clone(), &target, solve_params.rtol, f64::INFINITY)?;
                (m * solved.b - &target).norm() / norm
            };
            if residual < params.collinear_rtol {
                let with = set.iter().map(|&b| cand[b - 1]).collect();
                dropped.push((j, DropReason::Collinear { residual, with }));
                continue;
            }
        }
        set.push(bc);
    }
    Ok(set)
}

/// Step 4: backward elimination: while removing a column loses at most `min_cv_gain` of the
/// CV R^2, the column whose removal leaves the best CV R^2 goes. Returns the kept block
/// columns and their CV R^2.
fn select_by_cv(
    blocks: &[DMatrix<f64>],
    mut set: Vec<usize>,
    cand: &[usize],
    sst: f64,
    params: &FitParams,
    solve_params: &Params,
    dropped: &mut Vec<(usize, DropReason)>,
) -> Result<(Vec<usize>, f64)> {
    let (c, k) = (cand.len(), blocks.len());
    let ycol = c + 1;
    let train: Vec<DMatrix<f64>> = (0..k)
        .into_par_iter()
        .map(|f| {
            let others: Vec<&DMatrix<f64>> = blocks
                .iter()
                .enumerate()
                .filter(|&(g, _)| g != f)
                .map(|(_, b)| b)
                .collect();
            r_of(stack(&others, c + 2))
        })
        .collect();
    let mut current = cv_r2(&train, blocks, &set, ycol, sst, solve_params)?;
    while !set.is_empty() {
        let without: Vec<Result<f64>> = (0..set.len())
            .into_par_iter()
            .map(|i| {
                let mut s = set.clone();
                s.remove(i);
                cv_r2(&train, blocks, &s, ycol, sst, solve_params)
            })
            .collect();
        let mut best: Option<(usize, f64)> = None;
        for (i, r) in without.into_iter().enumerate() {
            let r = r?;
            if best.is_none_or(|(_, b)| r >= b) {
                best = Some((i, r));
            }
        }
        let Some((i, r)) = best else { break };
        if current - r > params.min_cv_gain {
            break;
        }
        let j = cand[set[i] - 1];
        dropped.push((
            j,
            DropReason::NoCvGain {
                cv_r2_with: current,
                cv_r2_without: r,
            },
        ));
        set.remove(i);
        current = r;
    }
    Ok((set, current))
}

/// Step 5: the intercept and the coefficients on the raw columns from the standardized
/// solution `(c0, b)` of the block columns `set`, and the kept columns in column order.
fn unscale(
    c0: f64,
    b: &DVector<f64>,
    set: &[usize],
    d: &Design<'_>,
    ymean: f64,
) -> (f64, Vec<f64>, Vec<usize>) {
    let mut coefficients = vec![0.0; d.p];
    let mut intercept = c0;
    let mut kept: Vec<usize> = Vec::with_capacity(set.len());
    for (kk, &bc) in set.iter().enumerate() {
        let j = d.cand[bc - 1];
        let (m, s) = d.scale[bc - 1];
        coefficients[j] = b[kk] / s;
        intercept -= b[kk] * m / s;
        kept.push(j);
    }
    if set.is_empty() {
        intercept = ymean;
    }
    kept.sort_unstable();
    (intercept, coefficients, kept)
}

/// The fitted values, R^2 and adjusted R^2 of `model` on `x`, `y`.
fn score(model: &mut Fit, x: &[f64], y: &[f64], sst: f64, label_constant: bool, ymax: f64) {
    let n = model.n;
    model.fitted = x
        .chunks_exact(model.p)
        .map(|row| model.predict_row(row))
        .collect();
    let sse: f64 = model
        .fitted
        .iter()
        .zip(y)
        .map(|(f, v)| (f - v) * (f - v))
        .sum();
    model.r2 = if sst > 0.0 && !label_constant {
        1.0 - sse / sst
    } else if sse <= (CONSTANT_RTOL * ymax).powi(2) * n as f64 {
        1.0
    } else {
        0.0
    };
    let kk = model.kept.len();
    model.adjusted_r2 =
        (n > kk + 1).then(|| 1.0 - (1.0 - model.r2) * (n - 1) as f64 / (n - kk - 1) as f64);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by `examples/fuzz.rs` (seed 1, case 115774): a label of 1e300 gave NaN
    /// coefficients and an `Ok`. Now a clear error.
    #[test]
    fn huge_labels_are_an_error_not_nan() {
        let x = [
            -4e-20, -3.9e-5, -4.9e-22, -48.8, 353.4, 7.4e-309, 7.4e-309, 0.0,
        ];
        let y = [-3e-14, 0.12, 0.17, -1.3e-18, 1e300, 0.91, 0.13, 0.014];
        for params in [FitParams::DEFAULT, FitParams::PLAIN_OLS] {
            let err = fit(&x, &y, 1, &params).unwrap_err();
            assert!(matches!(err, VplaceError::OutOfRange { ref what, .. } if what == "y[4]"));
        }
        let y = [0.0, 1.0, 0.5, 0.2, 1e149, 0.3, 0.1, 0.7];
        match fit(&x, &y, 1, &FitParams::PLAIN_OLS) {
            Ok(f) => assert!(f.coefficients.iter().all(|v| v.is_finite())),
            Err(e) => assert!(matches!(e, VplaceError::Invalid { .. }), "{e}"),
        }
    }

    fn design(n: usize, p: usize, seed: u64) -> Vec<f64> {
        let mut rng = Rng::new(seed, 3);
        (0..n * p)
            .map(|_| f64::from(rng.next_f32()) - 0.5)
            .collect()
    }

    fn labels(x: &[f64], p: usize, b: &[f64], b0: f64) -> Vec<f64> {
        x.chunks_exact(p)
            .map(|r| b0 + r.iter().zip(b).map(|(a, c)| a * c).sum::<f64>())
            .collect()
    }

    fn check_invariants(f: &Fit) {
        assert!(f.intercept.is_finite() && f.r2.is_finite());
        assert!(f
            .coefficients
            .iter()
            .chain(&f.weights)
            .chain(&f.fitted)
            .all(|v| v.is_finite()));
        let s: f64 = f.weights.iter().sum();
        assert!(
            (s - 1.0).abs() < 1e-12 || f.weights.iter().all(|&w| w == 0.0),
            "weights sum {s}"
        );
        assert_eq!(f.kept.len() + f.dropped.len(), f.p);
    }

    #[test]
    fn exact_linear_model_is_recovered() {
        for n in [200, 2 * CHUNK + 77] {
            exact_linear_model_is_recovered_with(n);
        }
    }

    fn exact_linear_model_is_recovered_with(n: usize) {
        let p = 4;
        let x = design(n, p, 1);
        let y = labels(&x, p, &[1.0, -2.0, 0.5, 3.0], 0.25);
        for params in [FitParams::DEFAULT, FitParams::PLAIN_OLS] {
            let f = fit(&x, &y, p, &params).unwrap();
            check_invariants(&f);
            assert_eq!(f.kept, vec![0, 1, 2, 3]);
            for (a, b) in f.coefficients.iter().zip([1.0, -2.0, 0.5, 3.0]) {
                assert!((a - b).abs() < 1e-10, "{a} vs {b}");
            }
            assert!((f.intercept - 0.25).abs() < 1e-10);
            assert!((f.r2 - 1.0).abs() < 1e-12);
            assert!(f.condition_number < 10.0);
        }
    }

    #[test]
    fn constant_duplicate_and_collinear_columns_are_dropped() {
        let n = 100;
        let base = design(n, 2, 2);
        let mut x = Vec::new();
        for r in base.chunks_exact(2) {
            x.extend_from_slice(&[r[0], 7.0, r[1], r[0], r[0] + r[1]]);
        }
        let y = labels(&x, 5, &[2.0, 0.0, -1.0, 0.0, 0.0], 1.0);
        let f = fit(&x, &y, 5, &FitParams::DEFAULT).unwrap();
        check_invariants(&f);
        assert_eq!(f.kept, vec![0, 2]);
        assert!(f.dropped.contains(&(1, DropReason::Constant)));
        assert!(f.dropped.iter().any(|(j, r)| *j == 3
            && matches!(r, DropReason::Collinear { with, .. } if with == &vec![0, 2])));
        assert!(f
            .dropped
            .iter()
            .any(|(j, r)| *j == 4 && matches!(r, DropReason::Collinear { .. })));
        assert!((f.coefficients[0] - 2.0).abs() < 1e-9 && (f.coefficients[2] + 1.0).abs() < 1e-9);
    }

    #[test]
    fn useless_features_are_dropped_by_cv() {
        let (n, p) = (400, 3);
        let x = design(n, p, 3);
        let mut rng = Rng::new(9, 1);
        let y: Vec<f64> = x
            .chunks_exact(p)
            .map(|r| 3.0 * r[0] + 0.01 * (f64::from(rng.next_f32()) - 0.5))
            .collect();
        let f = fit(&x, &y, p, &FitParams::DEFAULT).unwrap();
        check_invariants(&f);
        assert_eq!(f.kept, vec![0]);
        assert!(f
            .dropped
            .iter()
            .all(|(_, r)| matches!(r, DropReason::NoCvGain { .. })));
        assert_eq!(f.weights[0], 1.0);
        assert!(f.cv_r2.unwrap() > 0.99);
    }

    #[test]
    fn degenerate_inputs() {
        // Single row: everything constant, intercept only.
        let f = fit(&[1.0, 2.0], &[3.0], 2, &FitParams::DEFAULT).unwrap();
        check_invariants(&f);
        assert!(f.kept.is_empty() && f.intercept == 3.0 && f.adjusted_r2.is_none());
        // All labels zero.
        let x = design(50, 3, 4);
        let f = fit(&x, &[0.0; 50], 3, &FitParams::DEFAULT).unwrap();
        check_invariants(&f);
        assert!(f.weights.iter().all(|&w| w == 0.0) && f.r2 == 1.0);
        // More columns than rows.
        let x = design(5, 12, 5);
        let y: Vec<f64> = (0..5).map(|i| i as f64).collect();
        for params in [FitParams::DEFAULT, FitParams::PLAIN_OLS] {
            let f = fit(&x, &y, 12, &params).unwrap();
            check_invariants(&f);
        }
        // Errors, not panics.
        assert!(matches!(
            fit(&[f64::NAN], &[1.0], 1, &FitParams::DEFAULT),
            Err(VplaceError::NonFinite { .. })
        ));
        assert!(matches!(
            fit(&[1.0], &[f64::INFINITY], 1, &FitParams::DEFAULT),
            Err(VplaceError::NonFinite { .. })
        ));
        assert!(matches!(
            fit(&[1.0, 2.0], &[1.0], 1, &FitParams::DEFAULT),
            Err(VplaceError::Shape { .. })
        ));
        assert!(matches!(
            fit(&[], &[], 1, &FitParams::DEFAULT),
            Err(VplaceError::Empty { .. })
        ));
        let bad = FitParams {
            ridge_above: 0.5,
            ..FitParams::DEFAULT
        };
        assert!(matches!(
            fit(&[1.0], &[1.0], 1, &bad),
            Err(VplaceError::OutOfRange { .. })
        ));
    }

    #[test]
    fn ridge_fallback_caps_the_condition_number() {
        let n = 300;
        let base = design(n, 2, 6);
        let mut x = Vec::new();
        for r in base.chunks_exact(2) {
            x.extend_from_slice(&[r[0], r[1], r[0] + 1e-9 * r[1]]);
        }
        let y = labels(&x, 3, &[1.0, 1.0, 1.0], 0.0);
        let params = FitParams {
            collinear_rtol: 0.0,
            select: false,
            ..FitParams::DEFAULT
        };
        let f = fit(&x, &y, 3, &params).unwrap();
        check_invariants(&f);
        assert!(f.condition_number > 1e8 && f.ridge_lambda > 0.0);
        assert!(f.r2 > 0.999);
    }

    #[test]
    fn predict_matches_fitted() {
        let x = design(60, 3, 8);
        let y = labels(&x, 3, &[1.0, 2.0, 3.0], -1.0);
        let f = fit(&x, &y, 3, &FitParams::PLAIN_OLS).unwrap();
        assert_eq!(f.predict(&x).unwrap(), f.fitted);
        assert!(f.predict(&[1.0]).is_err());
    }
}
