//! Every light source of a scene: the lights of [`crate::scene::LightKind`] and the emissive
//! triangles, with their emitted power and the emission rays of light paths.
//!
//! Units are Blender's (Cycles 5.0, `intern/cycles/scene/light.cpp` and `kernel/light/`); `P`
//! is a light's `power` (colour x energy, W per channel):
//!
//! | kind | radiance or intensity | emitted power |
//! |---|---|---|
//! | point, radius 0 | intensity `P / (4 pi)` | `P` |
//! | point, radius `r` | a sphere (or, with soft falloff, a disk facing the receiver) of radiance `P / (4 pi^2 r^2)` | `P` |
//! | spot | the point times `smoothstep((cos - cos h) / ((1 - cos h) blend))` | `P (1 - cos h)(1 - blend / 2) / 2` |
//! | area, area `A` | `P / (pi A) g(theta)` one-sided, `g` the spread attenuation | `P` |
//! | sun, angle `a` | irradiance `P` (W/m^2), radiance `P / (pi sin^2(a / 2))` in the cone | `P pi R^2` |
//! | world | radiance `P map(w)` (W/(m^2 sr)) from direction `w` | `pi R^2 int P map(w) dw` |
//! | emissive triangle | radiance `L` on both sides | `2 pi L A` |
//!
//! `R` is the radius of the scene's bounding sphere (half the diagonal of its bounds): a sun's
//! or the world's parallel rays that can reach the geometry cross a disk of that radius. The
//! spread attenuation of an area light of spread `s` (half angle `h = s / 2`) is Blender's
//! soft-box grid, `g = max(0, tan h - tan theta) / (tan h - h)`, normalized so that the power
//! is `P` whatever the spread (`g = 1` for `s = pi`; `s = 0` is a collimated beam).
//!
//! **Light paths.** [`sample_emission`] draws one ray of an emitter with a weight `w` (RGB) such
//! that `P w` is the flux the ray carries and `E[w] = 1` per channel: positions uniformly over
//! the emitter (a point's sphere, an area's shape, a disk of radius `R` outside the bounding
//! sphere for a sun or the world, a triangle chosen by power for emissive meshes), directions
//! by the emission profile (uniform sphere, the spot's cone weighted by its blend, cosine or the
//! spread cone weighted by `g`, the sun's cone, the world's importance map, cosine on either
//! side of a triangle).
//!
//! **The world's map.** An [`EnvironmentMap`] holds an equirectangular float RGB image in
//! Blender's convention (`u = 0.5 - atan2(y, x) / (2 pi)`, the top row at +Z, `v` linear in
//! the polar angle) and a rotation from world to image directions. It is importance-sampled by a
//! 2D CDF: rows by their summed weight, then a column in the row; a pixel's weight is its
//! luminance times its exact solid angle (`dphi (cos theta_0 - cos theta_1)`, the sin(theta)
//! weighting integrated over the row), and a direction is uniform in solid angle inside the
//! pixel, so the density is exactly `mass / solid angle` of the pixel, matching the
//! piecewise-constant radiance.

use glam::{Mat3, Vec3};
use std::f32::consts::PI;

use crate::color::luminance;
use crate::error::{check_finite, Result, VplaceError};
use crate::scene::{Light, LightKind, Material, Scene};

/// Spreads (radians) below this are a collimated beam (Blender: cos of the spread < 0.9999997).
pub const COLLIMATED_SPREAD: f32 = 1e-3;
/// Sun angles (radians) below this are parallel light.
pub const PARALLEL_SUN: f32 = 1e-6;

/// An orthonormal basis `(t, b)` around unit `n`.
#[inline]
pub(crate) fn basis(n: Vec3) -> (Vec3, Vec3) {
    let t = n.any_orthonormal_vector();
    (t, n.cross(t))
}

/// A unit direction uniform over the sphere.
#[inline]
pub(crate) fn uniform_sphere(u1: f32, u2: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A cosine-distributed unit direction about unit `n` (density `cos / pi`).
#[inline]
pub(crate) fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let (t, b) = basis(n);
    (n * (1.0 - u1).max(0.0).sqrt() + (t * phi.cos() + b * phi.sin()) * r).normalize()
}

/// The mirror direction of travel direction `d` (towards the surface) about a microfacet normal
/// drawn from the GGX distribution of width `alpha` around unit normal `n` (which faces `d`'s
/// origin). A direction below the surface is mirrored back above it: the light a single
/// microfacet bounce would send into the surface leaves after further bounces in a
/// multiple-scattering model such as Cycles', and the layer's reflectance already says how much
/// leaves.
#[inline]
pub(crate) fn ggx_reflection(d: Vec3, n: Vec3, alpha: f32, u1: f32, u2: f32) -> Vec3 {
    let a2 = alpha * alpha;
    let cos2 = ((1.0 - u1) / (1.0 + (a2 - 1.0) * u1)).clamp(0.0, 1.0);
    let (cos_t, sin_t) = (cos2.sqrt(), (1.0 - cos2).sqrt());
    let phi = 2.0 * PI * u2;
    let (t, b) = basis(n);
    let h = n * cos_t + (t * phi.cos() + b * phi.sin()) * sin_t;
    let out = d - h * (2.0 * d.dot(h));
    let below = out.dot(n);
    let out = if below < 0.0 {
        out - n * (2.0 * below)
    } else {
        out
    };
    out.normalize_or(n)
}

/// A unit direction uniform in the cone of unit axis `axis` whose `1 - cos` of the half angle
/// is `one_minus_cos` (density `1 / (2 pi one_minus_cos)`).
#[inline]
pub(crate) fn uniform_cone(axis: Vec3, one_minus_cos: f32, u1: f32, u2: f32) -> Vec3 {
    let cos_t = 1.0 - u1 * one_minus_cos;
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    let (t, b) = basis(axis);
    (axis * cos_t + (t * phi.cos() + b * phi.sin()) * sin_t).normalize()
}

