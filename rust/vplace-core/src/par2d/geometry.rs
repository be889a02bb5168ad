//! Polygon cleaning and the per-point view of a convex polygon: containment, the two tangent
//! vectors of its angular interval, its front-facing edges.
//!
//! Every quantity here is computed from vectors relative to the query point, so coordinates
//! around 1e6 keep features of 1e-3 accurate to about `ulp(1e6) / 1e-3 ~ 1e-7` relative.

use glam::DVec2;

use crate::error::{Result, VplaceError};

/// Relative tolerance on `sin` of the turn at a vertex: turns smaller than this in magnitude
/// count as collinear (the vertex is dropped), more negative ones make the polygon non-convex.
pub const COLLINEAR_SIN: f64 = 1e-14;

/// The 2D cross product `a.x * b.y - a.y * b.x` (positive when `b` is counter-clockwise of `a`).
#[inline]
#[must_use]
pub fn cross(a: DVec2, b: DVec2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The counter-clockwise angle from `a` to `b` in `(-pi, pi]`, exact at the `+-pi` seam of
/// `atan2` because it is measured in the frame of `a`.
#[inline]
#[must_use]
pub fn angle_between(a: DVec2, b: DVec2) -> f64 {
    cross(a, b).atan2(a.dot(b))
}

/// A convex polygon with counter-clockwise vertices, no duplicate or collinear vertices and at
/// least three vertices (so a positive area, however small).
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    vertices: Vec<DVec2>,
    /// Mean of the vertices: the centre of a bounding circle.
    center: DVec2,
    /// Largest distance from `center` to a vertex: every point of the polygon lies within it.
    radius: f64,
}

impl Polygon {
    /// Cleans and checks one polygon given in either orientation: drops duplicate and collinear
    /// vertices (turn `|sin| <= COLLINEAR_SIN`), reverses a clockwise polygon, and rejects a
    /// non-convex, self-overlapping or degenerate one with [`VplaceError::Invalid`]. `index`
    /// names the polygon in the error.
    pub fn new(vertices: &[DVec2], index: usize) -> Result<Self> {
        let what = || format!("polygon {index}");
        if let Some(i) = vertices.iter().position(|v| !v.is_finite()) {
            return Err(VplaceError::NonFinite {
                what: format!("vertices of polygon {index}"),
                index: i,
            });
        }
        let mut v: Vec<DVec2> = Vec::with_capacity(vertices.len());
        for &p in vertices {
            if v.last() != Some(&p) {
                v.push(p);
            }
        }
        while v.len() > 1 && v.first() == v.last() {
            v.pop();
        }
        if v.len() >= 3 && signed_area2(&v) < 0.0 {
            v.reverse();
        }
        // Drop collinear vertices until none is left (each pass removes at least one or stops).
        loop {
            if v.len() < 3 {
                return Err(VplaceError::Invalid {
                    what: what(),
                    reason: "has zero area (fewer than 3 distinct, non-collinear vertices)"
                        .to_owned(),
                });
            }
            let n = v.len();
            let mut drop = None;
            for i in 0..n {
                let a = v[(i + n - 1) % n];
                let b = v[i];
                let c = v[(i + 1) % n];
                let (e0, e1) = (b - a, c - b);
                let s = cross(e0, e1);
                let scale = e0.length() * e1.length();
                if s.abs() <= COLLINEAR_SIN * scale {
                    drop = Some(i);
                    break;
                }
                if s < 0.0 {
                    return Err(VplaceError::Invalid {
                        what: what(),
                        reason: format!(
                            "is not convex (reflex vertex {i}); split it into convex parts \
                             before passing it"
                        ),
                    });
                }
            }
            match drop {
                Some(i) => {
                    v.remove(i);
                }
                None => break,
            }
        }
        // All turns are left turns; the total turn must be one full circle (not a star).
        let n = v.len();
        let turning: f64 = (0..n)
            .map(|i| {
                let a = v[(i + n - 1) % n];
                let b = v[i];
                let c = v[(i + 1) % n];
                angle_between(b - a, c - b)
            })
            .sum();
        if turning > 3.0 * std::f64::consts::PI {
            return Err(VplaceError::Invalid {
                what: what(),
                reason: "winds around more than once (self-intersecting); pass a simple convex \
                         polygon"
                    .to_owned(),
            });
        }
        let center = v.iter().copied().sum::<DVec2>() / v.len() as f64;
        let radius = v.iter().map(|&q| q.distance(center)).fold(0.0, f64::max);
        Ok(Self {
            vertices: v,
            center,
            radius,
        })
    }

