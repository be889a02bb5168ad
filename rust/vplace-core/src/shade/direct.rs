//! The direct-light estimator: the irradiance over pi that every light source of a scene gives
//! the covered pixels of a G-buffer, with shadow rays. This is what Cycles' `Diffuse Direct`
//! pass (DiffDir) holds on a diffuse surface, so a view's direct light can be computed without
//! Blender and compared with the capture.
//!
//! Per pixel (position `x`, unit normal `n`, shadow rays from `x` pushed off the surface by the
//! scene's ray epsilon) and per emitter ([`crate::scene::emitters`], Blender's units):
//! - point or spot of radius 0, sun of angle 0: the one exact term, one shadow ray;
//! - point or spot with a radius: the disk facing `x` sampled by area (soft falloff, Blender's
//!   default) or the sphere's visible cone sampled uniformly in solid angle; the spot's blend
//!   attenuation evaluated on each sampled direction (as Cycles does);
//! - area light: its rectangle or ellipse sampled by area; with a spread, the smaller of the
//!   shape and the disk of the light plane that can reach `x` (radius `height tan(spread / 2)`,
//!   samples outside the shape count zero); a collimated light (spread 0) is one exact term;
//! - sun with an angle: its cone sampled uniformly in solid angle;
//! - world: cosine-weighted directions, plus, with an image, directions drawn from its
//!   importance map, combined by the balance heuristic (multiple importance sampling);
//! - emissive triangles: a triangle chosen by power, a point uniform on it.
//!
//! `samples` is the number of samples per pixel and per emitter for the sampled kinds. The
//! samples of a pixel and emitter form a rank-1 (Fibonacci) lattice shifted by a random offset
//! (Cranley-Patterson rotation): stratified, so soft shadows converge much faster than with
//! independent samples. Random numbers come from a stream per pixel and emitter: the image is
//! the same for a seed whatever the thread count. Rows of pixels run in parallel (rayon), each
//! with one traversal state for its shadow rays; the cancel flag of [`Progress`] is polled per
//! row.

use glam::{Vec3, Vec3A};
use obvhs::{cwbvh::Traversal, ray::Ray};
use rayon::prelude::*;
use std::f32::consts::PI;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use crate::error::{Result, VplaceError};
use crate::progress::Progress;
use crate::rng::Rng;
use crate::scene::emitters::{
    area_of, basis, concentric_disk, cosine_direction, one_minus_cos, spot_attenuation,
    spread_attenuation, uniform_cone, EmissiveMesh, Emitter, EnvironmentMap, COLLIMATED_SPREAD,
    PARALLEL_SUN,
};
use crate::scene::{Light, LightKind, Scene};
use crate::view::GBuffer;

/// The most samples per pixel and emitter a call may ask for.
pub const MAX_SAMPLES: usize = 1 << 16;

/// Settings of [`direct_light`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DirectParams {
    /// Samples per pixel and per emitter for the sampled kinds (`1..=MAX_SAMPLES`); the exact
    /// kinds (radius 0, angle 0) take one shadow ray whatever this is.
    pub samples: usize,
    /// Seed of the random numbers: the same seed gives the same image.
    pub seed: u64,
}

impl DirectParams {
    /// 64 samples, seed 0: a few percent of noise in soft shadows.
    pub const PREVIEW: Self = Self {
        samples: 64,
        seed: 0,
    };
}

impl Default for DirectParams {
    fn default() -> Self {
        Self::PREVIEW
    }
}

/// What a call of [`direct_light`] cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DirectStats {
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// The golden ratio's fractional part, the generator of the rank-1 lattice.
const GOLDEN: f64 = 0.618_033_988_749_894_8;

/// `n` stratified points of `[0, 1)^2`: a Fibonacci lattice shifted by a random offset.
#[derive(Debug, Clone, Copy)]
struct Lattice {
    n: usize,
    shift: (f32, f32),
}

impl Lattice {
    fn new(n: usize, rng: &mut Rng) -> Self {
        Self {
            n,
            shift: (rng.next_f32(), rng.next_f32()),
        }
    }

    #[inline]
    fn point(&self, i: usize) -> (f32, f32) {
        let u = ((i as f64 + 0.5) / self.n as f64) as f32 + self.shift.0;
        let v = (i as f64 * GOLDEN).fract() as f32 + self.shift.1;
        (u.fract(), v.fract())
    }
}

/// Shadow rays with one traversal state.
struct Tracer<'a> {
    scene: &'a Scene,
    state: Traversal,
    rays: u64,
    /// Ray length that leaves the scene from any receiver.
    far: f32,
    eps: f32,
}