/// A point uniform over the unit disk (Shirley's concentric map: strata stay compact).
#[inline]
pub(crate) fn concentric_disk(u1: f32, u2: f32) -> (f32, f32) {
    let (a, b) = (2.0 * u1 - 1.0, 2.0 * u2 - 1.0);
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a * a > b * b {
        (a, PI / 4.0 * (b / a))
    } else {
        (b, PI / 2.0 - PI / 4.0 * (a / b))
    };
    (r * phi.cos(), r * phi.sin())
}

/// `1 - cos(h)` without cancellation for small `h`.
#[inline]
pub(crate) fn one_minus_cos(h: f32) -> f32 {
    let s = (0.5 * h).sin();
    2.0 * s * s
}

/// Blender's spot attenuation for a direction making cosine `cos_z` with the spot's axis:
/// `smoothstep((cos_z - cos h) / ((1 - cos h) blend))`, a step at the cone's edge for blend 0.
#[inline]
#[must_use]
pub fn spot_attenuation(cos_z: f32, half_angle: f32, blend: f32) -> f32 {
    let c = half_angle.cos();
    if blend <= 0.0 {
        return if cos_z > c { 1.0 } else { 0.0 };
    }
    let f = (cos_z - c) / (one_minus_cos(half_angle) * blend);
    if f <= 0.0 {
        0.0
    } else if f >= 1.0 {
        1.0
    } else {
        f * f * (3.0 - 2.0 * f)
    }
}

/// Blender's area-light spread: `(tan h, 1 / (tan h - h))` for spread `spread` (`h` its half),
/// with the Taylor form of the normalization below `h = 0.05` as Cycles has it.
#[inline]
#[must_use]
pub(crate) fn spread_constants(spread: f32) -> (f32, f32) {
    let h = 0.5 * spread;
    let tan_h = h.tan();
    let norm = if h > 0.05 {
        1.0 / (tan_h - h)
    } else {
        3.0 / (h * h * h)
    };
    (tan_h, norm)
}

/// The spread attenuation `g` toward a direction making cosine `cos_e > 0` with the area
/// light's axis (1 for a spread of pi; see the module docs).
#[inline]
#[must_use]
pub fn spread_attenuation(cos_e: f32, spread: f32) -> f32 {
    if spread >= PI {
        return 1.0;
    }
    if cos_e <= 0.0 {
        return 0.0;
    }
    let (tan_h, norm) = spread_constants(spread);
    let tan_a = (1.0 - cos_e * cos_e).max(0.0).sqrt() / cos_e;
    ((tan_h - tan_a) * norm).max(0.0)
}

/// The area of an area light's shape.
#[inline]
#[must_use]
pub fn area_of(disk: bool, size_x: f32, size_y: f32) -> f32 {
    if disk {
        PI / 4.0 * size_x * size_y
    } else {
        size_x * size_y
    }
}

/// An equirectangular environment image with its sampling tables (see the module docs).
///
/// Invariants: `width, height >= 1`; pixels finite and `>= 0`; `rotation` orthonormal with
/// determinant 1; the CDFs non-decreasing from 0 to 1.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// RGB per pixel, row-major, row 0 at the top (+Z).
    pixels: Vec<Vec3>,
    /// World direction to image direction.
    rotation: Mat3,
    /// Marginal CDF over rows, `height + 1` entries from 0 to 1.
    rows: Vec<f32>,
    /// Conditional CDF of each row, `width + 1` entries each.
    columns: Vec<f32>,
    /// The probability of each pixel.
    mass: Vec<f32>,
    /// The solid angle of one pixel of each row.
    pixel_solid_angle: Vec<f32>,
    /// `int map(w) dw` over the sphere, RGB.
    integral: Vec3,
}

/// The bin of `cdf` (`n + 1` non-decreasing entries from 0 to 1) that `u` falls in, and where
/// in it (`[0, 1)`).
#[inline]
fn select(cdf: &[f32], u: f32) -> (usize, f32) {
    let n = cdf.len() - 1;
    let k = cdf.partition_point(|&c| c <= u).clamp(1, n) - 1;
    let width = cdf[k + 1] - cdf[k];
    let rest = if width > 0.0 {
        ((u - cdf[k]) / width).clamp(0.0, 1.0 - f32::EPSILON / 2.0)
    } else {
        0.5
    };
    (k, rest)
}

/// Writes the `n + 1` entries of the CDF of `weights` (`n` of them) into `cdf`: from 0 to
/// exactly 1, uniform where the weights sum to 0. Returns their sum (added in order).
fn fill_cdf(weights: &[f64], cdf: &mut [f32]) -> f64 {
    let n = weights.len();
    let total: f64 = weights.iter().sum();
    let mut run = 0.0f64;
    for (j, w) in weights.iter().enumerate() {
        cdf[j] = if total > 0.0 {
            (run / total) as f32
        } else {
            j as f32 / n as f32
        };
        run += w;
    }
    cdf[n] = 1.0;
    total
}

