//! Virtual point lights and the uniform (instant radiosity) layout of Keller 1997.
//!
//! A VPL stands for light reflected by a diffuse surface (after one or more bounces). It carries the flux `Phi` (RGB
//! watts) that its patch reflects. How it radiates is its [`Profile`].

use glam::Vec3;
use std::f32::consts::PI;

mod light_paths;
pub(crate) use light_paths::light_powers;
pub use light_paths::{
    emitted_power, light_path_vpls, uniform_vpls, MAX_BOUNCES, MAX_RAYS_PER_VPL,
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
    /// Offset of a VPL off its surface, as a fraction of the scene diagonal.
    pub const SURFACE_OFFSET: f32 = 1e-3;
}
