//! Virtual point lights and the uniform (instant radiosity) layout of Keller 1997.
//!
//! A VPL stands for light reflected by a diffuse surface (after one or more bounces). It carries the flux `Phi` (RGB
//! watts) that its patch reflects. How it radiates is its [`Profile`].

use glam::Vec3;
use std::f32::consts::PI;

mod light_paths;
pub(crate) use light_paths::light_powers;
pub use light_paths::{
    emitted_power, light_path_hits, light_path_vpls, uniform_vpls, LightHit, MAX_BOUNCES,
    MAX_RAYS_PER_VPL,
};

/// How a VPL radiates its flux `Phi`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// Lambertian: intensity `Phi / pi * max(0, cos)` about the surface normal. Exactly a Blender
    /// AREA light of power `Phi` facing along the normal. The physically right choice.
    #[default]
    Cosine,
    /// Uniform over the sphere with power `2 Phi` (a Blender POINT light), so the hemisphere in
    /// front of the surface receives `Phi`, like the cosine profile; half is lost into the surface.
    Omni,
}

impl Profile {
    /// Radiant intensity (W/sr per unit flux) toward a direction making cosine `cos_e` with the
    /// VPL normal.
    #[inline]
    #[must_use]
    pub fn intensity_per_flux(self, cos_e: f32) -> f32 {
        match self {
            Profile::Cosine => cos_e.max(0.0) / PI,
            Profile::Omni => 2.0 / (4.0 * PI),
        }
    }

    /// The power a Blender light needs to reproduce this profile for a VPL of flux `flux`.
    #[must_use]
    pub fn blender_power(self, flux: Vec3) -> Vec3 {
        match self {
            Profile::Cosine => flux,
            Profile::Omni => 2.0 * flux,
        }
    }
}

/// Neighbours counted by [`near_field_radii`]: the area a VPL stands for is that of the disk
/// reaching its `k`-th nearest VPL, shared by the `k` VPLs inside it (a k-nearest-neighbour
/// density estimate, as in photon mapping).
pub const SPACING_NEIGHBOURS: usize = 8;

/// The patches a VPL's disk covers ([`near_field_radii`]): its area is that of this many
/// patches, so the disks of neighbouring VPLs overlap.
///
/// Why not one patch: disks of one patch each, at the random places a layout draws, leave a
/// good part of a surface under no disk and put a spot where one stands alone near a corner or
/// the next wall (on a Poisson set, disks of `m` patches each cover `1 - e^-m` of the surface:
/// 63 % at one patch, 86 % at two). A VPL stands for the light of its neighbourhood, so the
/// wall beside it shows the blend of its neighbours instead of the nearest one. Swept over 1,
/// 1.6, 2, 2.3, 3.1 and 4 patches (ARCHITECTURE, "Near field"): the evaluator's SSIM rose from
/// one patch to two on nearly every view of the built-in rooms, a flat and a house, three
/// patches gained a little more on most, and four lost in the sky room, whose sun patches are
/// sharp. Two, because EEVEE follows the evaluator less where a large disk reaches under an
/// object (`tests/render/test_eevee.py`: relative RMSE .0968 at one patch, .0908 at two,
/// .1048 at three).
pub const DISK_PATCHES: f32 = 2.0;

/// The largest near-field radius [`near_field_radii`] gives, in multiples of the set's radius.
pub const MAX_RADIUS_FACTOR: f32 = 10.0;