impl Tracer<'_> {
    /// True when nothing lies on the segment from `o` along unit `d` up to `tmax`.
    #[inline]
    fn visible(&mut self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        if tmax.is_nan() || tmax <= 0.0 {
            return true;
        }
        self.rays += 1;
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
        !self.scene.occluded_ray(&mut self.state, &ray)
    }

    /// True when nothing lies between `o` and the point `y`, `y` itself excluded by the ray
    /// epsilon when `surface` (a point on an emitting triangle).
    #[inline]
    fn visible_to(&mut self, o: Vec3, y: Vec3, surface: bool) -> bool {
        let e = y - o;
        let len = e.length();
        if len <= 0.0 {
            return true;
        }
        let tmax = if surface { len - self.eps } else { len };
        self.visible(o, e / len, tmax)
    }
}

/// A receiver: position, unit normal, and the start of its shadow rays.
#[derive(Debug, Clone, Copy)]
struct Point {
    x: Vec3,
    n: Vec3,
    o: Vec3,
}

/// The irradiance (W/m^2 per channel) of a point or spot light (`spot`: half angle and blend).
fn point_light(
    t: &mut Tracer,
    light: &Light,
    (radius, soft): (f32, bool),
    spot: Option<(f32, f32)>,
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    let to = light.position - p.x;
    let d2 = to.length_squared();
    if d2.is_nan() || d2 <= 0.0 {
        return Vec3::ZERO;
    }
    let d = d2.sqrt();
    let l = to / d;
    // The spot's attenuation of light leaving along unit `w` (from the light to the receiver).
    let atten = |w: Vec3| spot.map_or(1.0, |(h, b)| spot_attenuation(w.dot(light.direction), h, b));
    if radius <= 0.0 {
        let cos_r = p.n.dot(l);
        let a = atten(-l);
        if cos_r <= 0.0 || a <= 0.0 || !t.visible_to(p.o, light.position, false) {
            return Vec3::ZERO;
        }
        return light.power * (a * cos_r / (4.0 * PI * d2));
    }
    let radiance = light.power / (4.0 * PI * PI * radius * radius);
    let lattice = Lattice::new(samples, rng);
    let mut sum = 0.0f32;
    if soft {
        // A disk of the radius facing the receiver, sampled by area.
        let facing = -l;
        let (tu, tv) = basis(facing);
        for i in 0..samples {
            let (a1, a2) = lattice.point(i);
            let (dx, dy) = concentric_disk(a1, a2);
            let y = light.position + (tu * dx + tv * dy) * radius;
            let e = y - p.x;
            let t2 = e.length_squared();
            let w = e / t2.sqrt();
            let cos_r = p.n.dot(w);
            let cos_e = facing.dot(-w);
            if cos_r <= 0.0 || cos_e <= 0.0 {
                continue;
            }
            let a = atten(-w);
            if a > 0.0 && t.visible_to(p.o, y, false) {
                sum += a * cos_r * cos_e / t2;
            }
        }
        return radiance * (PI * radius * radius * sum / samples as f32);
    }
    if d <= radius {
        // Inside the sphere: light from every direction of the hemisphere, unshadowed.
        return radiance * PI;
    }
    // The sphere's visible cone, uniform in solid angle.
    let sin2 = radius * radius / d2;
    let omc = sin2 / (1.0 + (1.0 - sin2).sqrt());
    for i in 0..samples {
        let (a1, a2) = lattice.point(i);
        let w = uniform_cone(l, omc, a1, a2);
        let cos_r = p.n.dot(w);
        if cos_r <= 0.0 {
            continue;
        }
        let b = w.dot(to);
        let dist = b - (radius * radius - (d2 - b * b)).max(0.0).sqrt();
        let a = atten(-w);
        if a > 0.0 && t.visible(p.o, w, dist) {
            sum += a * cos_r;
        }
    }
    radiance * (2.0 * PI * omc * sum / samples as f32)
}