impl EnvironmentMap {
    /// Builds the map from `rgb` (`height x width x 3`, row 0 at the top, linear, `>= 0`) and
    /// the `rotation` taking world directions to image directions (identity: Blender's default
    /// mapping).
    ///
    /// Errors: a zero-size image, a wrong length, non-finite or negative values, a rotation
    /// that is not one.
    pub fn new(width: usize, height: usize, rgb: &[f32], rotation: Mat3) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(VplaceError::Empty {
                what: "environment image".into(),
                hint: format!("it is {height} x {width} pixels; give at least 1 x 1"),
            });
        }
        if rgb.len() != width * height * 3 {
            return Err(VplaceError::Shape {
                what: "environment image".into(),
                expected: format!("({height}, {width}, 3)"),
                got: format!("{} values", rgb.len()),
            });
        }
        check_finite("environment image", rgb)?;
        if let Some(i) = rgb.iter().position(|&v| v < 0.0) {
            return Err(VplaceError::OutOfRange {
                what: format!("environment image value at index {i}"),
                value: rgb[i].to_string(),
                expected: ">= 0 (linear radiance)".into(),
            });
        }
        check_finite("environment rotation", &rotation.to_cols_array())?;
        let gram = rotation.transpose() * rotation;
        let off = (gram - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        if off > 1e-3 || rotation.determinant() < 0.0 {
            return Err(VplaceError::Invalid {
                what: "environment rotation".into(),
                reason: "must be a rotation matrix (orthonormal, determinant 1), without scale \
                         or mirroring"
                    .into(),
            });
        }
        let pixels: Vec<Vec3> = rgb.chunks_exact(3).map(Vec3::from_slice).collect();
        let dphi = 2.0 * std::f64::consts::PI / width as f64;
        let pixel_solid_angle: Vec<f64> = (0..height)
            .map(|i| {
                let t0 = std::f64::consts::PI * i as f64 / height as f64;
                let t1 = std::f64::consts::PI * (i + 1) as f64 / height as f64;
                dphi * (t0.cos() - t1.cos())
            })
            .collect();
        let mut columns = vec![0.0f32; height * (width + 1)];
        let mut row_weight = vec![0.0f64; height];
        let mut integral = [0.0f64; 3];
        let mut weights = vec![0.0f64; width * height];
        for i in 0..height {
            for j in 0..width {
                let p = pixels[i * width + j];
                for (s, c) in integral.iter_mut().zip(p.to_array()) {
                    *s += f64::from(c) * pixel_solid_angle[i];
                }
                weights[i * width + j] = f64::from(luminance(p)) * pixel_solid_angle[i];
            }
            row_weight[i] = fill_cdf(
                &weights[i * width..(i + 1) * width],
                &mut columns[i * (width + 1)..(i + 1) * (width + 1)],
            );
        }
        let mut rows = vec![0.0f32; height + 1];
        let total = fill_cdf(&row_weight, &mut rows);
        let mass = weights
            .iter()
            .map(|&w| if total > 0.0 { (w / total) as f32 } else { 0.0 })
            .collect();
        Ok(Self {
            width,
            height,
            pixels,
            rotation,
            rows,
            columns,
            mass,
            pixel_solid_angle: pixel_solid_angle.iter().map(|&o| o as f32).collect(),
            integral: Vec3::new(integral[0] as f32, integral[1] as f32, integral[2] as f32),
        })
    }

    /// Image width, pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height, pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// `int map(w) dw` over the sphere (RGB; `4 pi` for a white map).
    #[must_use]
    pub fn integral(&self) -> Vec3 {
        self.integral
    }

    /// The pixel index that world direction `dir` (unit) looks up.
    #[inline]
    fn pixel(&self, dir: Vec3) -> usize {
        let d = self.rotation * dir;
        let theta = d.z.clamp(-1.0, 1.0).acos();
        let phi = d.y.atan2(d.x);
        let u = 0.5 - phi / (2.0 * PI);
        let j = ((u * self.width as f32).floor() as isize).rem_euclid(self.width as isize) as usize;
        let i = ((theta / PI * self.height as f32) as usize).min(self.height - 1);
        i * self.width + j
    }

    /// The map's value toward world direction `dir` (unit), nearest pixel.
    #[inline]
    #[must_use]
    pub fn value(&self, dir: Vec3) -> Vec3 {
        self.pixels[self.pixel(dir)]
    }

    /// The map's value toward `dir` and the density [`EnvironmentMap::sample`] draws `dir` with
    /// (per steradian).
    #[inline]
    #[must_use]
    pub fn value_and_pdf(&self, dir: Vec3) -> (Vec3, f32) {
        let p = self.pixel(dir);
        (
            self.pixels[p],
            self.mass[p] / self.pixel_solid_angle[p / self.width],
        )
    }

    /// A world direction drawn with density proportional to the map's luminance, and that
    /// density (per steradian). Only meaningful when the map's luminance integral is `> 0`.
    #[inline]
    #[must_use]
    pub fn sample(&self, u1: f32, u2: f32) -> (Vec3, f32) {
        let (i, r1) = select(&self.rows, u1);
        let w = self.width + 1;
        let (j, r2) = select(&self.columns[i * w..(i + 1) * w], u2);
        let (h, wf) = (self.height as f32, self.width as f32);
        let c0 = (PI * i as f32 / h).cos();
        let c1 = (PI * (i + 1) as f32 / h).cos();
        let cos_t = c0 - r1 * (c0 - c1);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * PI * (0.5 - (j as f32 + r2) / wf);
        let d = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
        let dir = (self.rotation.transpose() * d).normalize();
        let p = i * self.width + j;
        (dir, self.mass[p] / self.pixel_solid_angle[i])
    }

    /// The radiance-weighted mean direction the map's light comes from (unit), or `None` when
    /// the map is close to uniform (its luminance-weighted mean direction shorter than 0.1).
    #[must_use]
    pub fn dominant_direction(&self) -> Option<Vec3> {
        let mut sum = Vec3::ZERO;
        let mut total = 0.0f32;
        let (h, wf) = (self.height as f32, self.width as f32);
        for i in 0..self.height {
            let theta = PI * (i as f32 + 0.5) / h;
            for j in 0..self.width {
                let phi = 2.0 * PI * (0.5 - (j as f32 + 0.5) / wf);
                let d = Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let w = self.mass[i * self.width + j];
                sum += self.rotation.transpose() * d * w;
                total += w;
            }
        }
        if total > 0.0 && sum.length() > 0.1 * total {
            Some(sum.normalize())
        } else {
            None
        }
    }
}

