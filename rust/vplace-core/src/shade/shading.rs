//! The shading of one receiver by a set of VPLs: the one place where the VPL-to-pixel term is
//! written.
//!
//! For a receiver `x` (unit normal `n`, albedo `rho`) and VPL `j` (position `y`, unit normal
//! `m`, flux `Phi`, near-field radius `R`):
//!
//! `L_j = rho / pi * Phi * K(x, n, y, m, R) * V(x, y)`,
//!
//! `K` the irradiance per unit flux of the light the write-back creates for the VPL
//! ([`irradiance_per_flux`]), `V` an any-hit shadow ray from the receiver pushed off its surface
//! by the ray epsilon to the VPL's centre.
//!
//! **The near field.** A Blender light has no distance clamp, so the kernel is that of the light
//! itself, and the evaluator, the refit, the layout and EEVEE or Cycles rendering the written
//! lights all see the same light:
//! - cosine profile: a one-sided Lambertian disk of radius `R` facing along `m` (a Blender AREA
//!   disk of diameter `2R`), whose irradiance at `x` is, with `e = y - x`, `r^2 = |e|^2`,
//!   `h = -m . e` (the receiver's height above the disk plane), `T = sqrt((r^2 - R^2)^2 +
//!   4 R^2 h^2)`:
//!   `K = max(0, 2 h (n . e) - (T + R^2 - r^2) (n . m)) / (pi T (T + r^2 + R^2))` for `h > 0`,
//!   else 0. This is the exact disk integral `int cos_e cos_r / d^2 dA / (pi R^2 pi)` (the
//!   closed-form vector irradiance of a disk, `n . V` unclipped; a receiver whose tangent plane
//!   cuts the disk gets the clamped unclipped value). It is bounded by `1 / (pi R^2)` near the
//!   disk and tends to the point-light kernel `cos_e cos_r / (pi r^2)` far away (`R = 0` gives
//!   it exactly);
//! - omni profile: a Blender POINT light of radius 0, `K = 2 / (4 pi) * max(0, cos_r) / r^2`:
//!   the near-field radius does not apply. (A POINT light of radius `R` is no fix: Blender
//!   renders it as a sphere or a disk facing the receiver, half of it below the VPL's own surface
//!   when the VPL sits just above it, which lights the surface around the VPL twice as much as a
//!   facing-disk kernel computed from the centre says: 56 % relative RMSE against Cycles in the
//!   agreement test. The cosine profile, the default, has no such problem.)
//!
//! A pair whose kernel is zero (the receiver behind a cosine VPL's plane, or facing away from an
//! omni VPL, or at `r = 0`) gives nothing and needs no ray.
//!
//! The callers:
//! - the evaluator ([`crate::shade::evaluator`]) sums the pairs of each pixel, with shadow rays;
//! - the refit (`layout::refit`) keeps them per VPL as the columns of its matrix, with shadow
//!   rays;
//! - the layout's view efficiency (`layout::view_efficiency`) averages the unshadowed
//!   term of the cosine profile over a few pixels of the view.
//!
//! **How.** `Batch` computes one receiver against every VPL of a `VplSoa` (the VPLs in
//! structure-of-arrays form) in a loop the compiler vectorizes: the unshadowed kernel of every
//! pair and, for the callers that trace, its shadow ray (unit direction, its safe inverse and
//! length, as `Scene::occluded` and obvhs's `Ray::new` make them).

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;
use std::f32::consts::PI;

use crate::view::GBuffer;
use crate::vpl::{Profile, Vpl};

/// The irradiance per unit flux `K` that a VPL's light gives a receiver (see the module docs):
/// `e2` is `r^2 = |y - x|^2`, `ne` is `n . e`, `h` is `-m . e` (cosine only), `nm` is `n . m`
/// (cosine only), `radius_sq` is `R^2` (cosine only). `>= 0`; 0 where the pair gives nothing.
///
/// The one function that says how a VPL lights a point, for the evaluator, the refit and the
/// view efficiency alike, and the light the write-back creates.
#[inline(always)]
#[must_use]
pub fn irradiance_per_flux(
    profile: Profile,
    e2: f32,
    ne: f32,
    h: f32,
    nm: f32,
    radius_sq: f32,
) -> f32 {
    if e2 <= 0.0 {
        return 0.0;
    }
    match profile {
        Profile::Cosine => {
            if h <= 0.0 {
                return 0.0;
            }
            let d = e2 - radius_sq;
            let t = (d * d + 4.0 * radius_sq * h * h).sqrt();
            // `T + R^2 - r^2 = T - d`, written without cancellation where `d > 0`.
            let c = if d > 0.0 {
                4.0 * radius_sq * h * h / (t + d)
            } else {
                t - d
            };
            let k = (2.0 * h * ne - c * nm) / (PI * t * (t + e2 + radius_sq));
            if k > 0.0 {
                k
            } else {
                0.0
            }
        }
        Profile::Omni => {
            if ne <= 0.0 {
                return 0.0;
            }
            Profile::Omni.intensity_per_flux(0.0) * ne / (e2.sqrt() * e2)
        }
    }
}

