//! The scene's lights: every Blender kind with its parameters, checked once.

use super::*;

/// The emitting shape of a [`Light`]. Radiometry follows Blender's Cycles exactly (see DESIGN,
/// Coordinates and units, and the module docs of [`crate::scene::emitters`], which sample them).
#[derive(Debug, Clone, PartialEq)]
pub enum LightKind {
    /// Blender POINT of power `P`: intensity `P / (4 pi)` in every direction. With a `radius`
    /// (Blender's `shadow_soft_size`) it is a sphere of that radius (`soft_falloff` off) or a
    /// disk of that radius always facing the receiver (`soft_falloff` on, Blender's default),
    /// of radiance `P / (4 pi^2 radius^2)`.
    Point {
        /// Radius of the emitting sphere or disk, metres (`>= 0`; 0: a point).
        radius: f32,
        /// Blender's `use_soft_falloff`: a disk facing the receiver instead of a sphere.
        soft_falloff: bool,
    },
    /// Blender SPOT: the point light (with its radius) cut by the cone of half angle
    /// `half_angle` about `direction`, with Blender's smoothstep `blend` over the outer part of
    /// the cone. Emitted power is `P (1 - cos half_angle) (1 - blend / 2) / 2`.
    Spot {
        /// Half of Blender's `spot_size`, radians, in `(0, pi]`.
        half_angle: f32,
        /// Blender's `spot_blend`, in `[0, 1]`: the smoothstep covers this fraction of the
        /// cone's `1 - cos` range, from its edge inwards.
        blend: f32,
        /// Radius of the emitting sphere or disk, metres (`>= 0`).
        radius: f32,
        /// Blender's `use_soft_falloff` (see [`LightKind::Point`]).
        soft_falloff: bool,
    },
    /// Blender AREA light (normalize on): a one-sided emitter of total power `P` and radiance
    /// `P / (pi A) g(theta)` about `direction`, `A` its area, `g` Blender's spread attenuation
    /// (1 for a spread of pi: a cosine emitter). `size_x`, `size_y` along `tangent` and
    /// `direction x tangent`.
    Area {
        /// Elliptical (Blender DISK or ELLIPSE, diameters `size_x` and `size_y`) or
        /// rectangular (RECTANGLE or SQUARE).
        disk: bool,
        /// Extent along `tangent`, metres (`> 0`).
        size_x: f32,
        /// Extent along `direction x tangent`, metres (`> 0`; `size_x` for a square or a disk).
        size_y: f32,
        /// Blender's `spread`, radians in `[0, pi]`: the full angle of the cone the light leaves
        /// in, through a soft-box grid of that angle (pi: no grid; 0: a collimated beam).
        spread: f32,
    },
    /// Blender SUN: light travelling along `direction` with irradiance `power` (W/m^2) on a
    /// plane perpendicular to it, from a disk of directions of full angle `angle`, of radiance
    /// `power / (pi sin^2(angle / 2))`.
    Sun {
        /// Blender's `angle`, radians in `[0, pi]` (0: parallel light).
        angle: f32,
    },
    /// The world: light of radiance `power * map(w)` (W/(m^2 sr) per channel) arriving from
    /// every direction `w`; `map` an equirectangular image (Blender's Environment Texture), or 1
    /// (a uniform world colour) without one.
    World {
        /// The environment image, or `None` for a uniform colour.
        map: Option<Arc<EnvironmentMap>>,
    },
}

/// A light of the scene.
///
/// Invariants (checked by [`Light::validate`]): finite fields, non-negative `power`, unit
/// `direction` and `tangent`, perpendicular to each other; the kind's parameters in range.
#[derive(Debug, Clone, PartialEq)]
pub struct Light {
    /// The emitter shape.
    pub kind: LightKind,
    /// World position (centre of an area light); unused for a sun and the world.
    pub position: Vec3,
    /// Unit emission axis: the direction light leaves an area light or a spot, or travels for a sun.
    pub direction: Vec3,
    /// Unit tangent orienting an area light's `size_x` axis; perpendicular to `direction`.
    pub tangent: Vec3,
    /// Colour times power, W per channel (W/m^2 for a sun, W/(m^2 sr) for the world).
    pub power: Vec3,
}

impl Light {
    /// A POINT light of `power` (RGB watts), radius 0 (see [`Light::with_radius`]).
    #[must_use]
    pub fn point(position: Vec3, power: Vec3) -> Self {
        Self {
            kind: LightKind::Point {
                radius: 0.0,
                soft_falloff: true,
            },
            position,
            direction: Vec3::NEG_Z,
            tangent: Vec3::X,
            power,
        }
    }

    /// A SPOT light with cone half angle `half_angle` (radians) about `direction`, blend 0 and
    /// radius 0 (see [`Light::with_blend`], [`Light::with_radius`]).
    #[must_use]
    pub fn spot(position: Vec3, direction: Vec3, half_angle: f32, power: Vec3) -> Self {
        let direction = direction.normalize_or_zero();
        Self {
            kind: LightKind::Spot {
                half_angle,
                blend: 0.0,
                radius: 0.0,
                soft_falloff: true,
            },
            position,
            direction,
            tangent: direction.any_orthonormal_vector(),
            power,
        }
    }