/// One emissive triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct EmissiveTriangle {
    a: Vec3,
    e1: Vec3,
    e2: Vec3,
    /// Unit geometric normal.
    normal: Vec3,
    area: f32,
    /// Emitted radiance, both sides.
    radiance: Vec3,
}

/// The triangles whose material emits, with a CDF choosing them by power (area times the
/// luminance of their radiance).
///
/// Invariants: every triangle has a positive area and a radiance with positive luminance;
/// `cdf` has one more entry than there are triangles, from 0 to 1.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EmissiveMesh {
    triangles: Vec<EmissiveTriangle>,
    /// Per triangle of the scene: whether it is one of `triangles`.
    emits: Vec<bool>,
    cdf: Vec<f32>,
    /// The probability of each triangle.
    prob: Vec<f32>,
    /// `sum L A` over the triangles, RGB (the power is `2 pi` times it).
    radiance_area: Vec3,
}

impl EmissiveMesh {
    /// Gathers the emissive triangles of a scene's input (indices already checked).
    ///
    /// Errors: a material emission that is non-finite or negative.
    pub(crate) fn build(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        material_ids: &[u32],
        materials: &[Material],
    ) -> Result<Self> {
        for (m, mat) in materials.iter().enumerate() {
            check_finite(&format!("emission[{m}]"), &mat.emission.to_array())?;
            if mat.emission.min_element() < 0.0 {
                return Err(VplaceError::OutOfRange {
                    what: format!("emission[{m}]"),
                    value: format!("{:?}", mat.emission.to_array()),
                    expected: ">= 0 in every channel (radiance, W/(m^2 sr))".into(),
                });
            }
        }
        let mut out = Vec::new();
        let mut weights = Vec::new();
        let mut emits = vec![false; triangles.len()];
        for ((idx, &m), flag) in triangles.iter().zip(material_ids).zip(&mut emits) {
            let radiance = materials[m as usize].emission;
            if luminance(radiance) <= 0.0 {
                continue;
            }
            let [a, b, c] = idx.map(|i| vertices[i as usize]);
            let (e1, e2) = (b - a, c - a);
            let n = e1.cross(e2);
            let area = 0.5 * n.length();
            if area.is_nan() || area <= 0.0 {
                continue;
            }
            *flag = true;
            weights.push(f64::from(luminance(radiance)) * f64::from(area));
            out.push(EmissiveTriangle {
                a,
                e1,
                e2,
                normal: n.normalize(),
                area,
                radiance,
            });
        }
        let mut cdf = vec![0.0f32; weights.len() + 1];
        let total = fill_cdf(&weights, &mut cdf);
        let prob = weights.iter().map(|w| (w / total) as f32).collect();
        let radiance_area = out.iter().map(|t| t.radiance * t.area).sum();
        Ok(Self {
            triangles: out,
            emits,
            cdf,
            prob,
            radiance_area,
        })
    }

    /// Whether triangle `t` of the scene emits (false for an index past the scene's).
    #[must_use]
    pub fn emits(&self, t: u32) -> bool {
        self.emits.get(t as usize).copied().unwrap_or(false)
    }

    /// Number of emissive triangles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True without emissive triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The power the triangles emit (both sides), RGB watts: `2 pi sum L A`.
    #[must_use]
    pub fn power(&self) -> Vec3 {
        2.0 * PI * self.radiance_area
    }

    /// The power-weighted centroid of the triangles (the origin for an empty mesh).
    #[must_use]
    pub fn centroid(&self) -> Vec3 {
        let mut sum = Vec3::ZERO;
        for (t, &p) in self.triangles.iter().zip(&self.prob) {
            sum += (t.a + (t.e1 + t.e2) / 3.0) * p;
        }
        sum
    }

    /// A point drawn uniformly on a triangle drawn by power: `(point, unit normal, radiance,
    /// probability of the point per unit area)`. `u1` picks the triangle (its remainder is
    /// reused), `u2` the point. Only for a non-empty mesh.
    #[inline]
    #[must_use]
    pub fn sample(&self, u1: f32, u2: f32) -> (Vec3, Vec3, Vec3, f32) {
        let (k, r) = select(&self.cdf, u1);
        let t = &self.triangles[k];
        let s = r.sqrt();
        let p = t.a + t.e1 * (s * (1.0 - u2)) + t.e2 * (s * u2);
        (p, t.normal, t.radiance, self.prob[k] / t.area)
    }
}

/// A source of light of a scene: one of its lights, or all its emissive triangles together.
#[derive(Debug, Clone, Copy)]
pub enum Emitter<'a> {
    /// A light of [`Scene::lights`].
    Light(&'a Light),
    /// The emissive triangles ([`Scene::emissive`]).
    Mesh(&'a EmissiveMesh),
}

impl Emitter<'_> {
    /// A name for messages: the light's kind, or `"emissive triangles"`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Emitter::Light(l) => match l.kind {
                LightKind::Point { .. } => "point",
                LightKind::Spot { .. } => "spot",
                LightKind::Area { .. } => "area",
                LightKind::Sun { .. } => "sun",
                LightKind::World { .. } => "world",
            },
            Emitter::Mesh(_) => "emissive triangles",
        }
    }
}