/// The irradiance of an area light.
fn area_light(
    t: &mut Tracer,
    light: &Light,
    (disk, size_x, size_y, spread): (bool, f32, f32, f32),
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    let axis = light.direction;
    let (tu, tv) = (light.tangent, axis.cross(light.tangent));
    let c = light.position;
    let height = (p.x - c).dot(axis);
    if height.is_nan() || height <= 0.0 {
        return Vec3::ZERO;
    }
    let area = area_of(disk, size_x, size_y);
    let inside = |u: f32, v: f32| {
        if disk {
            let (a, b) = (2.0 * u / size_x, 2.0 * v / size_y);
            a * a + b * b <= 1.0
        } else {
            u.abs() <= 0.5 * size_x && v.abs() <= 0.5 * size_y
        }
    };
    let foot = p.x - axis * height;
    let (pu, pv) = ((foot - c).dot(tu), (foot - c).dot(tv));
    if spread < COLLIMATED_SPREAD {
        // A collimated beam: flux P / A per unit area along the axis.
        let cos_r = -p.n.dot(axis);
        if cos_r <= 0.0 || !inside(pu, pv) || !t.visible(p.o, -axis, (p.o - c).dot(axis)) {
            return Vec3::ZERO;
        }
        return light.power * (cos_r / area);
    }
    let spread_radius = if spread < PI {
        height * (0.5 * spread).tan()
    } else {
        f32::INFINITY
    };
    let spread_disk = PI * spread_radius * spread_radius < area;
    let region = if spread_disk {
        PI * spread_radius * spread_radius
    } else {
        area
    };
    let lattice = Lattice::new(samples, rng);
    let mut sum = 0.0f32;
    for i in 0..samples {
        let (a1, a2) = lattice.point(i);
        let (u, v) = if spread_disk {
            let (dx, dy) = concentric_disk(a1, a2);
            (pu + spread_radius * dx, pv + spread_radius * dy)
        } else if disk {
            let (dx, dy) = concentric_disk(a1, a2);
            (0.5 * size_x * dx, 0.5 * size_y * dy)
        } else {
            ((a1 - 0.5) * size_x, (a2 - 0.5) * size_y)
        };
        if spread_disk && !inside(u, v) {
            continue;
        }
        let y = c + tu * u + tv * v;
        let e = y - p.x;
        let t2 = e.length_squared();
        let w = e / t2.sqrt();
        let cos_r = p.n.dot(w);
        let cos_e = -w.dot(axis);
        if cos_r <= 0.0 || cos_e <= 0.0 {
            continue;
        }
        let g = spread_attenuation(cos_e, spread);
        if g > 0.0 && t.visible_to(p.o, y, true) {
            sum += g * cos_r * cos_e / t2;
        }
    }
    light.power / (PI * area) * (region * sum / samples as f32)
}

/// The irradiance of a sun of full angle `angle`.
fn sun_light(
    t: &mut Tracer,
    light: &Light,
    angle: f32,
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    let toward = -light.direction;
    if angle < PARALLEL_SUN {
        let cos_r = p.n.dot(toward);
        if cos_r <= 0.0 || !t.visible(p.o, toward, t.far) {
            return Vec3::ZERO;
        }
        return light.power * cos_r;
    }
    let h = 0.5 * angle;
    let omc = one_minus_cos(h);
    let lattice = Lattice::new(samples, rng);
    let mut sum = 0.0f32;
    for i in 0..samples {
        let (a1, a2) = lattice.point(i);
        let w = uniform_cone(toward, omc, a1, a2);
        let cos_r = p.n.dot(w);
        if cos_r > 0.0 && t.visible(p.o, w, t.far) {
            sum += cos_r;
        }
    }
    // Radiance `P / (pi sin^2 h)` over the cone's density `1 / (2 pi omc)`.
    let s = h.sin();
    light.power * (2.0 * omc / (s * s) * sum / samples as f32)
}

/// The irradiance of the world (radiance `light.power` times `map`).
fn world_light(
    t: &mut Tracer,
    light: &Light,
    map: Option<&EnvironmentMap>,
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    let Some(m) = map else {
        // A uniform world: cosine-weighted directions, `E = pi L (fraction unoccluded)`.
        let lattice = Lattice::new(samples, rng);
        let mut open = 0u32;
        for i in 0..samples {
            let (a1, a2) = lattice.point(i);
            let w = cosine_direction(p.n, a1, a2);
            if p.n.dot(w) > 0.0 && t.visible(p.o, w, t.far) {
                open += 1;
            }
        }
        return light.power * (PI * open as f32 / samples as f32);
    };
    if crate::color::luminance(m.integral()) <= 0.0 {
        return Vec3::ZERO;
    }
    let n_map = samples / 2;
    let n_cos = samples - n_map;
    let (fc, fm) = (n_cos as f32, n_map as f32);
    let mut sum = Vec3::ZERO;
    let lattice = Lattice::new(n_cos, rng);
    for i in 0..n_cos {
        let (a1, a2) = lattice.point(i);
        let w = cosine_direction(p.n, a1, a2);
        let cos = p.n.dot(w);
        if cos <= 0.0 {
            continue;
        }
        let (value, pdf_map) = m.value_and_pdf(w);
        if value == Vec3::ZERO || !t.visible(p.o, w, t.far) {
            continue;
        }
        sum += value * (cos / (fc * cos / PI + fm * pdf_map));
    }
    if n_map > 0 {
        let lattice = Lattice::new(n_map, rng);
        for i in 0..n_map {
            let (a1, a2) = lattice.point(i);
            let (w, pdf_map) = m.sample(a1, a2);
            let cos = p.n.dot(w);
            if cos <= 0.0 || pdf_map <= 0.0 || !t.visible(p.o, w, t.far) {
                continue;
            }
            sum += m.value(w) * (cos / (fc * cos / PI + fm * pdf_map));
        }
    }
    light.power * sum
}