    /// The cleaned vertices, counter-clockwise.
    #[must_use]
    pub fn vertices(&self) -> &[DVec2] {
        &self.vertices
    }

    /// A circle `(center, radius)` containing the polygon.
    #[must_use]
    pub fn bounding_circle(&self) -> (DVec2, f64) {
        (self.center, self.radius)
    }

    /// The signed area (positive: counter-clockwise).
    #[must_use]
    pub fn area(&self) -> f64 {
        0.5 * signed_area2(&self.vertices)
    }

    /// True when `p` lies in the closed polygon (boundary included), decided by the sign of
    /// `cross(b - a, p - a)` over the edges.
    #[must_use]
    pub fn contains(&self, p: DVec2) -> bool {
        let n = self.vertices.len();
        (0..n).all(|i| {
            let a = self.vertices[i];
            let b = self.vertices[(i + 1) % n];
            cross(b - a, p - a) >= 0.0
        })
    }
}

fn signed_area2(v: &[DVec2]) -> f64 {
    let n = v.len();
    let o = v[0];
    (1..n.saturating_sub(1))
        .map(|i| cross(v[i] - o, v[i + 1] - o))
        .sum()
}

/// How a polygon looks from a query point outside it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Vector from the point to the clockwise tangent vertex (the interval's start).
    pub r1: DVec2,
    /// Vector from the point to the counter-clockwise tangent vertex (the interval's end).
    pub r2: DVec2,
}

impl View {
    /// The interval's measure, radians, in `[0, pi)` (one `atan2`, so computed on demand).
    #[inline]
    #[must_use]
    pub fn width(&self) -> f64 {
        angle_between(self.r1, self.r2).max(0.0)
    }

    /// True when the interval has a positive measure.
    #[inline]
    #[must_use]
    pub fn is_open(&self) -> bool {
        cross(self.r1, self.r2) > 0.0
    }
}

/// The view of `poly` from `p`, or `None` when `p` lies in the closed polygon. Also appends the
/// indices `i` of the front-facing edges `(v[i], v[i+1])` (those `p` sees from outside) to
/// `front`.
#[must_use]
pub fn view(poly: &Polygon, p: DVec2, front: &mut Vec<u32>) -> Option<View> {
    let v = &poly.vertices;
    let n = v.len();
    let start = front.len();
    for i in 0..n {
        let a = v[i];
        let b = v[(i + 1) % n];
        if cross(b - a, p - a) < 0.0 {
            front.push(i as u32);
        }
    }
    if front.len() == start {
        return None;
    }
    // p is strictly outside, so all vertex directions lie in an open half-plane and "clockwise
    // of" is a consistent order; on ties (collinear with p) keep the nearer vertex.
    let mut r1 = v[0] - p;
    let mut r2 = r1;
    for &q in &v[1..] {
        let r = q - p;
        let c1 = cross(r1, r);
        if c1 < 0.0 || (c1 == 0.0 && r.dot(r1) > 0.0 && r.length_squared() < r1.length_squared()) {
            r1 = r;
        }
        let c2 = cross(r2, r);
        if c2 > 0.0 || (c2 == 0.0 && r.dot(r2) > 0.0 && r.length_squared() < r2.length_squared()) {
            r2 = r;
        }
    }
    Some(View { r1, r2 })
}

/// True when the angular intervals of `a` and `b` (each narrower than pi) share a range of
/// positive measure; decided with cross products only (no angles).
#[inline]
#[must_use]
pub fn intervals_overlap(a: &View, b: &View) -> bool {
    let starts_in = |x: DVec2, w: &View| cross(w.r1, x) >= 0.0 && cross(x, w.r2) > 0.0;
    a.is_open() && b.is_open() && (starts_in(b.r1, a) || starts_in(a.r1, b))
}

/// True when the key segment `[a, b]` (from the query point to a tangent vertex) crosses the
/// chord `[c, d]`: `a` and `b` lie strictly on opposite sides of the chord's line, and the
/// chord's endpoints lie on opposite sides of (or on) the segment's line. A tangent vertex
/// lying exactly on the chord (polygons touching there) does not count as crossing; nor does a
/// chord collinear with the segment.
#[must_use]
pub fn segment_crosses_chord(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let sign = |x: f64| i8::from(x > 0.0) - i8::from(x < 0.0);
    let s1 = sign(cross(b - a, c - a));
    let s2 = sign(cross(b - a, d - a));
    let s3 = sign(cross(d - c, a - c));
    let s4 = sign(cross(d - c, b - c));
    !(s1 == 0 && s2 == 0) && s1 * s2 <= 0 && s3 * s4 < 0
}