/// A covered pixel ready to receive VPL light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Receiver {
    /// World position.
    pub position: Vec3,
    /// Unit shading normal (zero where the G-buffer normal is zero).
    pub normal: Vec3,
    /// Diffuse BRDF `albedo / pi`.
    pub brdf: Vec3,
    /// Start of the shadow rays: the position pushed off the surface along the normal.
    pub origin: Vec3,
}

impl Receiver {
    /// Pixel `p` of `gbuffer` as a receiver of VPL light; `eps` is
    /// [`crate::scene::Scene::ray_epsilon`].
    #[inline]
    #[must_use]
    pub(crate) fn of_pixel(gbuffer: &GBuffer<'_>, p: usize, eps: f32) -> Self {
        Self::new(
            GBuffer::vec3(gbuffer.position, p),
            GBuffer::vec3(gbuffer.normal, p),
            GBuffer::vec3(gbuffer.albedo, p),
            eps,
        )
    }

    /// The receiver at `position` with the G-buffer's `normal` (normalized here; a box-filtered
    /// normal is shorter than 1, a zero normal stays zero) and `albedo`; `eps` is
    /// [`crate::scene::Scene::ray_epsilon`].
    #[inline]
    #[must_use]
    pub(crate) fn new(position: Vec3, normal: Vec3, albedo: Vec3, eps: f32) -> Self {
        let normal = normal.normalize_or_zero();
        Self {
            position,
            normal,
            brdf: albedo / PI,
            origin: position + normal * eps,
        }
    }
}

/// VPLs in structure-of-arrays form, the input of [`Batch`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct VplSoa {
    px: Vec<f32>,
    py: Vec<f32>,
    pz: Vec<f32>,
    mx: Vec<f32>,
    my: Vec<f32>,
    mz: Vec<f32>,
    /// Squared near-field radius of each VPL (`crate::vpl::near_field_radii`).
    r2: Vec<f32>,
    /// Flux of each VPL.
    pub flux: Vec<Vec3>,
}

impl VplSoa {
    /// The columns of `vpls`, VPL `j` of near-field radius `radii[j]` (`radii` as long as
    /// `vpls`).
    #[must_use]
    pub(crate) fn new(vpls: &[Vpl], radii: &[f32]) -> Self {
        debug_assert_eq!(vpls.len(), radii.len());
        let col = |f: fn(&Vpl) -> f32| vpls.iter().map(f).collect::<Vec<f32>>();
        Self {
            r2: radii.iter().map(|r| r * r).collect(),
            px: col(|v| v.position.x),
            py: col(|v| v.position.y),
            pz: col(|v| v.position.z),
            mx: col(|v| v.normal.x),
            my: col(|v| v.normal.y),
            mz: col(|v| v.normal.z),
            flux: vpls.iter().map(|v| v.flux).collect(),
        }
    }

    /// Number of VPLs.
    #[must_use]
    pub(crate) fn len(&self) -> usize {
        self.flux.len()
    }
}

/// `obvhs::ray::safe_inverse`, as `Ray::new` computes it.
#[inline(always)]
fn safe_inverse(x: f32) -> f32 {
    if x.abs() <= f32::EPSILON {
        x.signum() / f32::EPSILON
    } else {
        1.0 / x
    }
}

/// One receiver against every VPL of a [`VplSoa`] (see the module docs): per VPL `j`, the
/// unshadowed scale `I(cos_e) * cos_r * F(r)` (0 when the pair gives nothing) and, after
/// [`Batch::prepare`], its shadow ray. Buffers reused from receiver to receiver.
pub(crate) struct Batch {
    /// VPLs of the last prepare.
    count: usize,
    scale: Vec<f32>,
    /// Origin of the shadow rays of the last [`Batch::prepare`].
    origin: Vec3,
    len: Vec<f32>,
    dx: Vec<f32>,
    dy: Vec<f32>,
    dz: Vec<f32>,
    ix: Vec<f32>,
    iy: Vec<f32>,
    iz: Vec<f32>,
}