/// The irradiance of the emissive triangles.
fn mesh_light(
    t: &mut Tracer,
    mesh: &EmissiveMesh,
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    let lattice = Lattice::new(samples, rng);
    let mut sum = Vec3::ZERO;
    for i in 0..samples {
        let (a1, a2) = lattice.point(i);
        let (y, ny, radiance, pdf_area) = mesh.sample(a1, a2);
        let e = y - p.x;
        let t2 = e.length_squared();
        if t2.is_nan() || t2 <= 1e-12 {
            continue;
        }
        let w = e / t2.sqrt();
        let cos_r = p.n.dot(w);
        let cos_e = ny.dot(w).abs();
        if cos_r <= 0.0 || cos_e <= 0.0 || !t.visible_to(p.o, y, true) {
            continue;
        }
        sum += radiance * (cos_r * cos_e / (t2 * pdf_area));
    }
    sum / samples as f32
}

/// The irradiance (W/m^2 per channel) that `emitter` gives receiver `p`.
fn irradiance(
    t: &mut Tracer,
    emitter: Emitter<'_>,
    p: Point,
    samples: usize,
    rng: &mut Rng,
) -> Vec3 {
    match emitter {
        Emitter::Mesh(mesh) => mesh_light(t, mesh, p, samples, rng),
        Emitter::Light(light) => match &light.kind {
            LightKind::Point {
                radius,
                soft_falloff,
            } => point_light(t, light, (*radius, *soft_falloff), None, p, samples, rng),
            LightKind::Spot {
                half_angle,
                blend,
                radius,
                soft_falloff,
            } => point_light(
                t,
                light,
                (*radius, *soft_falloff),
                Some((*half_angle, *blend)),
                p,
                samples,
                rng,
            ),
            LightKind::Area {
                disk,
                size_x,
                size_y,
                spread,
            } => area_light(
                t,
                light,
                (*disk, *size_x, *size_y, *spread),
                p,
                samples,
                rng,
            ),
            LightKind::Sun { angle } => sun_light(t, light, *angle, p, samples, rng),
            LightKind::World { map } => world_light(t, light, map.as_deref(), p, samples, rng),
        },
    }
}

