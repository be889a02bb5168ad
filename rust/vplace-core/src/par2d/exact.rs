//! `exact`: an angular sweep over the front-facing edges, tracking the nearest one.
//!
//! Per light `L`, angles are measured counter-clockwise from `L`'s clockwise tangent vector
//! `r1`, so `L` covers `[0, w]` with `w < pi` and no interval ever crosses a seam. Every
//! front-facing edge of every polygon whose interval overlaps `[0, w]` becomes an angular
//! segment `[c0, c1]` clipped to `[0, w]`; between consecutive endpoints (the elementary
//! intervals) the set of active edges is fixed. Inside one elementary interval, with the
//! direction parametrised as `u(s) = m + s m_perp` (`m` the interval's mid direction), the
//! inverse depth of the line through an edge is linear in `s`, so the nearest surface is the
//! upper envelope of lines, computed exactly; the parts where it belongs to `L` are summed.
//! Edges of different polygons may cross (overlapping polygons): the envelope handles it.

use glam::DVec2;

use super::geometry::{angle_between, View};
use super::Scratch;

/// An edge as seen from the query point, clipped to the light's interval.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Segment {
    /// Start angle in the light's frame.
    pub c0: f64,
    /// End angle in the light's frame (`c1 > c0`).
    pub c1: f64,
    /// Edge endpoints relative to the query point.
    pub a: DVec2,
    pub b: DVec2,
    /// True for an edge of the light being measured.
    pub own: bool,
}

/// Pushes the front edges of polygon `j` (its view `vj`, vertices relative to `p`) as segments
/// in the frame of the light's `r1`, clipped to `[0, w]`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn push_segments(
    out: &mut Vec<Segment>,
    verts: &[DVec2],
    front: &[u32],
    p: DVec2,
    r1: DVec2,
    w: f64,
    vj: View,
    own: bool,
) {
    // Start of polygon j's interval in the light's frame; vertex angles are measured from
    // j's own start, so they never wrap.
    let b1 = if own { 0.0 } else { angle_between(r1, vj.r1) };
    let n = verts.len();
    // Consecutive front edges share a vertex: reuse its angle (one atan2 per vertex).
    let mut cached: Option<(usize, f64)> = None;
    for &i in front {
        let i = i as usize;
        // A front edge runs clockwise as seen from p: from v[i] (end) to v[i+1] (start).
        let a = verts[(i + 1) % n] - p;
        let b = verts[i] - p;
        let c0 = b1 + angle_between(vj.r1, a).max(0.0);
        let c1 = match cached {
            Some((k, c)) if k == i => c,
            _ => b1 + angle_between(vj.r1, b).max(0.0),
        };
        cached = Some(((i + 1) % n, c0));
        let (lo, hi) = (c0.max(0.0), c1.min(w));
        if hi > lo {
            out.push(Segment {
                c0: lo,
                c1: hi,
                a,
                b,
                own,
            });
        }
    }
}

/// The measure (radians) of the part of `[0, w]` where the nearest segment is an own one.
pub(crate) fn visible_measure(r1: DVec2, w: f64, scratch: &mut Scratch) -> f64 {
    let segs = &mut scratch.segments;
    if segs.iter().all(|s| s.own) {
        return w;
    }
    segs.sort_unstable_by(|x, y| x.c0.total_cmp(&y.c0));
    let events = &mut scratch.events;
    events.clear();
    events.push(0.0);
    events.push(w);
    for s in segs.iter() {
        events.push(s.c0);
        events.push(s.c1);
    }
    events.sort_unstable_by(f64::total_cmp);
    events.dedup();
    let dir = r1.normalize();
    let active = &mut scratch.active;
    active.clear();
    let mut next = 0;
    let mut total = 0.0;
    for k in 0..events.len() - 1 {
        let (t0, t1) = (events[k], events[k + 1]);
        if t1 <= t0 {
            continue;
        }
        active.retain(|&i| segs[i as usize].c1 > t0);
        while next < segs.len() && segs[next].c0 <= t0 {
            if segs[next].c1 > t0 {
                active.push(next as u32);
            }
            next += 1;
        }
        let mut any_own = false;
        let mut any_other = false;
        for &i in active.iter() {
            if segs[i as usize].own {
                any_own = true;
            } else {
                any_other = true;
            }
        }
        if !any_own {
            continue;
        }
        if !any_other {
            total += t1 - t0;
            continue;
        }
        total += envelope_own(segs, active, dir, t0, t1, &mut scratch.lines);
    }
    total
}

/// A line of inverse depth `g(s) = icpt + slope * s`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line {
    icpt: f64,
    slope: f64,
    own: bool,
}

fn envelope_own(
    segs: &[Segment],
    active: &[u32],
    dir: DVec2,
    t0: f64,
    t1: f64,
    lines: &mut Vec<Line>,
) -> f64 {
    let mid = 0.5 * (t0 + t1);
    let m = DVec2::from_angle(mid).rotate(dir);
    let m_perp = m.perp();
    let h = (0.5 * (t1 - t0)).tan();
    lines.clear();
    for &i in active {
        let s = segs[i as usize];
        let n = (s.b - s.a).perp();
        let c = n.dot(s.a);
        lines.push(Line {
            icpt: n.dot(m) / c,
            slope: n.dot(m_perp) / c,
            own: s.own,
        });
    }
    // The nearest line at s = -h (ties: the one that stays nearest, larger slope).
    let value = |l: &Line, s: f64| l.icpt + l.slope * s;
    let mut cur = 0;
    for (k, l) in lines.iter().enumerate() {
        let (vk, vc) = (value(l, -h), value(&lines[cur], -h));
        if vk > vc || (vk == vc && l.slope > lines[cur].slope) {
            cur = k;
        }
    }
    let mut s = -h;
    let mut measure = 0.0;
    loop {
        let c = lines[cur];
        let mut next_s = h;
        let mut next = None;
        for (k, l) in lines.iter().enumerate() {
            if k == cur || l.slope <= c.slope {
                continue;
            }
            let sx = (c.icpt - l.icpt) / (l.slope - c.slope);
            let better = sx < next_s
                || (sx == next_s && next.is_some_and(|n: usize| l.slope > lines[n].slope));
            if sx >= s && better {
                next_s = sx;
                next = Some(k);
            }
        }
        let next_s = next_s.clamp(s, h);
        if c.own {
            measure += next_s.atan() - s.atan();
        }
        match next {
            Some(k) if next_s < h => {
                cur = k;
                s = next_s;
            }
            _ => break,
        }
    }
    measure
}
