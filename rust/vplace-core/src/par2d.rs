//! Analytic 2D direct lighting: PAR (Qiu, "Probabilistic Angular Radiance"), an exact angular
//! sweep, and a Monte Carlo baseline, behind one API.
//!
//! A [`Scene2d`] holds convex polygons, each a light (RGB emission `e >= 0`, not all zero) or an
//! occluder (emission zero). Every polygon is opaque: lights also shadow each other. The query
//! is the fluence / 2 pi at a point `p`:
//!
//! `L(p) = sum_L e_L * mu(visible part of Theta_L(p)) / (2 pi)`,
//!
//! where `Theta_L(p)` is the set of directions from `p` that hit `L` and "visible" means `L` is
//! the nearest surface along that direction. No cosine term: it is the probability that a
//! uniformly random ray from `p` first hits `L`, times `e_L`.
//!
//! [`Method`] picks the algorithm:
//! - [`Method::Par`]: the paper's method, see `par2d/par.rs`. Exact (to rounding) when no
//!   polygon intersects a light; wrong when an occluder crosses a light (in front of it over
//!   part of its interval and behind it elsewhere): the paper's per-case depth test then blocks
//!   all or nothing of the overlap.
//! - [`Method::Exact`]: an angular sweep over the front-facing edges with the nearest one
//!   tracked by an exact lower envelope of depths, see `par2d/exact.rs`. Exact for every layout,
//!   overlapping polygons included.
//! - [`Method::MonteCarlo`]: 2D ray casting with uniform random directions, deterministic per
//!   seed (each query point / pixel has its own random stream).
//!
//! ## Decisions
//! - **Robust angles.** Each light's angles are measured in the frame of its own clockwise
//!   tangent vector with `atan2(cross, dot)`, so its interval is `[0, w]`, `w < pi`, and no
//!   interval ever crosses the `+-pi` seam of `atan2`. All geometry is computed from vectors
//!   relative to the query point, in `f64`.
//! - **Non-convex input is rejected** with [`VplaceError::Invalid`] naming the polygon and its
//!   reflex vertex (split it into convex parts first). Either orientation is accepted;
//!   duplicate vertices and collinear vertices (turn `|sin| <= 1e-14`) are dropped; a polygon
//!   left with fewer than 3 vertices (zero area) or winding more than once is rejected. Tiny
//!   but positive areas (1e-12 and below) are fine.
//! - **Points inside or on polygons.** Polygons are closed sets: a point on an edge or a vertex
//!   is inside. A point inside (or on the boundary of) an occluder gets 0; otherwise a point
//!   inside one or more lights gets the componentwise maximum of their emissions (the full
//!   angle `2 pi` of that light). All three methods share this rule, so they agree exactly
//!   there. Approached from outside, the value tends to about `e / 2` at a light's edge.
//! - **Coincident surfaces** (two polygons sharing a stretch of edge seen from `p`) are a tie
//!   of measure zero in angle unless the edges overlap; there the winner is unspecified.
//!
//! ```
//! use glam::DVec2;
//! use vplace_core::par2d::{Method, Scene2d};
//! // A unit square light at distance 2 and nothing else.
//! let square = vec![DVec2::new(2., -0.5), DVec2::new(3., -0.5), DVec2::new(3., 0.5), DVec2::new(2., 0.5)];
//! let scene = Scene2d::build(&[square], &[[1.0, 1.0, 1.0]]).unwrap();
//! let e = scene.irradiance_at(DVec2::ZERO, Method::Exact).unwrap();
//! let expected = 2.0 * (0.25f64).atan() / std::f64::consts::TAU;
//! assert!((e[0] - expected).abs() < 1e-12);
//! ```

mod exact;
mod geometry;
mod monte_carlo;
mod par;
pub mod procedural;
#[cfg(test)]
mod tests;

use std::sync::atomic::Ordering;

use glam::DVec2;
use rayon::prelude::*;

pub use geometry::Polygon;
use geometry::View;

use crate::error::{Result, VplaceError};
use crate::progress::Progress;
use crate::rng::Rng;

/// The algorithm answering a query. Copy settings; see the module doc for what each computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The paper's interval method with its per-case depth tests.
    Par,
    /// The exact angular sweep.
    Exact,
    /// Ray casting with `rays` uniform random directions per point (`rays >= 1`), seeded.
    MonteCarlo {
        /// Rays per query point, at least 1.
        rays: u32,
        /// Seed of the random streams; the stream is the point's (pixel's) index.
        seed: u64,
    },
}

impl Method {
    /// Monte Carlo with `rays` rays and seed 0.
    #[must_use]
    pub const fn monte_carlo(rays: u32) -> Self {
        Self::MonteCarlo { rays, seed: 0 }
    }