    /// An AREA light emitting along `direction`, `size_x` along `tangent`, spread pi (see
    /// [`Light::with_spread`]). A `disk` with `size_y <= 0` is round (`size_y = size_x`).
    #[must_use]
    pub fn area(
        position: Vec3,
        direction: Vec3,
        tangent: Vec3,
        disk: bool,
        size_x: f32,
        size_y: f32,
        power: Vec3,
    ) -> Self {
        let size_y = if disk && size_y <= 0.0 {
            size_x
        } else {
            size_y
        };
        Self {
            kind: LightKind::Area {
                disk,
                size_x,
                size_y,
                spread: std::f32::consts::PI,
            },
            position,
            direction: direction.normalize_or_zero(),
            tangent: tangent.normalize_or_zero(),
            power,
        }
    }

    /// A SUN travelling along `direction` with `irradiance` (RGB W/m^2), angle 0 (see
    /// [`Light::with_angle`]).
    #[must_use]
    pub fn sun(direction: Vec3, irradiance: Vec3) -> Self {
        let direction = direction.normalize_or_zero();
        Self {
            kind: LightKind::Sun { angle: 0.0 },
            position: Vec3::ZERO,
            direction,
            tangent: direction.any_orthonormal_vector(),
            power: irradiance,
        }
    }

    /// The world: radiance `radiance` (RGB W/(m^2 sr), Blender's background colour times
    /// strength) times `map` where one is given.
    #[must_use]
    pub fn world(radiance: Vec3, map: Option<Arc<EnvironmentMap>>) -> Self {
        Self {
            kind: LightKind::World { map },
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            tangent: Vec3::X,
            power: radiance,
        }
    }

    /// The light with Blender's `shadow_soft_size` `radius` and `use_soft_falloff`; no effect
    /// on lights other than points and spots.
    #[must_use]
    pub fn with_radius(mut self, radius_m: f32, soft: bool) -> Self {
        if let LightKind::Point {
            radius,
            soft_falloff,
        }
        | LightKind::Spot {
            radius,
            soft_falloff,
            ..
        } = &mut self.kind
        {
            *radius = radius_m;
            *soft_falloff = soft;
        }
        self
    }

    /// The spot with Blender's `spot_blend`; no effect on other lights.
    #[must_use]
    pub fn with_blend(mut self, spot_blend: f32) -> Self {
        if let LightKind::Spot { blend, .. } = &mut self.kind {
            *blend = spot_blend;
        }
        self
    }

    /// The area light with Blender's `spread` (radians); no effect on other lights.
    #[must_use]
    pub fn with_spread(mut self, area_spread: f32) -> Self {
        if let LightKind::Area { spread, .. } = &mut self.kind {
            *spread = area_spread;
        }
        self
    }

    /// The sun with Blender's `angle` (radians); no effect on other lights.
    #[must_use]
    pub fn with_angle(mut self, sun_angle: f32) -> Self {
        if let LightKind::Sun { angle } = &mut self.kind {
            *angle = sun_angle;
        }
        self
    }

    /// Checks the invariants; `index` names the light in the error.
    pub fn validate(&self, index: usize) -> Result<()> {
        self.validate_as(&format!("lights[{index}]"))
    }

    /// Checks the invariants; `what` names the light in the error.
    pub fn validate_as(&self, what: &str) -> Result<()> {
        let v = self;
        let flat = [
            v.position.to_array(),
            v.direction.to_array(),
            v.tangent.to_array(),
            v.power.to_array(),
        ]
        .concat();
        check_finite(what, &flat)?;
        if v.power.min_element() < 0.0 {
            return Err(VplaceError::OutOfRange {
                what: format!("{what}.power"),
                value: format!("{:?}", v.power.to_array()),
                expected: "every channel >= 0".into(),
            });
        }
        if (v.direction.length() - 1.0).abs() > 1e-3 || (v.tangent.length() - 1.0).abs() > 1e-3 {
            return Err(VplaceError::Invalid {
                what: what.to_owned(),
                reason: "direction and tangent must be non-zero vectors".into(),
            });
        }
        let range = |name: &str, value: f32, ok: bool, expected: &str| {
            if ok {
                Ok(())
            } else {
                Err(VplaceError::OutOfRange {
                    what: format!("{what}.{name}"),
                    value: value.to_string(),
                    expected: expected.into(),
                })
            }
        };
        let pi = std::f32::consts::PI;
        match &v.kind {
            LightKind::Point { radius, .. } => range(
                "radius",
                *radius,
                *radius >= 0.0 && radius.is_finite(),
                ">= 0",
            ),
            LightKind::Spot {
                half_angle,
                blend,
                radius,
                ..
            } => {
                range(
                    "half_angle",
                    *half_angle,
                    *half_angle > 0.0 && *half_angle <= pi,
                    "(0, pi]",
                )?;
                range("blend", *blend, (0.0..=1.0).contains(blend), "[0, 1]")?;
                range(
                    "radius",
                    *radius,
                    *radius >= 0.0 && radius.is_finite(),
                    ">= 0",
                )
            }
            LightKind::Area {
                size_x,
                size_y,
                spread,
                ..
            } => {
                if !(*size_x > 0.0 && *size_y > 0.0 && size_x.is_finite() && size_y.is_finite()) {
                    return Err(VplaceError::OutOfRange {
                        what: format!("{what}.size"),
                        value: format!("({size_x}, {size_y})"),
                        expected: "> 0".into(),
                    });
                }
                range("spread", *spread, (0.0..=pi).contains(spread), "[0, pi]")
            }
            LightKind::Sun { angle } => {
                range("angle", *angle, (0.0..=pi).contains(angle), "[0, pi]")
            }
            LightKind::World { .. } => Ok(()),
        }
    }
}
