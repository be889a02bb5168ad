//! `par`: the paper's method (Qiu, "Probabilistic Angular Radiance", section 2.2).
//!
//! Per light `L`, every other polygon `B` (occluders and the other lights, all opaque) is seen
//! as an angular interval stored as its two tangent vectors. In the frame of `L`'s clockwise
//! tangent vector (no seam), the intervals are classified and tested as the paper does:
//! - disjoint: ignored;
//! - partial overlap: `B` occludes when one of `L`'s key segments `p -> L1`, `p -> L2`
//!   crosses `B`'s chord `O1 O2` (the segment between the endpoints of its key vectors);
//! - `Theta_L` inside `Theta_B`: the same test;
//! - `Theta_B` inside `Theta_L`: `B` is *behind* `L` when one of `B`'s key segments
//!   `p -> O1`, `p -> O2` crosses `L`'s chord `L1 L2`, otherwise it occludes.
//!
//! The blocking intervals are merged (their union, no double counting) and subtracted.
//! A tangent vertex exactly on the other polygon's chord (the two touch there) does not count
//! as a crossing: for `Theta_B` inside `Theta_L` a vertex of `B` touching `L`'s chord is in
//! front of `L`.
//!
//! Valid when the depth order of `L` and `B` is the same over their whole common interval,
//! which holds whenever `B` does not intersect `L` (two disjoint convex sets never swap depth
//! order as seen from a point). It is wrong when `B` crosses `L` (in front over part of the
//! interval, behind elsewhere): then the whole overlap is either blocked or not.

use glam::DVec2;

use super::geometry::{angle_between, intervals_overlap, segment_crosses_chord, View};

/// The visible measure (radians) of light `l` from `p`; `views[j]` is polygon `j`'s view and
/// `depth[j]` bounds its distance from `p` (near, far).
pub(crate) fn visible_measure(
    l: usize,
    views: &[Option<View>],
    depth: &[(f64, f64)],
    blocks: &mut Vec<(f64, f64)>,
) -> f64 {
    let Some(vl) = views[l] else { return 0.0 };
    let w = vl.width();
    if w <= 0.0 {
        return 0.0;
    }
    let (l1, l2) = (vl.r1, vl.r2);
    let o = DVec2::ZERO;
    blocks.clear();
    for (j, vj) in views.iter().enumerate() {
        let Some(vj) = *vj else { continue };
        // Entirely behind L's bounding circle (the depth tests would say "behind"), or disjoint.
        if j == l || depth[j].0 > depth[l].1 || !intervals_overlap(&vl, &vj) {
            continue;
        }
        let b1 = angle_between(l1, vj.r1);
        let b2 = b1 + vj.width();
        if b2 <= 0.0 || b1 >= w {
            continue; // disjoint
        }
        let (o1, o2) = (vj.r1, vj.r2);
        let occludes = if b1 >= 0.0 && b2 <= w && !(b1 <= 0.0 && b2 >= w) {
            // Theta_B inside Theta_L: B's key rays reaching L's chord means B is behind L.
            !(segment_crosses_chord(o, o1, l1, l2) || segment_crosses_chord(o, o2, l1, l2))
        } else {
            // Partial overlap, or Theta_L inside Theta_B.
            segment_crosses_chord(o, l1, o1, o2) || segment_crosses_chord(o, l2, o1, o2)
        };
        if occludes {
            blocks.push((b1.max(0.0), b2.min(w)));
        }
    }
    w - union_measure(blocks)
}

/// The measure of a union of intervals (sorts `blocks` in place).
pub(crate) fn union_measure(blocks: &mut [(f64, f64)]) -> f64 {
    blocks.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut total = 0.0;
    let mut cur: Option<(f64, f64)> = None;
    for &(lo, hi) in blocks.iter() {
        match cur {
            Some((clo, chi)) if lo <= chi => cur = Some((clo, chi.max(hi))),
            Some((clo, chi)) => {
                total += chi - clo;
                cur = Some((lo, hi));
            }
            None => cur = Some((lo, hi)),
        }
    }
    if let Some((clo, chi)) = cur {
        total += chi - clo;
    }
    total
}
