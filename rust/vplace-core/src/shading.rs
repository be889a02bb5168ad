//! The shading of one receiver by a set of VPLs: the one place where the VPL-to-pixel term is
//! written.
//!
//! For a receiver `x` (unit normal `n`, albedo `rho`) and VPL `j` (position `y`, unit normal
//! `m`, flux `Phi`), with `r = |y - x|`, `l = (y - x) / r`:
//!
//! `L_j = rho / pi * Phi * I(cos_e) * max(0, n . l) * F(r) * V(x, y)`,
//!
//! `cos_e = -m . l`, `I` the profile's intensity per unit flux
//! ([`Profile::intensity_per_flux`]), `F` the near-field term ([`near_field`]: today
//! `1 / max(r^2, r_min^2)`), `V` an any-hit shadow ray from the receiver pushed off its surface
//! by the ray epsilon to the VPL. A pair behind the receiver (`n . l <= 0`), behind a cosine VPL
//! (`cos_e <= 0`), at `r = 0`, or whose unshadowed term is zero gives nothing and needs no ray.
//!
//! The callers:
//! - the evaluator ([`crate::evaluator`]) sums the pairs of each pixel, with shadow rays;
//! - the refit ([`crate::refit`]) keeps them per VPL as the columns of its matrix, with shadow
//!   rays;
//! - the layout's view efficiency ([`crate::layout::view_efficiency`]) averages the unshadowed
//!   term of the cosine profile over a few pixels of the view.
//!
//! **How.** `Batch` computes one receiver against every VPL of a `VplSoa` (the VPLs in
//! structure-of-arrays form) in a loop the compiler vectorizes: the unshadowed scale of every
//! pair and, for the callers that trace, its shadow ray (unit direction, its safe inverse and
//! length, as `Scene::occluded` and obvhs's `Ray::new` make them). The operations are those of
//! the scalar formula in the same order, so every value is bit for bit what the scalar code
//! computed (the evaluator's image did not change when it moved to the batch).

use glam::{Vec3, Vec3A};
use obvhs::ray::Ray;
use std::f32::consts::PI;

use crate::vpl::{Profile, Vpl};

/// The default near-field radius `r_min` as a fraction of the scene diagonal
/// ([`crate::scene::Scene::near_field_radius`]): VPL spacing grows with the scene, so the radius
/// within which a VPL's `1 / r^2` is bounded does too.
pub const NEAR_FIELD_FRACTION: f32 = 0.01;

/// The near-field term: the distance falloff `F(r)` of a VPL applied to `cosines`
/// (`I(cos_e) * cos_r`), that is `cosines * F(r)` with `F(r) = 1 / max(r^2, r_min^2)` (a point
/// light whose `1 / r^2` is clamped within the near-field radius `r_min`). `r2` is `r^2`,
/// `r_min_sq` is `r_min^2`; `r_min = 0` gives the unclamped inverse square.
///
/// The one function that says how a VPL's light falls off with distance, for the evaluator, the
/// refit and the view efficiency alike. Written as a division (not a product with `1 / max`) so
/// that the values are bit for bit those of the formula `i * cos_r / max(r^2, r_min^2)`.
#[inline(always)]
#[must_use]
pub fn near_field(cosines: f32, r2: f32, r_min_sq: f32) -> f32 {
    cosines / r2.max(r_min_sq)
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
    /// Flux of each VPL.
    pub flux: Vec<Vec3>,
}