impl Scene {
    /// Every source of light: the lights in order, then the emissive triangles (when any).
    #[must_use]
    pub fn emitters(&self) -> Vec<Emitter<'_>> {
        let mut out: Vec<Emitter<'_>> = self.lights.iter().map(Emitter::Light).collect();
        if !self.emissive().is_empty() {
            out.push(Emitter::Mesh(self.emissive()));
        }
        out
    }

    /// Centre and radius of the scene's bounding sphere (about the centre of its bounds).
    #[must_use]
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        let (lo, hi) = self.bounds();
        (0.5 * (lo + hi), 0.5 * self.diagonal())
    }

    /// The sphere the sun's and the world's light is sent through, `(centre, radius, start)`:
    /// the working region's ([`Scene::scale`] across, about the centre of the region the
    /// cameras see; the bounding sphere when the scale is the bounds'), and the distance
    /// before its centre at which a parallel ray starts outside every triangle. Light that
    /// meets geometry outside it (a ground plane of a kilometre under a room) is not sent: it
    /// would make VPLs where no camera looks, out of the budget of those it does.
    #[must_use]
    pub fn emission_sphere(&self) -> (Vec3, f32, f32) {
        let (lo, hi) = self.bounds();
        let (a, b) = self.region().unwrap_or((lo, hi));
        let centre = 0.5 * (a + b);
        let far = (centre - lo)
            .max(hi - centre)
            .length()
            .max(0.5 * self.scale());
        (centre, 0.5 * self.scale(), 2.0 * far)
    }
}

/// Total power a light emits into the scene (RGB watts; see the module docs).
#[must_use]
pub fn light_power(light: &Light, scene: &Scene) -> Vec3 {
    let (_, r, _) = scene.emission_sphere();
    match &light.kind {
        LightKind::Point { .. } | LightKind::Area { .. } => light.power,
        LightKind::Spot {
            half_angle, blend, ..
        } => light.power * one_minus_cos(*half_angle) * (1.0 - 0.5 * blend) / 2.0,
        LightKind::Sun { .. } => light.power * PI * r * r,
        LightKind::World { map } => {
            let integral = map.as_ref().map_or(Vec3::splat(4.0 * PI), |m| m.integral());
            light.power * integral * PI * r * r
        }
    }
}

/// Total power an emitter emits into the scene (RGB watts).
#[must_use]
pub fn emitter_power(emitter: Emitter<'_>, scene: &Scene) -> Vec3 {
    match emitter {
        Emitter::Light(l) => light_power(l, scene),
        Emitter::Mesh(m) => m.power(),
    }
}

/// One emission ray: it starts at `origin` and leaves along unit `direction`, carrying the
/// emitter's power times `weight` (per channel, `E[weight] = 1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmissionRay {
    /// Start of the ray, off any emitting surface.
    pub origin: Vec3,
    /// Unit direction.
    pub direction: Vec3,
    /// Flux of the ray over the emitter's power, per channel.
    pub weight: Vec3,
    /// True when it leaves an emissive triangle's back side (against its winding's normal):
    /// the inside of a closed emitter whose normals face out, as Blender's do.
    pub back: bool,
}

impl EmissionRay {
    /// Whether this ray, which first meets `triangle`, is light trapped inside a closed
    /// emitter: it left an emissive triangle's back side and meets an emissive triangle's back
    /// side. Blender's normals face out of a closed mesh, so that light bounces inside the
    /// emitter and never leaves it (Cycles emits on both sides alike). As VPLs it would only
    /// take the budget (a 4 cm emissive strip under a ceiling held 7 of the 12 strongest of 128
    /// VPLs) and light a surface that meets the emitter's face through that face. Light that
    /// leaves an open emitter's back side meets something else and goes on. The light paths
    /// and the RSM leave no VPL for it.
    #[must_use]
    pub fn trapped(&self, scene: &Scene, triangle: u32) -> bool {
        self.back
            && scene.emissive().emits(triangle)
            && scene.normal(triangle).dot(self.direction) > 0.0
    }
}

/// Draws an emission ray of `emitter` from the uniform numbers `next` returns (see the module
/// docs). The numbers are taken in a fixed order per kind (two for a direction, then two for a
/// position where the kind has one), so a point, spot, area light or sun with the parameters of
/// a Blender light of radius 0, blend 0, spread pi and angle 0 draws exactly as before.
pub fn sample_emission(
    emitter: Emitter<'_>,
    scene: &Scene,
    next: &mut impl FnMut() -> f32,
) -> EmissionRay {
    let one = Vec3::ONE;
    let (u1, u2) = (next(), next());
    let light = match emitter {
        Emitter::Light(l) => l,
        Emitter::Mesh(mesh) => return mesh_ray(mesh, scene, u1, u2, next),
    };
    let on_sphere = |radius: f32, next: &mut dyn FnMut() -> f32| {
        if radius > 0.0 {
            light.position + uniform_sphere(next(), next()) * radius
        } else {
            light.position
        }
    };
    match &light.kind {
        LightKind::Point { radius, .. } => {
            if *radius > 0.0 {
                let s = uniform_sphere(next(), next());
                EmissionRay {
                    origin: light.position + s * *radius,
                    direction: cosine_direction(s, u1, u2),
                    weight: one,
                    back: false,
                }
            } else {
                EmissionRay {
                    origin: light.position,
                    direction: uniform_sphere(u1, u2),
                    weight: one,
                    back: false,
                }
            }
        }
        LightKind::Spot {
            half_angle,
            blend,
            radius,
            ..
        } => {
            // Uniform over the spherical cap: cos theta uniform in [cos half_angle, 1], weighted
            // by the blend's attenuation over its mean `1 - blend / 2`.
            let d = uniform_cone(light.direction, one_minus_cos(*half_angle), u1, u2);
            let cos_z = d.dot(light.direction).min(1.0);
            let w = if *blend > 0.0 {
                spot_attenuation(cos_z, *half_angle, *blend) / (1.0 - 0.5 * blend)
            } else {
                1.0
            };
            EmissionRay {
                origin: on_sphere(*radius, next),
                direction: d,
                weight: Vec3::splat(w),
                back: false,
            }
        }
        LightKind::Area {
            disk,
            size_x,
            size_y,
            spread,
        } => {
            let (v1, v2) = (next(), next());
            let bitangent = light.direction.cross(light.tangent);
            let offset = if *disk {
                let r = 0.5 * v1.sqrt();
                let a = 2.0 * PI * v2;
                light.tangent * (r * a.cos() * size_x) + bitangent * (r * a.sin() * size_y)
            } else {
                light.tangent * ((v1 - 0.5) * size_x) + bitangent * ((v2 - 0.5) * size_y)
            };
            let (d, w) = area_direction(light.direction, *spread, u1, u2);
            EmissionRay {
                origin: light.position + offset,
                direction: d,
                weight: Vec3::splat(w),
                back: false,
            }
        }
        LightKind::Sun { angle } => {
            // Parallel rays from a disk of radius R (the bounding sphere's) perpendicular to the
            // direction, placed outside the scene bounds; with an angle, the direction is drawn
            // in the sun's cone first and the disk faces it.
            let d = if *angle > PARALLEL_SUN {
                uniform_cone(light.direction, one_minus_cos(0.5 * angle), next(), next())
            } else {
                light.direction
            };
            EmissionRay {
                origin: outside_disk(scene, d, u1, u2),
                direction: d,
                weight: one,
                back: false,
            }
        }
        LightKind::World { map } => world_ray(map.as_deref(), scene, u1, u2, next),
    }
}