impl Batch {
    /// Buffers for `n` VPLs.
    #[must_use]
    pub(crate) fn new(n: usize) -> Self {
        let z = || vec![0.0f32; n];
        Self {
            count: 0,
            scale: z(),
            origin: Vec3::ZERO,
            len: z(),
            dx: z(),
            dy: z(),
            dz: z(),
            ix: z(),
            iy: z(),
            iz: z(),
        }
    }

    /// Shades `recv` by every VPL of `v` (at most as many as [`Batch::new`] was given) and
    /// builds the shadow rays from `recv.origin`.
    pub(crate) fn prepare(&mut self, v: &VplSoa, recv: &Receiver, profile: Profile) {
        self.origin = recv.origin;
        let (pos, n, origin) = (recv.position, recv.normal, recv.origin);
        match profile {
            Profile::Cosine => self.prepare_with::<true, true>(v, pos, n, origin),
            Profile::Omni => self.prepare_with::<false, true>(v, pos, n, origin),
        }
    }

    /// The unshadowed scales only (no shadow rays) of a receiver at `position` with unit (or
    /// zero) `normal`; [`Batch::scales`] reads them.
    pub(crate) fn prepare_unshadowed(
        &mut self,
        v: &VplSoa,
        position: Vec3,
        normal: Vec3,
        profile: Profile,
    ) {
        let p = position;
        match profile {
            Profile::Cosine => self.prepare_with::<true, false>(v, p, normal, p),
            Profile::Omni => self.prepare_with::<false, false>(v, p, normal, p),
        }
    }

    #[inline(always)]
    fn prepare_with<const COSINE: bool, const RAYS: bool>(
        &mut self,
        v: &VplSoa,
        pos: Vec3,
        n: Vec3,
        origin: Vec3,
    ) {
        let m = v.len();
        let r2 = &v.r2[..m];
        self.count = m;
        let (px, py, pz) = (&v.px[..m], &v.py[..m], &v.pz[..m]);
        let (mx, my, mz) = (&v.mx[..m], &v.my[..m], &v.mz[..m]);
        let scale = &mut self.scale[..m];
        let len = &mut self.len[..m];
        let (dx, dy, dz) = (&mut self.dx[..m], &mut self.dy[..m], &mut self.dz[..m]);
        let (ix, iy, iz) = (&mut self.ix[..m], &mut self.iy[..m], &mut self.iz[..m]);
        for j in 0..m {
            let (ex, ey, ez) = (px[j] - pos.x, py[j] - pos.y, pz[j] - pos.z);
            let e2 = (ex * ex) + (ey * ey) + (ez * ez);
            let ne = (n.x * ex) + (n.y * ey) + (n.z * ez);
            scale[j] = if COSINE {
                let h = -((mx[j] * ex) + (my[j] * ey) + (mz[j] * ez));
                let nm = (n.x * mx[j]) + (n.y * my[j]) + (n.z * mz[j]);
                irradiance_per_flux(Profile::Cosine, e2, ne, h, nm, r2[j])
            } else {
                irradiance_per_flux(Profile::Omni, e2, ne, 0.0, 0.0, 0.0)
            };
            if RAYS {
                // The shadow ray from `origin`, as `Scene::occluded` and `Ray::new` make it.
                let (ox, oy, oz) = (px[j] - origin.x, py[j] - origin.y, pz[j] - origin.z);
                let l = ((ox * ox) + (oy * oy) + (oz * oz)).sqrt();
                let (ux, uy, uz) = (ox / l, oy / l, oz / l);
                len[j] = l;
                (dx[j], dy[j], dz[j]) = (ux, uy, uz);
                (ix[j], iy[j], iz[j]) = (safe_inverse(ux), safe_inverse(uy), safe_inverse(uz));
            }
        }
    }

    /// The unshadowed kernels `K` ([`irradiance_per_flux`]) of the last prepare, one per VPL
    /// (`>= 0`, 0 where the pair gives nothing).
    #[inline]
    #[must_use]
    pub(crate) fn scales(&self) -> &[f32] {
        &self.scale[..self.count]
    }