impl VplSoa {
    /// The columns of `vpls`.
    #[must_use]
    pub(crate) fn new(vpls: &[Vpl]) -> Self {
        let col = |f: fn(&Vpl) -> f32| vpls.iter().map(f).collect::<Vec<f32>>();
        Self {
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
    pub(crate) fn prepare(&mut self, v: &VplSoa, recv: &Receiver, profile: Profile, r_min_sq: f32) {
        self.origin = recv.origin;
        let (pos, n, origin) = (recv.position, recv.normal, recv.origin);
        match profile {
            Profile::Cosine => self.prepare_with::<true, true>(v, pos, n, origin, r_min_sq),
            Profile::Omni => self.prepare_with::<false, true>(v, pos, n, origin, r_min_sq),
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
        r_min_sq: f32,
    ) {
        let p = position;
        match profile {
            Profile::Cosine => self.prepare_with::<true, false>(v, p, normal, p, r_min_sq),
            Profile::Omni => self.prepare_with::<false, false>(v, p, normal, p, r_min_sq),
        }
    }

    #[inline(always)]
    fn prepare_with<const COSINE: bool, const RAYS: bool>(
        &mut self,
        v: &VplSoa,
        pos: Vec3,
        n: Vec3,
        origin: Vec3,
        r_min_sq: f32,
    ) {
        let m = v.len();
        self.count = m;
        let (px, py, pz) = (&v.px[..m], &v.py[..m], &v.pz[..m]);
        let (mx, my, mz) = (&v.mx[..m], &v.my[..m], &v.mz[..m]);
        let scale = &mut self.scale[..m];
        let len = &mut self.len[..m];
        let (dx, dy, dz) = (&mut self.dx[..m], &mut self.dy[..m], &mut self.dz[..m]);
        let (ix, iy, iz) = (&mut self.ix[..m], &mut self.iy[..m], &mut self.iz[..m]);
        for j in 0..m {
            // The shading term, as the scalar formula computes it.
            let (ex, ey, ez) = (px[j] - pos.x, py[j] - pos.y, pz[j] - pos.z);
            let r2 = (ex * ex) + (ey * ey) + (ez * ez);
            let r = r2.sqrt();
            let (lx, ly, lz) = (ex / r, ey / r, ez / r);
            let cos_r = (n.x * lx) + (n.y * ly) + (n.z * lz);
            let i = if COSINE {
                let cos_e = -((mx[j] * lx) + (my[j] * ly) + (mz[j] * lz));
                Profile::Cosine.intensity_per_flux(cos_e)
            } else {
                Profile::Omni.intensity_per_flux(0.0)
            };
            let s = near_field(i * cos_r, r2, r_min_sq);
            scale[j] = if r2 > 0.0 && cos_r > 0.0 && i > 0.0 {
                s
            } else {
                0.0
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

    /// The unshadowed scales `I(cos_e) * cos_r * F(r)` of the last prepare, one per VPL
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

    /// The formula of the near-field term itself: the reference tests of the callers share
    /// this function with them, so it is checked here on its own.
    #[test]
    fn near_field_is_the_clamped_inverse_square() {
        assert_eq!(near_field(2.0, 4.0, 0.0), 0.5);
        assert_eq!(near_field(2.0, 4.0, 1.0), 0.5); // beyond the radius: 1 / r^2
        assert_eq!(near_field(1.0, 0.01, 0.25), 4.0); // within: 1 / r_min^2
        assert_eq!(near_field(3.0, 0.25, 0.25), 12.0);
        assert_eq!(near_field(0.0, 0.0, 0.01), 0.0);
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
        let soa = VplSoa::new(&unit);
        let mut batch = Batch::new(soa.len());
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
                for r_min in [0.0, 0.1] {
                    let r_min_sq = r_min * r_min;
                    batch.prepare(&soa, &recv, profile, r_min_sq);
                    let scales = batch.scales().to_vec();
                    let unshadowed: Vec<usize> = batch.unshadowed(&soa).map(|(j, _)| j).collect();
                    let mut expect = Vec::new();
                    for (j, v) in unit.iter().enumerate() {
                        let want =
                            reference_incident(None, position, recv.normal, v, profile, r_min);
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
                    batch.prepare_unshadowed(&soa, position, recv.normal, profile, r_min_sq);
                    assert_eq!(batch.scales(), &scales[..]);
                }
            }
        }
    }
}