/// [`sample_emission`] of emissive triangles: a point by power (`u1`, `u2`), a side, then a
/// cosine direction from it.
fn mesh_ray(
    mesh: &EmissiveMesh,
    scene: &Scene,
    u1: f32,
    u2: f32,
    next: &mut impl FnMut() -> f32,
) -> EmissionRay {
    let (p, n, radiance, pdf_area) = mesh.sample(u1, u2);
    let back = next() >= 0.5;
    let side = if back { -n } else { n };
    let d = cosine_direction(side, next(), next());
    // Flux of the ray `L A / p` per side over the half power `pi sum L A` of a side.
    let weight = Vec3::select(
        mesh.radiance_area.cmpgt(Vec3::ZERO),
        radiance / (pdf_area * mesh.radiance_area),
        Vec3::ZERO,
    );
    EmissionRay {
        origin: p + side * scene.ray_epsilon(),
        direction: d,
        weight,
        back,
    }
}

/// [`sample_emission`] of the world: a direction from its map (`u1`, `u2`), then a start on
/// the disk outside the scene.
fn world_ray(
    map: Option<&EnvironmentMap>,
    scene: &Scene,
    u1: f32,
    u2: f32,
    next: &mut impl FnMut() -> f32,
) -> EmissionRay {
    let one = Vec3::ONE;
    // `w` is where the light comes from; the ray travels along `-w`.
    let (w, weight) = match map {
        Some(m) => {
            let (w, pdf) = m.sample(u1, u2);
            let value = m.value(w);
            let ok = m.integral().cmpgt(Vec3::ZERO);
            let weight = Vec3::select(ok, value / (pdf * m.integral()), Vec3::ZERO);
            (w, if pdf > 0.0 { weight } else { Vec3::ZERO })
        }
        None => (uniform_sphere(u1, u2), one),
    };
    let (v1, v2) = (next(), next());
    EmissionRay {
        origin: outside_disk(scene, -w, v1, v2),
        direction: -w,
        weight,
        back: false,
    }
}

/// The start of a parallel ray travelling along unit `d`: a point uniform on the disk of the
/// emission sphere's radius ([`Scene::emission_sphere`]), perpendicular to `d`, outside every
/// triangle before the centre (twice the radius before it when the sphere bounds the scene).
fn outside_disk(scene: &Scene, d: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (centre, radius, start) = scene.emission_sphere();
    let (t, b) = basis(d);
    let r = radius * u1.sqrt();
    let a = 2.0 * PI * u2;
    centre - d * start + (t * a.cos() + b * a.sin()) * r
}