    fn check(self) -> Result<()> {
        match self {
            Self::MonteCarlo { rays: 0, .. } => Err(VplaceError::OutOfRange {
                what: "rays".to_owned(),
                value: "0".to_owned(),
                expected: "at least 1".to_owned(),
            }),
            _ => Ok(()),
        }
    }
}

/// An axis-aligned rectangle of the plane, `min < max` on both axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds2 {
    /// Lower-left corner.
    pub min: DVec2,
    /// Upper-right corner.
    pub max: DVec2,
}

/// Convex polygons, each a light or an occluder. Immutable once built.
#[derive(Debug, Clone)]
pub struct Scene2d {
    /// Cleaned convex polygons, counter-clockwise.
    polygons: Vec<Polygon>,
    /// RGB emission per polygon, finite and `>= 0`; all zero for an occluder.
    emission: Vec<[f64; 3]>,
    /// Indices of the lights (emission not all zero), ascending.
    lights: Vec<usize>,
}

/// Per-thread buffers reused across query points.
#[derive(Debug, Default)]
pub(crate) struct Scratch {
    views: Vec<Option<View>>,
    front: Vec<u32>,
    ranges: Vec<(u32, u32)>,
    segments: Vec<exact::Segment>,
    events: Vec<f64>,
    active: Vec<u32>,
    lines: Vec<exact::Line>,
    blocks: Vec<(f64, f64)>,
    overlapping: Vec<u32>,
    /// Per polygon, bounds `(near, far)` on the distance from the query point to its points.
    depth: Vec<(f64, f64)>,
}

impl Scene2d {
    /// Builds a scene from polygons (either orientation) and one RGB emission per polygon.
    /// Errors: no polygons, a length mismatch, a non-finite value, a negative emission, a
    /// non-convex or zero-area polygon (see the module doc).
    pub fn build(polygons: &[Vec<DVec2>], emission: &[[f64; 3]]) -> Result<Self> {
        if polygons.is_empty() {
            return Err(VplaceError::Empty {
                what: "polygons".to_owned(),
                hint: "pass at least one polygon (a light or an occluder)".to_owned(),
            });
        }
        if emission.len() != polygons.len() {
            return Err(VplaceError::Shape {
                what: "emission".to_owned(),
                expected: format!("({}, 3), one row per polygon", polygons.len()),
                got: format!("({}, 3)", emission.len()),
            });
        }
        for (i, e) in emission.iter().enumerate() {
            for (c, &x) in e.iter().enumerate() {
                if !x.is_finite() {
                    return Err(VplaceError::NonFinite {
                        what: "emission".to_owned(),
                        index: 3 * i + c,
                    });
                }
                if x < 0.0 {
                    return Err(VplaceError::OutOfRange {
                        what: format!("emission[{i}][{c}]"),
                        value: x.to_string(),
                        expected: ">= 0".to_owned(),
                    });
                }
            }
        }
        let polygons = polygons
            .iter()
            .enumerate()
            .map(|(i, v)| Polygon::new(v, i))
            .collect::<Result<Vec<_>>>()?;
        let lights = (0..polygons.len())
            .filter(|&i| emission[i].iter().any(|&x| x > 0.0))
            .collect();
        Ok(Self {
            polygons,
            emission: emission.to_vec(),
            lights,
        })
    }

    /// Builds a scene from flat arrays: `vertices` `(V, 2)` row-major, `counts[i]` vertices
    /// per polygon (summing to `V`), `emission` `(P, 3)` row-major.
    pub fn from_flat(vertices: &[f64], counts: &[usize], emission: &[f64]) -> Result<Self> {
        let total: usize = counts.iter().sum();
        if vertices.len() != 2 * total {
            return Err(VplaceError::Shape {
                what: "vertices".to_owned(),
                expected: format!("({total}, 2), the sum of counts"),
                got: format!("{} values", vertices.len()),
            });
        }
        if emission.len() != 3 * counts.len() {
            return Err(VplaceError::Shape {
                what: "emission".to_owned(),
                expected: format!("({}, 3), one row per polygon", counts.len()),
                got: format!("{} values", emission.len()),
            });
        }
        let mut polys = Vec::with_capacity(counts.len());
        let mut at = 0;
        for &n in counts {
            polys.push(
                vertices[2 * at..2 * (at + n)]
                    .chunks_exact(2)
                    .map(|c| DVec2::new(c[0], c[1]))
                    .collect(),
            );
            at += n;
        }
        let em: Vec<[f64; 3]> = emission
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        Self::build(&polys, &em)
    }

