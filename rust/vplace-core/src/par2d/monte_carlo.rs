//! `monte_carlo`: the 2D ray casting baseline. Uniform random directions (i.i.d., 53-bit
//! angles from PCG32), the nearest polygon along each ray gives its emission; the mean over
//! rays estimates the same fluence / 2 pi as the analytic methods (no cosine term).

use glam::DVec2;

use super::geometry::{cross, View};
use crate::rng::Rng;

/// A uniform `f64` in `[0, 1)` with 53 random bits.
fn next_f64(rng: &mut Rng) -> f64 {
    let hi = u64::from(rng.next_u32()) << 21;
    let lo = u64::from(rng.next_u32() >> 11);
    (hi | lo) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Mean and standard error per channel of `rays` rays from `p` (outside every polygon).
/// `views[j]`, `depth[j]` (near, far) and `front[ranges[j]]` are polygon `j`'s view, distance
/// bounds and front-edge indices.
#[allow(clippy::too_many_arguments)]
pub(crate) fn estimate(
    p: DVec2,
    polygons: &[&[DVec2]],
    emission: &[[f64; 3]],
    views: &[Option<View>],
    depth: &[(f64, f64)],
    front: &[u32],
    ranges: &[(u32, u32)],
    rays: u32,
    rng: &mut Rng,
) -> ([f64; 3], [f64; 3]) {
    let mut sum = [0.0f64; 3];
    let mut sum_sq = [0.0f64; 3];
    for _ in 0..rays {
        let theta = std::f64::consts::TAU * next_f64(rng);
        let u = DVec2::from_angle(theta);
        let mut best_t = f64::INFINITY;
        let mut best = None;
        for (j, vj) in views.iter().enumerate() {
            let Some(vj) = vj else { continue };
            if depth[j].0 >= best_t {
                continue;
            }
            // The wedge between r1 and r2 (width < pi) is the intersection of two half-planes.
            if cross(vj.r1, u) < 0.0 || cross(u, vj.r2) < 0.0 {
                continue;
            }
            let verts = polygons[j];
            let n = verts.len();
            let (s, e) = ranges[j];
            for &i in &front[s as usize..e as usize] {
                let a = verts[i as usize] - p;
                let d = verts[(i as usize + 1) % n] - verts[i as usize];
                let denom = cross(u, d);
                if denom == 0.0 {
                    continue;
                }
                let t = cross(a, d) / denom;
                let sp = cross(a, u) / denom;
                if t > 0.0 && (0.0..=1.0).contains(&sp) && t < best_t {
                    best_t = t;
                    best = Some(j);
                }
            }
        }
        if let Some(j) = best {
            for c in 0..3 {
                sum[c] += emission[j][c];
                sum_sq[c] += emission[j][c] * emission[j][c];
            }
        }
    }
    let n = f64::from(rays);
    let mut mean = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        mean[c] = sum[c] / n;
        if rays > 1 {
            let var = ((sum_sq[c] / n - mean[c] * mean[c]) * n / (n - 1.0)).max(0.0);
            se[c] = (var / n).sqrt();
        }
    }
    (mean, se)
}