/// A direction leaving an area light of axis `axis` and spread `spread`, and its weight (mean
/// 1): cosine-distributed for a spread of pi; otherwise uniform in the spread's cone, weighted
/// by `cos g / pi` over the cone's density.
#[inline]
pub(crate) fn area_direction(axis: Vec3, spread: f32, u1: f32, u2: f32) -> (Vec3, f32) {
    if spread >= PI {
        return (cosine_direction(axis, u1, u2), 1.0);
    }
    if spread < COLLIMATED_SPREAD {
        return (axis, 1.0);
    }
    let omc = one_minus_cos(0.5 * spread);
    let d = uniform_cone(axis, omc, u1, u2);
    let cos_e = d.dot(axis).clamp(0.0, 1.0);
    let w = cos_e * spread_attenuation(cos_e, spread) / PI * (2.0 * PI * omc);
    (d, w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::test_util::closed_box;

    /// The mean over `n` draws of `f(u1, u2)` with stratified numbers.
    fn mean2(n: usize, mut f: impl FnMut(f32, f32) -> f64) -> f64 {
        let mut rng = Rng::new(5, 5);
        let k = (n as f64).sqrt() as usize;
        let mut s = 0.0;
        for i in 0..k {
            for j in 0..k {
                let u1 = (i as f32 + rng.next_f32()) / k as f32;
                let u2 = (j as f32 + rng.next_f32()) / k as f32;
                s += f(u1, u2);
            }
        }
        s / (k * k) as f64
    }

    fn gradient_map(w: usize, h: usize) -> Vec<f32> {
        // A bright patch near the zenith on a dim, coloured gradient.
        let mut px = Vec::with_capacity(w * h * 3);
        for i in 0..h {
            for j in 0..w {
                let hot = i < h / 6 && (w / 3..w / 2).contains(&j);
                let base = 0.1 + 0.4 * j as f32 / w as f32;
                let v = if hot { 20.0 } else { base };
                px.extend([v, 0.5 * v, 0.25 * v + 0.01 * i as f32]);
            }
        }
        px
    }

    #[test]
    fn environment_pdf_integrates_to_one_and_matches_samples() {
        let (w, h) = (24, 12);
        let rot = Mat3::from_rotation_z(0.7) * Mat3::from_rotation_x(0.3);
        let m = EnvironmentMap::new(w, h, &gradient_map(w, h), rot).unwrap();
        // The density integrates to 1 over the sphere (uniform directions).
        let integral = mean2(40_000, |u1, u2| {
            f64::from(m.value_and_pdf(uniform_sphere(u1, u2)).1) * 4.0 * std::f64::consts::PI
        });
        assert!((integral - 1.0).abs() < 0.02, "{integral}");
        // Sampled directions have the density the map says, and a histogram of which pixel they
        // land in matches the pixel masses.
        let mut hist = vec![0usize; w * h];
        let n = 200_000;
        let mut rng = Rng::new(1, 2);
        for _ in 0..n {
            let (d, pdf) = m.sample(rng.next_f32(), rng.next_f32());
            assert!((d.length() - 1.0).abs() < 1e-4);
            let (_, pdf2) = m.value_and_pdf(d);
            assert!((pdf - pdf2).abs() <= 1e-3 * pdf.max(1e-3), "{pdf} {pdf2}");
            hist[m.pixel(d)] += 1;
        }
        for (p, &count) in hist.iter().enumerate() {
            let expect = f64::from(m.mass[p]) * n as f64;
            let sigma = expect.sqrt().max(1.0);
            assert!(
                (count as f64 - expect).abs() < 5.0 * sigma + 2.0,
                "pixel {p}: {count} vs {expect}"
            );
        }
        // The integral of the map is the solid-angle sum (the hot patch dominates).
        let direct = mean2(40_000, |u1, u2| {
            f64::from(m.value(uniform_sphere(u1, u2)).x) * 4.0 * std::f64::consts::PI
        });
        assert!((direct / f64::from(m.integral().x) - 1.0).abs() < 0.03);
    }

    #[test]
    fn environment_follows_blenders_equirectangular_convention() {
        // Pixel (row 0) is the zenith; the centre column faces +X, a quarter to the left +Y.
        let (w, h) = (8, 4);
        let mut px = vec![0.0f32; w * h * 3];
        let mut set = |i: usize, j: usize, v: f32| px[3 * (i * w + j)] = v;
        set(0, 0, 1.0); // top row
        set(2, 4, 2.0); // just below the horizon, u in [0.5, 0.625): +X turning to -Y
        set(1, 2, 3.0); // above the horizon, u in [0.25, 0.375): +Y side
        let m = EnvironmentMap::new(w, h, &px, Mat3::IDENTITY).unwrap();
        assert_eq!(m.pixel(Vec3::Z) / w, 0);
        assert_eq!(m.pixel(Vec3::NEG_Z) / w, h - 1);
        assert_eq!(m.value(Vec3::new(1.0, -0.1, -0.2).normalize()).x, 2.0);
        assert_eq!(m.value(Vec3::new(0.2, 1.0, 0.3).normalize()).x, 3.0);
        // A rotation turns the lookup: world +Y looks where the image has +X.
        let r = Mat3::from_rotation_z(-PI / 2.0);
        let m = EnvironmentMap::new(w, h, &px, r).unwrap();
        assert_eq!(m.value(Vec3::new(0.1, 1.0, -0.2).normalize()).x, 2.0);
    }

    #[test]
    fn environment_errors() {
        assert!(matches!(
            EnvironmentMap::new(0, 4, &[], Mat3::IDENTITY),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            EnvironmentMap::new(2, 1, &[0.0; 5], Mat3::IDENTITY),
            Err(VplaceError::Shape { .. })
        ));
        let mut px = [0.5f32; 6];
        px[4] = f32::NAN;
        assert!(matches!(
            EnvironmentMap::new(2, 1, &px, Mat3::IDENTITY),
            Err(VplaceError::NonFinite { index: 4, .. })
        ));
        px[4] = -1.0;
        assert!(matches!(
            EnvironmentMap::new(2, 1, &px, Mat3::IDENTITY),
            Err(VplaceError::OutOfRange { .. })
        ));
        px[4] = 1.0;
        assert!(matches!(
            EnvironmentMap::new(2, 1, &px, Mat3::from_diagonal(Vec3::splat(2.0))),
            Err(VplaceError::Invalid { .. })
        ));
        assert!(matches!(
            EnvironmentMap::new(2, 1, &px, Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0))),
            Err(VplaceError::Invalid { .. })
        ));
        // An all-black map is valid: it emits nothing.
        let m = EnvironmentMap::new(2, 1, &[0.0; 6], Mat3::IDENTITY).unwrap();
        assert_eq!(m.integral(), Vec3::ZERO);
    }

    #[test]
    fn spot_and_spread_attenuations_have_blenders_shape_and_normalization() {
        let h = 0.6f32;
        assert_eq!(spot_attenuation(h.cos() + 1e-4, h, 0.0), 1.0);
        assert_eq!(spot_attenuation(h.cos() - 1e-4, h, 0.0), 0.0);
        // The smoothstep covers `blend` of the cap's `1 - cos` range.
        let c = h.cos();
        let edge = c + 0.4 * (1.0 - c);
        assert!((spot_attenuation(edge, h, 0.4) - 1.0).abs() < 1e-5);
        assert!((spot_attenuation(0.5 * (c + edge), h, 0.4) - 0.5).abs() < 1e-4);
        // The mean of the attenuation over the cap is 1 - blend / 2 (the power formula).
        for blend in [0.0f32, 0.3, 1.0] {
            let mean = mean2(40_000, |u, _| {
                let cos = 1.0 - u * one_minus_cos(h);
                f64::from(spot_attenuation(cos, h, blend))
            });
            assert!(
                (mean - f64::from(1.0 - blend / 2.0)).abs() < 2e-3,
                "{blend} {mean}"
            );
        }
        // The spread attenuation keeps an area light's power: `cos g / pi` integrates to 1 over
        // the spread's cone (hence the hemisphere) for every spread, and `g` is 0 outside it.
        for spread in [0.02f32, 0.3, 1.0, 2.0, 3.0, PI] {
            let h = 0.5 * spread;
            let omc = one_minus_cos(h.min(PI / 2.0));
            let integral = mean2(90_000, |u1, u2| {
                let d = uniform_cone(Vec3::Z, omc, u1, u2);
                let g = spread_attenuation(d.z, spread);
                f64::from(d.z * g / PI * 2.0 * PI * omc)
            });
            assert!((integral - 1.0).abs() < 0.01, "{spread}: {integral}");
            if spread < PI {
                assert_eq!(spread_attenuation((h + 0.01).cos(), spread), 0.0);
                assert!(spread_attenuation((0.5 * h).cos(), spread) > 0.0);
            }
        }
    }

    #[test]
    fn area_directions_have_mean_weight_one_inside_the_spread() {
        for spread in [0.2f32, 1.0, 2.5, PI] {
            let mut inside = true;
            let mean = mean2(40_000, |u1, u2| {
                let (d, w) = area_direction(Vec3::Z, spread, u1, u2);
                inside &= d.z >= (0.5 * spread).cos() - 1e-4;
                f64::from(w)
            });
            assert!(inside);
            assert!((mean - 1.0).abs() < 0.01, "{spread}: {mean}");
        }
        assert_eq!(
            area_direction(Vec3::Y, 0.0, 0.3, 0.7),
            (Vec3::Y, 1.0),
            "collimated"
        );
    }

    #[test]
    fn emissive_triangles_are_chosen_by_power() {
        let v = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0., 0., 1.),
            Vec3::new(2., 0., 1.),
            Vec3::new(0., 2., 1.),
        ];
        let t = [[0, 1, 2], [3, 4, 5], [0, 1, 2]];
        let mats = [
            Material::diffuse(Vec3::splat(0.5)).with_emission(Vec3::new(1.0, 0.0, 0.0)),
            Material::diffuse(Vec3::splat(0.5)).with_emission(Vec3::splat(0.5)),
            Material::diffuse(Vec3::splat(0.5)),
        ];
        let mesh = EmissiveMesh::build(&v, &t, &[0, 1, 2], &mats).unwrap();
        assert_eq!(mesh.len(), 2, "the third triangle does not emit");
        // Areas 0.5 and 2: power 2 pi (0.5 (1, 0, 0) + 2 (0.5, 0.5, 0.5)).
        let expect = 2.0 * PI * Vec3::new(1.5, 1.0, 1.0);
        assert!((mesh.power() - expect).abs().max_element() < 1e-5);
        // Luminance weights: 0.5 * 0.2126 and 2 * 0.5.
        let w0 = 0.5 * 0.2126f32;
        let p0 = w0 / (w0 + 1.0);
        let mut rng = Rng::new(3, 3);
        let n = 100_000;
        let mut first = 0;
        for _ in 0..n {
            let (p, nrm, rad, pdf) = mesh.sample(rng.next_f32(), rng.next_f32());
            if p.z < 0.5 {
                first += 1;
                assert!(p.x >= -1e-6 && p.y >= -1e-6 && p.x + p.y <= 1.0 + 1e-5);
                assert_eq!(rad, Vec3::new(1.0, 0.0, 0.0));
                assert!((pdf - p0 / 0.5).abs() < 1e-4);
            } else {
                assert!((pdf - (1.0 - p0) / 2.0).abs() < 1e-4);
            }
            assert!((nrm - Vec3::Z).length() < 1e-6);
        }
        let got = first as f32 / n as f32;
        assert!((got - p0).abs() < 0.005, "{got} {p0}");
        let bad = [Material::diffuse(Vec3::ONE).with_emission(Vec3::new(0., -1., 0.))];
        assert!(EmissiveMesh::build(&v, &t[..1], &[0], &bad).is_err());
        let bad = [Material::diffuse(Vec3::ONE).with_emission(Vec3::new(0., f32::NAN, 0.))];
        assert!(matches!(
            EmissiveMesh::build(&v, &t[..1], &[0], &bad),
            Err(VplaceError::NonFinite { .. })
        ));
    }

    #[test]
    fn emission_weights_average_to_one() {
        // Every kind: the mean weight of its emission rays is 1 per channel, directions unit.
        let map = EnvironmentMap::new(12, 6, &gradient_map(12, 6), Mat3::IDENTITY).unwrap();
        let lights = [
            Light::point(Vec3::new(0., 0., 1.), Vec3::ONE).with_radius(0.2, false),
            Light::spot(Vec3::new(0., 0., 1.), Vec3::NEG_Z, 0.7, Vec3::ONE).with_blend(0.6),
            Light::area(
                Vec3::new(0., 0., 1.9),
                Vec3::NEG_Z,
                Vec3::X,
                true,
                0.3,
                0.5,
                Vec3::ONE,
            )
            .with_spread(0.8),
            Light::sun(Vec3::new(0.2, 0.1, -1.0), Vec3::ONE).with_angle(0.3),
            Light::world(Vec3::ONE, Some(std::sync::Arc::new(map))),
            Light::world(Vec3::ONE, None),
        ];
        let s = closed_box(lights.to_vec());
        for light in &lights {
            let mut rng = Rng::new(9, 1);
            let mut next = || rng.next_f32();
            let n = 100_000;
            let mut sum = Vec3::ZERO;
            for _ in 0..n {
                let r = sample_emission(Emitter::Light(light), &s, &mut next);
                assert!((r.direction.length() - 1.0).abs() < 1e-4);
                assert!(r.weight.min_element() >= 0.0 && r.weight.is_finite());
                sum += r.weight;
            }
            let mean = sum / n as f32;
            assert!(
                (mean - Vec3::ONE).abs().max_element() < 0.03,
                "{:?}: {mean}",
                light.kind
            );
        }
    }
}