    /// Number of polygons.
    #[must_use]
    pub fn len(&self) -> usize {
        self.polygons.len()
    }

    /// Always false: a scene holds at least one polygon.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.polygons.is_empty()
    }

    /// The cleaned polygons, in input order.
    #[must_use]
    pub fn polygons(&self) -> &[Polygon] {
        &self.polygons
    }

    /// The emission of each polygon, in input order.
    #[must_use]
    pub fn emission(&self) -> &[[f64; 3]] {
        &self.emission
    }

    /// Number of lights (polygons with some positive emission).
    #[must_use]
    pub fn light_count(&self) -> usize {
        self.lights.len()
    }

    /// The fluence / 2 pi at one point. Errors: a non-finite point, zero Monte Carlo rays.
    /// Monte Carlo uses random stream 0.
    pub fn irradiance_at(&self, p: DVec2, method: Method) -> Result<[f64; 3]> {
        check_point(p, 0)?;
        method.check()?;
        Ok(self.eval(p, method, 0, &mut Scratch::default()))
    }

    /// Monte Carlo mean and standard error (per channel) at `p` with random stream `stream`.
    pub fn monte_carlo_at(
        &self,
        p: DVec2,
        rays: u32,
        seed: u64,
        stream: u64,
    ) -> Result<([f64; 3], [f64; 3])> {
        check_point(p, 0)?;
        Method::monte_carlo(rays).check()?;
        let mut s = Scratch::default();
        if let Some(v) = self.prepare(p, &mut s) {
            return Ok((v, [0.0; 3]));
        }
        Ok(self.monte_carlo(p, rays, &mut Rng::new(seed, stream), &s))
    }

    /// The fluence / 2 pi at many points, in parallel. Monte Carlo uses stream `i` for point
    /// `i`. `progress` (optional) counts points and is polled for cancellation.
    pub fn irradiance(
        &self,
        points: &[DVec2],
        method: Method,
        progress: Option<&Progress>,
    ) -> Result<Vec<[f64; 3]>> {
        for (i, &p) in points.iter().enumerate() {
            check_point(p, i)?;
        }
        method.check()?;
        const CHUNK: usize = 256;
        if let Some(pr) = progress {
            pr.total.store(points.len(), Ordering::Relaxed);
            pr.done.store(0, Ordering::Relaxed);
        }
        let mut out = vec![[0.0; 3]; points.len()];
        out.par_chunks_mut(CHUNK).enumerate().try_for_each_init(
            Scratch::default,
            |s, (k, chunk)| {
                if progress.is_some_and(|pr| pr.cancel.load(Ordering::Relaxed)) {
                    return Err(VplaceError::Cancelled);
                }
                for (i, o) in chunk.iter_mut().enumerate() {
                    let idx = k * CHUNK + i;
                    *o = self.eval(points[idx], method, idx as u64, s);
                }
                if let Some(pr) = progress {
                    pr.done.fetch_add(chunk.len(), Ordering::Relaxed);
                }
                Ok(())
            },
        )?;
        Ok(out)
    }

    /// A `height x width` RGB light map of `bounds`, row-major `H x W x 3`, row 0 at the top
    /// (largest y), pixel centres sampled. Parallel over rows; Monte Carlo uses stream
    /// `row * width + column`. `progress` (optional) counts rows and is polled per row.
    pub fn light_map(
        &self,
        bounds: Bounds2,
        width: usize,
        height: usize,
        method: Method,
        progress: Option<&Progress>,
    ) -> Result<Vec<f64>> {
        if !(bounds.min.is_finite() && bounds.max.is_finite()) {
            return Err(VplaceError::NonFinite {
                what: "bounds".to_owned(),
                index: 0,
            });
        }
        if !(bounds.min.x < bounds.max.x && bounds.min.y < bounds.max.y) {
            return Err(VplaceError::Invalid {
                what: "bounds".to_owned(),
                reason: format!(
                    "need min < max on both axes, got min {:?} max {:?}",
                    bounds.min, bounds.max
                ),
            });
        }
        if width == 0 || height == 0 {
            return Err(VplaceError::OutOfRange {
                what: "width x height".to_owned(),
                value: format!("{width} x {height}"),
                expected: "both at least 1".to_owned(),
            });
        }
        method.check()?;
        if let Some(pr) = progress {
            pr.total.store(height, Ordering::Relaxed);
            pr.done.store(0, Ordering::Relaxed);
        }
        let size = bounds.max - bounds.min;
        let mut out = vec![0.0; width * height * 3];
        out.par_chunks_mut(width * 3)
            .enumerate()
            .try_for_each_init(Scratch::default, |s, (row, pixels)| {
                if progress.is_some_and(|pr| pr.cancel.load(Ordering::Relaxed)) {
                    return Err(VplaceError::Cancelled);
                }
                let y = bounds.max.y - (row as f64 + 0.5) / height as f64 * size.y;
                for (col, px) in pixels.chunks_exact_mut(3).enumerate() {
                    let x = bounds.min.x + (col as f64 + 0.5) / width as f64 * size.x;
                    let stream = (row * width + col) as u64;
                    px.copy_from_slice(&self.eval(DVec2::new(x, y), method, stream, s));
                }
                if let Some(pr) = progress {
                    pr.done.fetch_add(1, Ordering::Relaxed);
                }
                Ok(())
            })?;
        Ok(out)
    }

    /// Computes every polygon's view from `p` into `s`; returns the answer directly when `p`
    /// lies in a polygon (see the module doc).
    fn prepare(&self, p: DVec2, s: &mut Scratch) -> Option<[f64; 3]> {
        s.views.clear();
        s.depth.clear();
        s.front.clear();
        s.ranges.clear();
        let mut inside_light: Option<[f64; 3]> = None;
        for (j, poly) in self.polygons.iter().enumerate() {
            let start = s.front.len() as u32;
            let v = geometry::view(poly, p, &mut s.front);
            s.ranges.push((start, s.front.len() as u32));
            s.views.push(v);
            let (c, r) = poly.bounding_circle();
            let d = p.distance(c);
            s.depth.push((d - r, d + r));
            if v.is_none() {
                let e = self.emission[j];
                if e == [0.0; 3] {
                    return Some([0.0; 3]);
                }
                let m = inside_light.get_or_insert([0.0; 3]);
                for c in 0..3 {
                    m[c] = m[c].max(e[c]);
                }
            }
        }
        inside_light
    }

    /// The answer at a finite point with a checked method.
    fn eval(&self, p: DVec2, method: Method, stream: u64, s: &mut Scratch) -> [f64; 3] {
        if let Some(v) = self.prepare(p, s) {
            return v;
        }
        if let Method::MonteCarlo { rays, seed } = method {
            return self.monte_carlo(p, rays, &mut Rng::new(seed, stream), s).0;
        }
        let mut out = [0.0; 3];
        for &l in &self.lights {
            let measure = match method {
                Method::Par => par::visible_measure(l, &s.views, &s.depth, &mut s.blocks),
                _ => self.exact_measure(p, l, s),
            };
            let f = measure / std::f64::consts::TAU;
            for (o, e) in out.iter_mut().zip(self.emission[l]) {
                *o += e * f;
            }
        }
        out
    }

    fn exact_measure(&self, p: DVec2, l: usize, s: &mut Scratch) -> f64 {
        let Some(vl) = s.views[l] else { return 0.0 };
        let w = vl.width();
        if w <= 0.0 {
            return 0.0;
        }
        s.segments.clear();
        s.overlapping.clear();
        for (j, vj) in s.views.iter().enumerate() {
            // Entirely behind the light's bounding circle: cannot hide any of it.
            if j == l || s.depth[j].0 > s.depth[l].1 {
                continue;
            }
            if vj.is_some_and(|vj| geometry::intervals_overlap(&vl, &vj)) {
                s.overlapping.push(j as u32);
            }
        }
        if s.overlapping.is_empty() {
            return w;
        }
        s.overlapping.push(l as u32);
        for &j in &s.overlapping {
            let j = j as usize;
            let Some(vj) = s.views[j] else { continue };
            let (a, b) = s.ranges[j];
            exact::push_segments(
                &mut s.segments,
                self.polygons[j].vertices(),
                &s.front[a as usize..b as usize],
                p,
                vl.r1,
                w,
                vj,
                j == l,
            );
        }
        exact::visible_measure(vl.r1, w, s)
    }

    fn monte_carlo(&self, p: DVec2, rays: u32, rng: &mut Rng, s: &Scratch) -> ([f64; 3], [f64; 3]) {
        let polys: Vec<&[DVec2]> = self.polygons.iter().map(Polygon::vertices).collect();
        monte_carlo::estimate(
            p,
            &polys,
            &self.emission,
            &s.views,
            &s.depth,
            &s.front,
            &s.ranges,
            rays,
            rng,
        )
    }
}

fn check_point(p: DVec2, index: usize) -> Result<()> {
    if p.is_finite() {
        Ok(())
    } else {
        Err(VplaceError::NonFinite {
            what: "points".to_owned(),
            index: 2 * index + usize::from(p.x.is_finite()),
        })
    }
}
