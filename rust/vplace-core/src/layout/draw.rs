//! Flux-proportional systematic draws of the allocated VPLs inside each stratum (or pooled
//! group).

use super::*;

/// Draws `n` emitters of `group` (stratum ranges) by luminance flux with systematic sampling
/// (one random offset); each VPL carries the luminance `lum(group) / n` with its emitter's colour,
/// times [`Strata::pixel_flux_scale`] where the emitter is a pixel's (a cell's).
pub(super) fn draw_group(
    strata: &Strata,
    group: &[usize],
    n: usize,
    rng: &mut Rng,
    out: &mut Vec<Vpl>,
) {
    if n == 0 {
        return;
    }
    let cells = strata.offscreen();
    let items = || {
        group.iter().flat_map(move |&k| {
            let scale = if k < cells {
                strata.pixel_flux_scale
            } else {
                1.0
            };
            strata.emitters[strata.start[k]..strata.start[k + 1]]
                .iter()
                .map(move |e| (e, scale))
        })
    };
    let total: f64 = items().map(|(e, _)| f64::from(luminance(e.flux))).sum();
    if total.is_nan() || total <= 0.0 {
        return;
    }
    let per = total / n as f64;
    let r = f64::from(rng.next_f32());
    let mut acc = 0.0f64;
    let mut i = 0usize;
    let mut last = None;
    for (e, scale) in items() {
        let l = f64::from(luminance(e.flux));
        acc += l;
        last = Some((e, scale));
        while i < n && (i as f64 + r) * per < acc {
            out.push(Vpl {
                position: e.position,
                normal: e.normal,
                flux: e.flux * (per / l) as f32 * scale,
            });
            i += 1;
        }
    }
    // Rounding can leave the last target just past the end of the sum.
    if let Some((e, scale)) = last {
        let l = f64::from(luminance(e.flux));
        while i < n {
            out.push(Vpl {
                position: e.position,
                normal: e.normal,
                flux: e.flux * (per / l) as f32 * scale,
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
