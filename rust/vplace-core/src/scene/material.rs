//! The surface of one material: albedo (constant or textured), emission and alpha test.

use super::*;

/// The surface of one material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Diffuse albedo, every channel in `[0, 1]`; with a `texture`, the constant that the
    /// tinted texture is added to.
    pub albedo: Vec3,
    /// Emitted radiance, W/(m^2 sr) per channel, finite and `>= 0`, from both sides of the
    /// surface (Blender's Emission shader or Principled emission: colour times strength).
    pub emission: Vec3,
    /// A base-colour texture: the albedo at a hit is `albedo + texture_tint * rgb`, clamped to
    /// `[0, 1]` ([`Scene::albedo_at`]).
    pub texture: Option<TextureRef>,
    /// Multiplies the texture's RGB; finite, `>= 0`.
    pub texture_tint: Vec3,
    /// Where the surface is cut away for every ray ([`AlphaTest`]); `None`: opaque.
    pub alpha_test: Option<AlphaTest>,
    /// The glossy layer the light paths reflect off besides the diffuse albedo
    /// ([`Scene::gloss_at`]); `None`: none. The shading of views does not read it (their
    /// glossy layer comes from the captures).
    pub gloss: Option<Gloss>,
}

/// A glossy layer: its reflectance (the mean over incident directions) `constant + tint * rgb`
/// with `rgb` the material's texture (without one, `constant`), clamped to `[0, 1]`, and its
/// roughness (Blender's: the GGX `alpha` is its square).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gloss {
    /// The constant part; every channel finite and `>= 0`.
    pub constant: Vec3,
    /// Multiplies the texture's RGB; every channel finite and `>= 0`.
    pub tint: Vec3,
    /// In `[0, 1]`.
    pub roughness: f32,
}

impl Material {
    /// A plain diffuse material that does not emit.
    #[must_use]
    pub const fn diffuse(albedo: Vec3) -> Self {
        Self {
            albedo,
            emission: Vec3::ZERO,
            texture: None,
            texture_tint: Vec3::ONE,
            alpha_test: None,
            gloss: None,
        }
    }

    /// The material emitting `radiance` (W/(m^2 sr) per channel) from both sides.
    #[must_use]
    pub const fn with_emission(mut self, radiance: Vec3) -> Self {
        self.emission = radiance;
        self
    }

    /// A diffuse material whose albedo is the texture `map` (times `tint`).
    #[must_use]
    pub const fn textured(map: TextureRef, tint: Vec3) -> Self {
        Self {
            albedo: Vec3::ZERO,
            emission: Vec3::ZERO,
            texture: Some(map),
            texture_tint: tint,
            alpha_test: None,
            gloss: None,
        }
    }

    /// The material with a glossy layer (see [`Gloss`]).
    #[must_use]
    pub const fn with_gloss(mut self, constant: Vec3, tint: Vec3, roughness: f32) -> Self {
        self.gloss = Some(Gloss {
            constant,
            tint,
            roughness,
        });
        self
    }

    /// True when hits need the material's UVs (a texture or a textured alpha test).
    #[must_use]
    pub fn reads_uvs(&self) -> bool {
        self.texture.is_some() || self.alpha_test.is_some_and(|a| a.texture.is_some())
    }

    /// Checks the texture references and values; `index` names the material in errors.
    pub(super) fn validate(&self, index: usize, textures: usize) -> Result<()> {
        let what = format!("materials[{index}]");
        if let Some(g) = &self.gloss {
            for (name, v) in [("constant", g.constant), ("tint", g.tint)] {
                let name = format!("{what}.gloss.{name}");
                check_finite(&name, &v.to_array())?;
                if v.min_element() < 0.0 {
                    return Err(VplaceError::OutOfRange {
                        what: name,
                        value: format!("{:?}", v.to_array()),
                        expected: "every channel >= 0".into(),
                    });
                }
            }
            if !(0.0..=1.0).contains(&g.roughness) {
                return Err(VplaceError::OutOfRange {
                    what: format!("{what}.gloss.roughness"),
                    value: g.roughness.to_string(),
                    expected: "in [0, 1]".into(),
                });
            }
        }
        let mut refs = Vec::new();
        if let Some(map) = &self.texture {
            refs.push(("texture", *map));
            check_finite(
                &format!("{what}.texture_tint"),
                &self.texture_tint.to_array(),
            )?;
            if self.texture_tint.min_element() < 0.0 {
                return Err(VplaceError::OutOfRange {
                    what: format!("{what}.texture_tint"),
                    value: format!("{:?}", self.texture_tint.to_array()),
                    expected: "every channel >= 0".into(),
                });
            }
        }
        if let Some(a) = &self.alpha_test {
            check_finite(
                &format!("{what}.alpha_test"),
                &[a.offset, a.scale, a.cutoff],
            )?;
            if let Some(map) = &a.texture {
                refs.push(("alpha_test.texture", *map));
            }
        }
        for (name, map) in refs {
            if map.texture as usize >= textures {
                return Err(VplaceError::IndexOutOfBounds {
                    what: format!("{what}.{name}"),
                    index: map.texture as usize,
                    len: textures,
                });
            }
            let flat = [map.uv_scale.to_array(), map.uv_offset.to_array()].concat();
            check_finite(&format!("{what}.{name} UV transform"), &flat)?;
        }
        Ok(())
    }
}