    /// The pairs of the last prepare that give light before shadowing: `(j, Phi_j * scale_j)`
    /// for every VPL `j` of `v` whose product is not zero, in order. Exactly these need a
    /// shadow ray.
    #[inline]
    pub(crate) fn unshadowed<'a>(
        &'a self,
        v: &'a VplSoa,
    ) -> impl Iterator<Item = (usize, Vec3)> + 'a {
        self.scales()
            .iter()
            .zip(&v.flux)
            .enumerate()
            .filter_map(|(j, (&s, &flux))| {
                if s == 0.0 {
                    return None;
                }
                let c = flux * s;
                (c != Vec3::ZERO).then_some((j, c))
            })
    }

    /// The shadow ray of pair `j` of the last [`Batch::prepare`] (unit direction, `tmin` 0,
    /// `tmax` the distance to the VPL); `None` for a zero-length ray, which nothing blocks.
    #[inline(always)]
    #[must_use]
    pub(crate) fn shadow_ray(&self, j: usize) -> Option<Ray> {
        let len = self.len[j];
        if len <= 0.0 {
            return None;
        }
        Some(Ray {
            origin: Vec3A::from(self.origin),
            direction: Vec3A::new(self.dx[j], self.dy[j], self.dz[j]),
            inv_direction: Vec3A::new(self.ix[j], self.iy[j], self.iz[j]),
            tmin: 0.0,
            tmax: len,
        })
    }

    /// Whether the shadow ray of pair `j` is blocked, by `occluded`; a zero-length ray is not.
    #[inline(always)]
    pub(crate) fn occluded(&self, j: usize, occluded: impl FnOnce(&Ray) -> bool) -> bool {
        self.shadow_ray(j).is_some_and(|ray| occluded(&ray))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use crate::test_util::{reference_incident, shading_cases};

    /// The exact irradiance of a Lambertian disk by numerical integration (a fine polar grid):
    /// the reference of [`irradiance_per_flux`]'s cosine profile.
    fn disk_integral(x: Vec3, n: Vec3, c: Vec3, m: Vec3, radius: f32) -> f64 {
        let (t, b) = (
            m.any_orthonormal_vector(),
            m.cross(m.any_orthonormal_vector()),
        );
        let (rings, sectors) = (400, 400);
        let mut sum = 0.0f64;
        for i in 0..rings {
            let r0 = f64::from(radius) * (i as f64 / rings as f64);
            let r1 = f64::from(radius) * ((i + 1) as f64 / rings as f64);
            let rr = 0.5 * (r0 + r1);
            let area = std::f64::consts::PI * (r1 * r1 - r0 * r0) / sectors as f64;
            for k in 0..sectors {
                let a = std::f64::consts::TAU * (k as f64 + 0.5) / sectors as f64;
                let y = c + (t * a.cos() as f32 + b * a.sin() as f32) * rr as f32;
                let e = (y - x).as_dvec3();
                let d2 = e.length_squared();
                let l = e / d2.sqrt();
                let ce = (-m.as_dvec3().dot(l)).max(0.0);
                let cr = n.as_dvec3().dot(l).max(0.0);
                sum += ce * cr / d2 * area;
            }
        }
        // Radiance of unit flux over the disk: 1 / (pi * pi R^2).
        let r = f64::from(radius);
        sum / (std::f64::consts::PI * std::f64::consts::PI * r * r)
    }

    fn kernel(profile: Profile, x: Vec3, n: Vec3, y: Vec3, m: Vec3, radius: f32) -> f32 {
        let e = y - x;
        irradiance_per_flux(
            profile,
            e.length_squared(),
            n.dot(e),
            -m.dot(e),
            n.dot(m),
            radius * radius,
        )
    }

    /// The cosine kernel is the disk light's exact irradiance (wherever the receiver's tangent
    /// plane does not cut the disk), bounded by `1 / (pi R^2)`; with `R = 0` it is the point
    /// light's `cos_e cos_r / (pi r^2)`; the omni kernel is the point light's `cos_r / (2 pi
    /// r^2)` whatever the radius.
    #[test]
    fn kernel_is_the_disk_light() {
        let mut rng = Rng::new(3, 0);
        let mut u = || 2.0 * rng.next_f32() - 1.0;
        let (c, m, radius) = (Vec3::ZERO, Vec3::Z, 0.1f32);
        let mut checked = 0;
        for _ in 0..400 {
            let x = Vec3::new(0.3 * u(), 0.3 * u(), 0.01 + 0.3 * u().abs());
            let n = Vec3::new(u(), u(), u()).normalize();
            // Skip receivers whose tangent plane cuts the disk (the unclipped form's limit).
            let rim = (0..64).map(|k| {
                let a = std::f32::consts::TAU * k as f32 / 64.0;
                c + Vec3::new(a.cos(), a.sin(), 0.0) * radius
            });
            if rim.into_iter().any(|p| n.dot(p - x) <= 0.0) {
                continue;
            }
            let want = disk_integral(x, n, c, m, radius);
            let got = f64::from(kernel(Profile::Cosine, x, n, c, m, radius));
            assert!((got / want - 1.0).abs() < 2e-3, "{x} {n}: {got} {want}");
            checked += 1;
        }
        assert!(checked > 50, "{checked}");
        // On the axis, facing the disk: 1 / (pi (h^2 + R^2)).
        for h in [0.01f32, 0.1, 1.0] {
            let k = kernel(Profile::Cosine, Vec3::Z * h, -Vec3::Z, c, m, radius);
            let want = 1.0 / (PI * (h * h + radius * radius));
            assert!((k / want - 1.0).abs() < 1e-5, "{h}: {k} {want}");
            assert!(k <= 1.0 / (PI * radius * radius) * (1.0 + 1e-6));
        }
        // Radius 0: the point light, as before the near field existed.
        let x = Vec3::new(0.3, -0.2, 0.7);
        let n = Vec3::new(0.1, 0.2, -1.0).normalize();
        let e = c - x;
        let (r2, l) = (e.length_squared(), e.normalize());
        let (cos_e, cos_r) = (-m.dot(l), n.dot(l));
        let point = cos_e * cos_r / (PI * r2);
        assert!((kernel(Profile::Cosine, x, n, c, m, 0.0) / point - 1.0).abs() < 1e-5);
        let omni = kernel(Profile::Omni, x, n, c, m, 0.2);
        assert!((omni / (cos_r / (2.0 * PI * r2)) - 1.0).abs() < 1e-5);
        // Nothing behind the disk's plane, at the centre, or behind an omni receiver.
        assert_eq!(
            kernel(Profile::Cosine, -Vec3::Z * 0.1, Vec3::Z, c, m, radius),
            0.0
        );
        assert_eq!(kernel(Profile::Cosine, c, Vec3::Z, c, m, radius), 0.0);
        assert_eq!(kernel(Profile::Omni, Vec3::Z, Vec3::Z, c, m, radius), 0.0);
    }

    /// The batch's scales are the scalar reference's (unshadowed, unit flux) and its shadow
    /// rays are the rays `Scene::occluded` builds (`Ray::new` from the receiver's origin), bit
    /// for bit, for random receivers and the VPLs of [`shading_cases`].
    #[test]
    fn batch_matches_the_scalar_formula_and_scene_rays() {
        let (scene, _, vpls) = shading_cases();
        let unit: Vec<Vpl> = vpls
            .iter()
            .map(|v| Vpl {
                flux: Vec3::ONE,
                ..*v
            })
            .collect();
        let mut batch = Batch::new(unit.len());
        let mut rng = Rng::new(5, 0);
        let mut r = || 2.0 * rng.next_f32() - 1.0;
        let eps = scene.ray_epsilon();
        for k in 0..200 {
            let position = Vec3::new(r(), r(), 1.0 + r());
            let normal = match k % 4 {
                0 => Vec3::ZERO,
                1 => Vec3::Z,
                _ => Vec3::new(r(), r(), r()),
            };
            let recv = Receiver::new(position, normal, Vec3::splat(0.5), eps);
            for profile in [Profile::Cosine, Profile::Omni] {
                for radius in [0.0, 0.1] {
                    let soa = VplSoa::new(&unit, &vec![radius; unit.len()]);
                    batch.prepare(&soa, &recv, profile);
                    let scales = batch.scales().to_vec();
                    let unshadowed: Vec<usize> = batch.unshadowed(&soa).map(|(j, _)| j).collect();
                    let mut expect = Vec::new();
                    for (j, v) in unit.iter().enumerate() {
                        let want =
                            reference_incident(None, position, recv.normal, v, profile, radius);
                        assert_eq!(scales[j], want.map_or(0.0, |c| c.x), "{k} {j}");
                        if want.is_some() {
                            expect.push(j);
                        }
                        let d = v.position - recv.origin;
                        let len = d.length();
                        let ray =
                            Ray::new(Vec3A::from(recv.origin), Vec3A::from(d / len), 0.0, len);
                        let got = batch.shadow_ray(j).unwrap();
                        assert_eq!(
                            (
                                got.origin,
                                got.direction,
                                got.inv_direction,
                                got.tmin,
                                got.tmax
                            ),
                            (
                                ray.origin,
                                ray.direction,
                                ray.inv_direction,
                                ray.tmin,
                                ray.tmax
                            )
                        );
                    }
                    assert_eq!(unshadowed, expect);
                    batch.prepare_unshadowed(&soa, position, recv.normal, profile);
                    assert_eq!(batch.scales(), &scales[..]);
                }
            }
        }
    }
}
