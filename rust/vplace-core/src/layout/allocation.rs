//! The budget split over the strata: the uniform and guided shares, their blend and the
//! rounding by largest remainder, with the pool of strata that hold flux but got no VPL.

use super::*;

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
pub(super) fn largest(counts: &[usize]) -> (usize, usize) {
    let (k, &most) = counts
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        .expect("at least one stratum");
    (k, most)
}

/// The least part of its light-path share that a stratum the views see gets, whatever its
/// predicted importance: the strata the views see split what they get together (the sum of
/// their shares) at least this much in proportion to their flux, before the weights are
/// normalized again.
///
/// Without it a sparsely drawn stratum's few VPLs each carry its whole flux: one VPL of a sunlit
/// window reveal carried 14 times the mean light-path VPL's flux in the L room and drew the hard
/// edge of its aperture across a view no capture saw. With it a VPL of a stratum the views see
/// carries at most about `(1 + f) / f` times (3 times) the flux of a light-path VPL. 0.5 was
/// measured against 0 and 1 with the refit, 8 seeds (ARCHITECTURE.md, "Layout strata and
/// flux"): at 0.5 every view of the four rooms gained or stayed within .0002 and Sponza's views
/// moved within their seeds' spread; 0.25 gained less, and at 1 one seed of a sky-room view had
/// 0.145 % hot pixels.
pub const LIGHT_PATH_FLOOR: f64 = 0.5;

/// Splits `budget` over the strata by largest remainder of `budget * shares`, each stratum the
/// views see raised first to [`LIGHT_PATH_FLOOR`] of its light-path share, then pools the
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
    let seen = |k: usize| lum[k] > 0.0 && strata.view_weight[k] > 0.0;
    let seen_lum: f64 = (0..lum.len()).filter(|&k| seen(k)).map(|k| lum[k]).sum();
    let seen_share: f64 = (0..lum.len()).filter(|&k| seen(k)).map(|k| shares[k]).sum();
    // A stratum without flux cannot emit, whatever its share; each stratum the views see gets
    // at least `LIGHT_PATH_FLOOR` of its light-path part of what those strata get together (a
    // no-op when the shares follow the flux).
    let w: Vec<f64> = (0..lum.len())
        .map(|k| {
            if lum[k] <= 0.0 {
                0.0
            } else if seen(k) {
                shares[k].max(LIGHT_PATH_FLOOR * seen_share * lum[k] / seen_lum)
            } else {
                shares[k]
            }
        })
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