/// The near-field radius of each VPL of a set whose radius is `radius` (see
/// `shade::shading`): the radius of a disk of [`DISK_PATCHES`] surface patches of the size the
/// VPL stands for, `R_j = d_k sqrt(DISK_PATCHES / k)` with `d_k` the distance from VPL `j` to
/// its `k`-th nearest VPL ([`SPACING_NEIGHBOURS`]), clamped to `[radius, MAX_RADIUS_FACTOR *
/// radius]`.
///
/// Why: a VPL carries the light its patch reflects. Drawn as a disk of its neighbourhood, a VPL
/// that stands for a large, sparsely sampled area (where a layout places few, strong VPLs)
/// spreads its flux over that area near its surface instead of a bright spot, and a VPL among
/// many stays small and sharp. Far from the VPL the disk is a point light, so the far field and
/// the total flux are unchanged. The radii depend on the positions only (not on the flux), so a
/// refit that rescales the powers keeps them, and the evaluator, the refit and the write-back
/// compute the same radii from the same set. `radius = 0` gives points (all radii 0); a set of
/// fewer than two VPLs keeps `radius`.
///
/// Brute force, `O(n^2)` distance tests (rayon over VPLs): 0.05 s for 8,192 VPLs.
#[must_use]
pub fn near_field_radii(vpls: &[Vpl], radius: f32) -> Vec<f32> {
    use rayon::prelude::*;
    let n = vpls.len();
    if n < 2 || radius <= 0.0 {
        return vec![radius.max(0.0); n];
    }
    let k = SPACING_NEIGHBOURS.min(n - 1);
    let scale = (DISK_PATCHES / k as f32).sqrt();
    let cap = MAX_RADIUS_FACTOR * radius;
    vpls.par_iter()
        .enumerate()
        .map(|(i, v)| {
            // The k smallest squared distances to the other VPLs, ascending.
            let mut best = [f32::INFINITY; SPACING_NEIGHBOURS];
            for (j, u) in vpls.iter().enumerate() {
                let d2 = (u.position - v.position).length_squared();
                if j == i || d2 >= best[k - 1] {
                    continue;
                }
                let mut at = k - 1;
                while at > 0 && best[at - 1] > d2 {
                    best[at] = best[at - 1];
                    at -= 1;
                }
                best[at] = d2;
            }
            (best[k - 1].sqrt() * scale).clamp(radius, cap)
        })
        .collect()
}

/// A virtual point light.
///
/// Invariants: `normal` is unit length; `position` lies a small offset
/// ([`Vpl::SURFACE_OFFSET`] times the scene diagonal) off its surface along `normal`, so shadow
/// rays and Blender lights placed there never start inside the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vpl {
    /// World position, already offset off the surface.
    pub position: Vec3,
    /// Unit surface normal, facing the side the light arrived from.
    pub normal: Vec3,
    /// Reflected flux, RGB watts.
    pub flux: Vec3,
}

impl Vpl {
    /// Offset of a VPL off its surface, as a fraction of the scene's working scale
    /// ([`crate::scene::Scene::scale`]).
    pub const SURFACE_OFFSET: f32 = 1e-3;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(p: Vec3) -> Vpl {
        Vpl {
            position: p,
            normal: Vec3::Z,
            flux: Vec3::ONE,
        }
    }

    /// On a square grid of spacing `a`, an inner VPL's eighth neighbour is a diagonal one
    /// (`a sqrt 2`), so its patch radius is `a sqrt 2 / sqrt 8 = a / 2` and its disk, of
    /// `DISK_PATCHES` (2) patches, `a / sqrt 2`; the set's radius bounds it below and
    /// `MAX_RADIUS_FACTOR` times it above; an isolated VPL gets the cap; radius 0 and sets of
    /// one keep the radius.
    #[test]
    fn near_field_radii_follow_the_spacing() {
        let a = 0.1f32;
        let mut vpls: Vec<Vpl> = (0..100)
            .map(|i| at(Vec3::new(a * (i % 10) as f32, a * (i / 10) as f32, 0.0)))
            .collect();
        let inner = 5 * 10 + 5;
        let r = near_field_radii(&vpls, 0.01);
        let want = a / 2.0 * DISK_PATCHES.sqrt();
        assert!((r[inner] - want).abs() < 1e-6, "{} {want}", r[inner]);
        assert!(r.iter().all(|&x| (0.01..=0.1).contains(&x)));
        assert_eq!(near_field_radii(&vpls, 0.09)[inner], 0.09);
        assert_eq!(
            near_field_radii(&vpls, 0.001)[inner],
            MAX_RADIUS_FACTOR * 0.001
        );
        vpls.push(at(Vec3::new(50.0, 0.0, 0.0)));
        assert_eq!(
            *near_field_radii(&vpls, 0.01).last().unwrap(),
            MAX_RADIUS_FACTOR * 0.01
        );
        assert!(near_field_radii(&vpls, 0.0).iter().all(|&x| x == 0.0));
        assert_eq!(near_field_radii(&vpls[..1], 0.02), vec![0.02]);
        assert!(near_field_radii(&[], 0.02).is_empty());
        // Three VPLs: the farthest other one is the k-th neighbour (k = 2).
        let three = [Vec3::ZERO, Vec3::X * 0.3, Vec3::X * 0.5].map(at);
        let r = near_field_radii(&three, 0.1);
        let want = 0.5 * (DISK_PATCHES / 2.0).sqrt();
        assert!((r[0] - want).abs() < 1e-6, "{r:?}");
    }
}