/// The direct irradiance over pi of every covered pixel of `gbuffer` from every emitter of
/// `scene` (`H x W x 3`, uncovered pixels and pixels without a normal 0): what Cycles' DiffDir
/// pass holds on a diffuse surface. See the module docs for how each kind is sampled.
///
/// Errors: a bad G-buffer, `samples` outside `1..=MAX_SAMPLES`, cancellation.
pub fn direct_light(
    scene: &Scene,
    gbuffer: &GBuffer,
    params: &DirectParams,
    progress: Option<&Progress>,
) -> Result<(Vec<f32>, DirectStats)> {
    gbuffer.validate()?;
    if params.samples == 0 || params.samples > MAX_SAMPLES {
        return Err(VplaceError::OutOfRange {
            what: "samples".into(),
            value: params.samples.to_string(),
            expected: format!("1 to {MAX_SAMPLES}"),
        });
    }
    let start = Instant::now();
    let (w, h) = (gbuffer.width, gbuffer.height);
    if let Some(pr) = progress {
        pr.total.store(h, Ordering::Relaxed);
        pr.done.store(0, Ordering::Relaxed);
    }
    let emitters = scene.emitters();
    let n_emitters = emitters.len() as u64;
    let eps = scene.ray_epsilon();
    let (centre, radius) = scene.bounding_sphere();
    let rays = AtomicU64::new(0);
    let cancelled = || progress.is_some_and(|p| p.cancel.load(Ordering::Relaxed));
    let rows: Vec<Option<Vec<f32>>> = (0..h)
        .into_par_iter()
        .map(|y| {
            if cancelled() {
                return None;
            }
            let mut row = vec![0.0f32; 3 * w];
            let mut tracer = Tracer {
                scene,
                state: scene.shadow_state(),
                rays: 0,
                far: 0.0,
                eps,
            };
            for x in 0..w {
                let pix = y * w + x;
                if !gbuffer.covered[pix] {
                    continue;
                }
                let at = |a: &[f32]| Vec3::new(a[3 * pix], a[3 * pix + 1], a[3 * pix + 2]);
                let (pos, n) = (at(gbuffer.position), at(gbuffer.normal).normalize_or_zero());
                if n == Vec3::ZERO {
                    continue;
                }
                let p = Point {
                    x: pos,
                    n,
                    o: pos + n * eps,
                };
                tracer.far = (pos - centre).length() + 2.0 * radius;
                let mut e = Vec3::ZERO;
                for (k, &emitter) in emitters.iter().enumerate() {
                    let mut rng = Rng::new(params.seed, pix as u64 * n_emitters + k as u64);
                    e += irradiance(&mut tracer, emitter, p, params.samples, &mut rng);
                }
                row[3 * x..3 * x + 3].copy_from_slice(&(e / PI).to_array());
            }
            rays.fetch_add(tracer.rays, Ordering::Relaxed);
            if let Some(pr) = progress {
                pr.done.fetch_add(1, Ordering::Relaxed);
            }
            Some(row)
        })
        .collect();
    if cancelled() {
        return Err(VplaceError::Cancelled);
    }
    let image: Vec<f32> = rows.into_iter().flatten().flatten().collect();
    Ok((
        image,
        DirectStats {
            shadow_rays: rays.into_inner(),
            seconds: start.elapsed().as_secs_f64(),
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::emitters::light_power;
    use crate::scene::Material;
    use crate::test_util::{box_with, closed_box, GBufferArrays, BLOCKER};
    use glam::Mat3;
    use std::sync::Arc;

    /// A G-buffer of the given receivers (position, normal), one row.
    fn receivers(points: &[(Vec3, Vec3)]) -> GBufferArrays {
        GBufferArrays {
            width: points.len(),
            height: 1,
            position: points.iter().flat_map(|p| p.0.to_array()).collect(),
            normal: points.iter().flat_map(|p| p.1.to_array()).collect(),
            albedo: [0.5, 0.5, 0.5].repeat(points.len()),
            covered: vec![true; points.len()],
        }
    }

    /// DiffDir (irradiance / pi) at each receiver.
    fn diffdir(scene: &Scene, points: &[(Vec3, Vec3)], samples: usize) -> Vec<Vec3> {
        let g = receivers(points);
        let params = DirectParams { samples, seed: 7 };
        let (img, _) = direct_light(scene, &g.gbuffer(), &params, None).unwrap();
        img.chunks_exact(3).map(Vec3::from_slice).collect()
    }

    /// A 10 m open floor quad (nothing above it) and `lights`.
    fn open_floor(lights: Vec<Light>) -> Scene {
        let v = [
            Vec3::new(-5., -5., 0.),
            Vec3::new(5., -5., 0.),
            Vec3::new(5., 5., 0.),
            Vec3::new(-5., 5., 0.),
        ];
        Scene::build(
            &v,
            &[[0, 1, 2], [0, 2, 3]],
            &[0, 0],
            &[Vec3::splat(0.5)],
            lights,
        )
        .unwrap()
    }

    /// A scene whose only triangle is far away from the receivers (nothing occludes them).
    fn empty_space(lights: Vec<Light>) -> Scene {
        let v = [
            Vec3::new(50., 50., -50.),
            Vec3::new(51., 50., -50.),
            Vec3::new(50., 51., -50.),
        ];
        Scene::build(&v, &[[0, 1, 2]], &[0], &[Vec3::splat(0.5)], lights).unwrap()
    }

    /// `pi` times the form factor from a point to a parallel `a x b` rectangle whose corner is
    /// straight above it at height `h`.
    fn corner_rect(a: f32, b: f32, h: f32) -> f32 {
        let (x, y) = (a / h, b / h);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        0.5 * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan())
    }

    fn close(got: Vec3, want: Vec3, tol: f32) {
        let err = (got - want).abs().max_element() / want.max_element().max(1e-12);
        assert!(err < tol, "got {got}, want {want} ({err:.4})");
    }

    const UP: Vec3 = Vec3::Z;

    #[test]
    fn point_and_spot_lights_match_their_formulas() {
        let p = Vec3::new(0.3, -0.2, 1.5);
        let power = Vec3::new(100.0, 50.0, 20.0);
        let x = Vec3::new(-0.4, 0.1, 0.0);
        let d2 = (p - x).length_squared();
        let cos = (p - x).z / d2.sqrt();
        let point = power / (4.0 * PI * d2) * cos / PI;
        let s = open_floor(vec![Light::point(p, power)]);
        close(diffdir(&s, &[(x, UP)], 1)[0], point, 1e-5);
        // A sphere seen by a receiver facing its centre gives exactly the point's irradiance;
        // a disk facing the receiver gives `P / (4 pi (d^2 + r^2))`.
        let facing = (p - x).normalize();
        let s = open_floor(vec![Light::point(p, power).with_radius(0.4, false)]);
        close(
            diffdir(&s, &[(x, facing)], 256)[0],
            power / (4.0 * PI * d2) / PI,
            2e-3,
        );
        let s = open_floor(vec![Light::point(p, power).with_radius(0.4, true)]);
        let disk = power / (4.0 * PI * (d2 + 0.16)) / PI;
        close(diffdir(&s, &[(x, facing)], 256)[0], disk, 2e-3);
        // A spot: the point inside the cone, nothing outside, the smoothstep across the blend.
        let spot = Light::spot(p, Vec3::NEG_Z, 0.5, power);
        let s = open_floor(vec![spot.clone()]);
        let under = Vec3::new(p.x, p.y, 0.0);
        let far = Vec3::new(p.x + 3.0, p.y, 0.0);
        let got = diffdir(&s, &[(under, UP), (far, UP)], 1);
        close(got[0], power / (4.0 * PI * p.z * p.z) / PI, 1e-5);
        assert_eq!(got[1], Vec3::ZERO);
        let h = 0.5f32;
        let blend = 0.5;
        let edge = h.cos() + blend * (1.0 - h.cos());
        let mid = (0.5 * (h.cos() + edge)).acos();
        let x = Vec3::new(p.x + p.z * mid.tan(), p.y, 0.0);
        let s = open_floor(vec![spot.with_blend(blend)]);
        let d2 = (p - x).length_squared();
        let want = power / (4.0 * PI * d2) * (p.z / d2.sqrt()) * 0.5 / PI;
        close(diffdir(&s, &[(x, UP)], 1)[0], want, 1e-3);
    }

    #[test]
    fn area_lights_match_their_formulas() {
        let power = Vec3::new(40.0, 40.0, 10.0);
        let h = 1.2f32;
        let c = Vec3::new(0.0, 0.0, h);
        // A round disk of radius R on its axis: `E = P / (pi (h^2 + R^2))`.
        let r = 0.5f32;
        let disk = Light::area(c, Vec3::NEG_Z, Vec3::X, true, 2.0 * r, 0.0, power);
        let s = open_floor(vec![disk]);
        let want = power / (PI * (h * h + r * r)) / PI;
        close(diffdir(&s, &[(Vec3::ZERO, UP)], 1024)[0], want, 2e-3);
        // A rectangle, from its form factor at the centre and at a corner.
        let (a, b) = (1.0f32, 0.6f32);
        let rect = Light::area(c, Vec3::NEG_Z, Vec3::X, false, a, b, power);
        let s = open_floor(vec![rect]);
        let l = power / (PI * a * b);
        let centre = l * 4.0 * corner_rect(0.5 * a, 0.5 * b, h) / PI;
        let corner = l * corner_rect(a, b, h) / PI;
        let corner_x = Vec3::new(-0.5 * a, -0.5 * b, 0.0);
        let got = diffdir(&s, &[(Vec3::ZERO, UP), (corner_x, UP)], 1024);
        close(got[0], centre, 3e-3);
        close(got[1], corner, 3e-3);
        // Behind the light: nothing.
        let s = open_floor(vec![Light::area(
            Vec3::new(0., 0., 0.5),
            Vec3::Z,
            Vec3::X,
            false,
            a,
            b,
            power,
        )]);
        assert_eq!(diffdir(&s, &[(Vec3::ZERO, UP)], 16)[0], Vec3::ZERO);
        // A collimated beam (spread 0): `P / A` inside the shape, nothing outside.
        let beam = Light::area(c, Vec3::NEG_Z, Vec3::X, false, a, b, power).with_spread(0.0);
        let s = open_floor(vec![beam]);
        let got = diffdir(
            &s,
            &[(Vec3::new(0.4, 0.2, 0.), UP), (Vec3::new(0.6, 0., 0.), UP)],
            4,
        );
        close(got[0], power / (a * b) / PI, 1e-5);
        assert_eq!(got[1], Vec3::ZERO);
    }

    #[test]
    fn area_spread_matches_a_fine_quadrature() {
        // The irradiance with a spread against a midpoint rule over the shape (400 x 400 cells),
        // both shapes, for receivers under the light and off to the side.
        let power = Vec3::splat(30.0);
        let (a, b, h) = (1.4f32, 0.8f32, 0.9f32);
        for disk in [false, true] {
            for spread in [0.4f32, 1.2, 2.4] {
                let light = Light::area(
                    Vec3::new(0., 0., h),
                    Vec3::NEG_Z,
                    Vec3::X,
                    disk,
                    a,
                    b,
                    power,
                )
                .with_spread(spread);
                let s = open_floor(vec![light]);
                for x in [Vec3::new(0.1, -0.05, 0.0), Vec3::new(0.55, 0.3, 0.0)] {
                    let k = 400;
                    let mut sum = 0.0f64;
                    for i in 0..k {
                        for j in 0..k {
                            let u = ((i as f32 + 0.5) / k as f32 - 0.5) * a;
                            let v = ((j as f32 + 0.5) / k as f32 - 0.5) * b;
                            if disk && (2.0 * u / a).powi(2) + (2.0 * v / b).powi(2) > 1.0 {
                                continue;
                            }
                            let e = Vec3::new(u, v, h) - x;
                            let t2 = e.length_squared();
                            let cos = e.z / t2.sqrt();
                            let g = spread_attenuation(cos, spread);
                            sum += f64::from(g * cos * cos / t2);
                        }
                    }
                    let cell = a * b / (k * k) as f32;
                    let area = area_of(disk, a, b);
                    let want = power / (PI * area) * (sum as f32 * cell) / PI;
                    let got = diffdir(&s, &[(x, UP)], 4096)[0];
                    close(got, want, 0.01);
                }
            }
        }
    }

    #[test]
    fn sun_and_world_match_their_formulas() {
        let s_irr = Vec3::new(3.0, 2.0, 1.0);
        let dir = Vec3::new(0.3, -0.2, -1.0).normalize();
        let tilted = Vec3::new(0.2, 0.1, 1.0).normalize();
        for angle in [0.0f32, 0.05, 0.6] {
            let s = open_floor(vec![Light::sun(dir, s_irr).with_angle(angle)]);
            // The whole cone above the horizon: exactly `S (n . -axis)`.
            let got = diffdir(&s, &[(Vec3::ZERO, UP), (Vec3::ZERO, tilted)], 256);
            close(got[0], s_irr * (-dir.z) / PI, 2e-3);
            close(got[1], s_irr * tilted.dot(-dir) / PI, 2e-3);
        }
        // A uniform world over an open floor: DiffDir is the radiance.
        let radiance = Vec3::new(0.5, 0.7, 1.1);
        let s = open_floor(vec![Light::world(radiance, None)]);
        close(diffdir(&s, &[(Vec3::ZERO, UP)], 64)[0], radiance, 1e-5);
        // An image bright above the horizon (A) and dim below (B): A on the floor, (A + B) / 2
        // on a wall facing +X; turned by 90 degrees about X (the bright half to +Y), (A + B) / 2
        // on the floor and A on a receiver facing +Y.
        let (w, hgt) = (16, 8);
        let (bright, dim) = (Vec3::new(2.0, 1.0, 0.5), Vec3::new(0.2, 0.3, 0.1));
        let px: Vec<f32> = (0..hgt)
            .flat_map(|i| (0..w).map(move |_| if i < hgt / 2 { bright } else { dim }))
            .flat_map(|c| c.to_array())
            .collect();
        let m = EnvironmentMap::new(w, hgt, &px, Mat3::IDENTITY).unwrap();
        let s = empty_space(vec![Light::world(Vec3::ONE, Some(Arc::new(m)))]);
        let lifted = Vec3::new(0.0, 0.0, 0.5);
        let got = diffdir(&s, &[(lifted, UP), (lifted, Vec3::X)], 512);
        close(got[0], bright, 5e-3);
        close(got[1], 0.5 * (bright + dim), 0.01);
        // World +Y looks up the image: the image direction is R w with R taking +Y to +Z.
        let rot = Mat3::from_rotation_x(PI / 2.0);
        assert!((rot * Vec3::Y - Vec3::Z).length() < 1e-6);
        let m = EnvironmentMap::new(w, hgt, &px, rot).unwrap();
        let s = empty_space(vec![Light::world(Vec3::ONE, Some(Arc::new(m)))]);
        let got = diffdir(&s, &[(lifted, UP), (lifted, Vec3::Y)], 512);
        close(got[0], 0.5 * (bright + dim), 0.01);
        close(got[1], bright, 0.01);
    }

    #[test]
    fn emissive_triangles_match_the_form_factor() {
        // A floor with an emissive 1 x 0.6 quad 1.2 above it, facing either way (two-sided).
        let (a, b, h) = (1.0f32, 0.6f32, 1.2f32);
        let radiance = Vec3::new(2.0, 1.0, 0.5);
        for flip in [false, true] {
            let mut v = vec![
                Vec3::new(-5., -5., 0.),
                Vec3::new(5., -5., 0.),
                Vec3::new(5., 5., 0.),
                Vec3::new(-5., 5., 0.),
            ];
            v.extend([
                Vec3::new(-0.5 * a, -0.5 * b, h),
                Vec3::new(0.5 * a, -0.5 * b, h),
                Vec3::new(0.5 * a, 0.5 * b, h),
                Vec3::new(-0.5 * a, 0.5 * b, h),
            ]);
            let quad = if flip {
                [[4, 6, 5], [4, 7, 6]]
            } else {
                [[4, 5, 6], [4, 6, 7]]
            };
            let tris = [[0, 1, 2], [0, 2, 3], quad[0], quad[1]];
            let mats = [
                Material::diffuse(Vec3::splat(0.5)),
                Material::diffuse(Vec3::ZERO).with_emission(radiance),
            ];
            let s = Scene::new(crate::scene::SceneInput {
                vertices: &v,
                triangles: &tris,
                material_ids: &[0, 0, 1, 1],
                materials: &mats,
                lights: vec![],
                ..Default::default()
            })
            .unwrap();
            assert_eq!(s.emissive().len(), 2);
            let corner_x = Vec3::new(-0.5 * a, -0.5 * b, 0.0);
            let got = diffdir(&s, &[(Vec3::ZERO, UP), (corner_x, UP)], 2048);
            close(
                got[0],
                radiance * 4.0 * corner_rect(0.5 * a, 0.5 * b, h) / PI,
                5e-3,
            );
            close(got[1], radiance * corner_rect(a, b, h) / PI, 5e-3);
            let power = s
                .emitters()
                .iter()
                .map(|&e| crate::scene::emitters::emitter_power(e, &s))
                .sum::<Vec3>();
            close(power, radiance * 2.0 * PI * a * b, 1e-5);
        }
    }

    #[test]
    fn closed_box_receives_the_emitted_power() {
        // All the light of an emitter inside a closed box lands on its walls: the irradiance
        // integrated over the walls is the emitter's power, for every kind (the power formulas
        // and the direct estimates agree). Receivers: a stratified grid on each wall. (Not the
        // soft-falloff disk: Blender's ad-hoc disk gives `P / (4 pi (d^2 + r^2))` facing it,
        // which is not power-preserving near the light; its formula is tested above.)
        let lights = [
            Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::new(10., 5., 1.)),
            Light::point(Vec3::new(0.2, -0.1, 1.2), Vec3::splat(10.)).with_radius(0.3, false),
            Light::spot(
                Vec3::new(0.1, 0., 1.6),
                Vec3::new(0.2, 0.1, -1.),
                0.8,
                Vec3::splat(8.),
            )
            .with_blend(0.7),
            Light::area(
                Vec3::new(0., 0., 1.99),
                Vec3::NEG_Z,
                Vec3::X,
                false,
                0.6,
                0.3,
                Vec3::splat(4.),
            ),
            Light::area(
                Vec3::new(0., 0., 1.0),
                Vec3::new(1., 0., -1.).normalize(),
                Vec3::Y,
                true,
                0.5,
                0.3,
                Vec3::splat(4.),
            )
            .with_spread(1.0),
        ];
        let k = 40;
        let mut pts = Vec::new();
        let faces: [(Vec3, Vec3, Vec3, Vec3); 6] = [
            (Vec3::new(0., 0., 0.), Vec3::X, Vec3::Y, Vec3::Z),
            (Vec3::new(0., 0., 2.), Vec3::X, Vec3::Y, Vec3::NEG_Z),
            (Vec3::new(-1., 0., 1.), Vec3::Y, Vec3::Z, Vec3::X),
            (Vec3::new(1., 0., 1.), Vec3::Y, Vec3::Z, Vec3::NEG_X),
            (Vec3::new(0., -1., 1.), Vec3::X, Vec3::Z, Vec3::Y),
            (Vec3::new(0., 1., 1.), Vec3::X, Vec3::Z, Vec3::NEG_Y),
        ];
        for (c, u, v, n) in faces {
            for i in 0..k {
                for j in 0..k {
                    let a = (i as f32 + 0.5) / k as f32 * 2.0 - 1.0;
                    let b = (j as f32 + 0.5) / k as f32 * 2.0 - 1.0;
                    pts.push((c + u * a + v * b, n));
                }
            }
        }
        let cell = 4.0 / (k * k) as f32;
        for light in lights {
            let s = closed_box(vec![light.clone()]);
            let got = diffdir(&s, &pts, 64);
            let flux: Vec3 = got.iter().map(|&e| e * PI * cell).sum();
            close(flux, light_power(&light, &s), 0.02);
        }
    }

    #[test]
    fn shadows_determinism_and_errors() {
        // Under the blocker the point light is hidden; the uniform world is partly.
        let s = box_with(
            vec![Light::point(Vec3::new(0., 0., 1.5), Vec3::splat(10.))],
            &[BLOCKER],
        );
        let got = diffdir(&s, &[(Vec3::ZERO, UP), (Vec3::new(0.8, 0.8, 0.), UP)], 1);
        assert_eq!(got[0], Vec3::ZERO);
        assert!(got[1].x > 0.0);
        let s = box_with(vec![Light::world(Vec3::ONE, None)], &[]);
        assert_eq!(
            diffdir(&s, &[(Vec3::new(0., 0., 1.), UP)], 16)[0],
            Vec3::ZERO,
            "closed"
        );
        // The same seed gives the same image, another seed another; one thread or many.
        let s = box_with(
            vec![Light::point(Vec3::new(0., 0., 1.5), Vec3::splat(10.)).with_radius(0.3, true)],
            &[BLOCKER],
        );
        let g = crate::test_util::floor_gbuffer(24);
        let run = |seed| direct_light(&s, &g.gbuffer(), &DirectParams { samples: 8, seed }, None);
        let (a, stats) = run(1).unwrap();
        assert!(stats.shadow_rays > 0);
        assert_eq!(a, run(1).unwrap().0);
        assert_ne!(a, run(2).unwrap().0);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(a, pool.install(|| run(1)).unwrap().0);
        assert!(matches!(
            direct_light(
                &s,
                &g.gbuffer(),
                &DirectParams {
                    samples: 0,
                    seed: 0
                },
                None
            ),
            Err(VplaceError::OutOfRange { .. })
        ));
        let progress = Progress::default();
        progress.cancel.store(true, Ordering::Relaxed);
        assert!(matches!(
            direct_light(&s, &g.gbuffer(), &DirectParams::PREVIEW, Some(&progress)),
            Err(VplaceError::Cancelled)
        ));
        // No emitters: a black image, no error.
        let s = closed_box(vec![]);
        let (img, _) = direct_light(&s, &g.gbuffer(), &DirectParams::PREVIEW, None).unwrap();
        assert!(img.iter().all(|&v| v == 0.0));
    }
}
