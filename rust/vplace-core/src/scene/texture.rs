//! Textures of the materials: linear RGBA images looked up at a surface point's UV.
//!
//! A [`Texture`] holds `height x width` texels, RGBA `f32`, scene-linear, row 0 at the top (the
//! crate's image convention). UV `(0, 0)` is the image's bottom-left corner and `(1, 1)` its
//! top-right, as in Blender; texel `(x, y)` (column `x`, row `y` from the top) has its centre at
//! `u = (x + 0.5) / width`, `v = 1 - (y + 0.5) / height`. [`Texture::sample`] is bilinear
//! between the four nearest texel centres, as Cycles' "Linear" interpolation, with the
//! [`Wrap`] mode deciding which texels lie past the edges.
//!
//! A material refers to a texture through a [`TextureRef`] (texture index, UV scale and offset,
//! wrap mode); what it does with the value is [`crate::scene::Material`]'s business: the base
//! colour (`albedo + tint * rgb`) or the alpha of an [`AlphaTest`].

use glam::{Vec2, Vec4};
use rayon::prelude::*;

use crate::color::luminance;
use crate::error::{Result, VplaceError};

/// What happens past the edges of a texture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    /// The texture tiles the plane (Blender's "Repeat"): `u` and `u + 1` read the same texel.
    #[default]
    Repeat,
    /// The edge texels extend outward (Blender's "Extend").
    Extend,
}

/// A linear RGBA image.
///
/// Invariants: `width, height >= 1`; `texels.len() == width * height`; every value finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the top.
    texels: Vec<Vec4>,
    /// The mean of every texel.
    mean: Vec4,
}

impl Texture {
    /// A texture from `height x width x channels` values (`channels` 3 or 4; RGB gets alpha 1),
    /// row 0 at the top. `what` names it in errors.
    ///
    /// Errors: a zero size, a channel count other than 3 or 4, a length that does not match,
    /// a non-finite value.
    pub fn new(
        what: &str,
        width: usize,
        height: usize,
        channels: usize,
        values: &[f32],
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(VplaceError::Empty {
                what: what.to_owned(),
                hint: format!("a texture needs at least one texel, got {height} x {width}"),
            });
        }
        if channels != 3 && channels != 4 {
            return Err(VplaceError::Shape {
                what: what.to_owned(),
                expected: "3 (RGB) or 4 (RGBA) channels".into(),
                got: format!("{channels} channels"),
            });
        }
        let n = width * height;
        if values.len() != n * channels {
            return Err(VplaceError::Shape {
                what: what.to_owned(),
                expected: format!("({height}, {width}, {channels})"),
                got: format!("{} values", values.len()),
            });
        }
        crate::error::check_finite(what, values)?;
        let texels: Vec<Vec4> = if channels == 4 {
            values.chunks_exact(4).map(Vec4::from_slice).collect()
        } else {
            values
                .chunks_exact(3)
                .map(|c| Vec4::new(c[0], c[1], c[2], 1.0))
                .collect()
        };
        let sum = texels
            .iter()
            .fold(glam::DVec4::ZERO, |acc, t| acc + t.as_dvec4());
        let mean = (sum / n as f64).as_vec4();
        Ok(Self {
            width,
            height,
            texels,
            mean,
        })
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// The mean of every texel, RGBA.
    #[must_use]
    pub fn mean(&self) -> Vec4 {
        self.mean
    }

    /// The texel in column `x`, row `y` (from the top), wrapped into the image by `wrap`.
    #[inline]
    #[must_use]
    pub fn texel(&self, x: i64, y: i64, wrap: Wrap) -> Vec4 {
        let (x, y) = (
            wrap_index(x, self.width, wrap),
            wrap_index(y, self.height, wrap),
        );
        self.texels[y * self.width + x]
    }

    /// The bilinear lookup at `uv` (see the module docs). A non-finite `uv` reads `(0, 0)`.
    #[inline]
    #[must_use]
    pub fn sample(&self, uv: Vec2, wrap: Wrap) -> Vec4 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        // Continuous texel coordinates whose integer points are texel centres.
        let x = f64::from(uv.x) * self.width as f64 - 0.5;
        let y = (1.0 - f64::from(uv.y)) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        // Far outside any sensible range the wrap of an i64 is still defined; clamp first so
        // the cast cannot saturate into different texels for Repeat.
        let (x0, y0) = (clamp_coord(x0), clamp_coord(y0));
        let t00 = self.texel(x0, y0, wrap);
        let t10 = self.texel(x0 + 1, y0, wrap);
        let t01 = self.texel(x0, y0 + 1, wrap);
        let t11 = self.texel(x0 + 1, y0 + 1, wrap);
        let top = t00.lerp(t10, fx);
        let bottom = t01.lerp(t11, fx);
        top.lerp(bottom, fy)
    }
}

/// The 8-bit codes of an image in its colour space, as linear values: entry `c` is code `c`'s.
pub type CodeTable = [f32; 256];

/// An image's pixels as Blender's `Image.pixels` holds them, `height x width x channels` floats
/// with row 0 at the *bottom*, as the crate's linear RGBA (`height x width x 4`, row 0 at the
/// top, [`Texture::new`]'s values) and the mean of every texel, RGBA.
///
/// RGB is the first three channels (one or two channels: the first, grey). With `table` (an
/// 8-bit image in a non-linear space, whose floats are its codes over 255), each RGB value
/// `v` reads `table[round(v * 255)]`, the rounding half to even (`v * 255` in `f32`); without,
/// RGB is kept. Alpha is the last channel where `alpha` and there are 2 or 4 channels, else 1.
/// The mean is summed in `f64` texel by texel from the top row, then divided by the texels.
///
/// Errors: a zero size or channel count, a length that does not match.
pub fn linear_rgba(
    what: &str,
    width: usize,
    height: usize,
    channels: usize,
    values: &[f32],
    table: Option<&CodeTable>,
    alpha: bool,
) -> Result<(Vec<f32>, [f64; 4])> {
    if width == 0 || height == 0 || channels == 0 {
        return Err(VplaceError::Empty {
            what: what.to_owned(),
            hint: format!(
                "an image needs at least one texel and one channel, got {height} x {width} x \
                 {channels}"
            ),
        });
    }
    if values.len() != width * height * channels {
        return Err(VplaceError::Shape {
            what: what.to_owned(),
            expected: format!("{height} x {width} x {channels} values"),
            got: format!("{} values", values.len()),
        });
    }
    let use_alpha = alpha && (channels == 2 || channels == 4);
    let decode = |v: f32| match table {
        // `as u8` saturates: a byte image's values lie in [0, 1], their codes in [0, 255].
        Some(t) => t[usize::from((v * 255.0).round_ties_even() as u8)],
        None => v,
    };
    let mut out = vec![0.0f32; width * height * 4];
    out.par_chunks_mut(width * 4)
        .enumerate()
        .for_each(|(y, row)| {
            let src = &values[(height - 1 - y) * width * channels..][..width * channels];
            for (texel, px) in row.chunks_exact_mut(4).zip(src.chunks_exact(channels)) {
                let rgb = if channels >= 3 {
                    [px[0], px[1], px[2]]
                } else {
                    [px[0]; 3]
                };
                for (o, v) in texel.iter_mut().zip(rgb) {
                    *o = decode(v);
                }
                texel[3] = if use_alpha { px[channels - 1] } else { 1.0 };
            }
        });
    let mut sum = [0.0f64; 4];
    for texel in out.chunks_exact(4) {
        for (s, &v) in sum.iter_mut().zip(texel) {
            *s += f64::from(v);
        }
    }
    let n = (width * height) as f64;
    Ok((out, sum.map(|s| s / n)))
}

/// A texel coordinate kept where `i64` arithmetic and the wrap are exact.
#[inline]
fn clamp_coord(c: f64) -> i64 {
    c.clamp(-(1i64 << 52) as f64, (1i64 << 52) as f64) as i64
}

#[inline]
fn wrap_index(i: i64, n: usize, wrap: Wrap) -> usize {
    match wrap {
        Wrap::Repeat => i.rem_euclid(n as i64) as usize,
        Wrap::Extend => i.clamp(0, n as i64 - 1) as usize,
    }
}

/// How a material reads one texture: `uv' = uv * uv_scale + uv_offset`, then a [`Wrap`]ped
/// bilinear lookup (Blender's Mapping node of type Point without rotation, in front of an Image
/// Texture node).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    /// Index into the scene's textures.
    pub texture: u32,
    /// Scale of the UV coordinates, per axis.
    pub uv_scale: Vec2,
    /// Offset added after the scale.
    pub uv_offset: Vec2,
    /// What lies past the texture's edges.
    pub wrap: Wrap,
}

impl TextureRef {
    /// Texture `texture` read at the plain UV coordinates, repeating.
    #[must_use]
    pub const fn new(texture: u32) -> Self {
        Self {
            texture,
            uv_scale: Vec2::ONE,
            uv_offset: Vec2::ZERO,
            wrap: Wrap::Repeat,
        }
    }

    /// The lookup in `textures` at `uv` (the index was checked when the scene was built).
    #[inline]
    #[must_use]
    pub fn sample(&self, textures: &[Texture], uv: Vec2) -> Vec4 {
        textures[self.texture as usize].sample(uv * self.uv_scale + self.uv_offset, self.wrap)
    }
}

/// Which value of a texture an [`AlphaTest`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AlphaSource {
    /// The alpha channel (an Image Texture node's Alpha output).
    #[default]
    Alpha,
    /// The Rec. 709 luminance of RGB (its Color output plugged into a float input).
    Luminance,
}

/// An alpha-tested surface: where `alpha < cutoff` rays pass through it as if it were not
/// there (shadow rays, light paths); elsewhere it is opaque.
///
/// `alpha = offset + scale * value`, `value` the [`AlphaSource`] of `texture` at the hit, or
/// `alpha = offset` without a texture. (Cycles lets a fraction `1 - alpha` of the light through;
/// with the cutoff `0.5` the test rounds that to the nearer of all or nothing.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaTest {
    /// The alpha without a texture, or the offset of the texture's value.
    pub offset: f32,
    /// Multiplies the texture's value (`-1` with offset `1` inverts it).
    pub scale: f32,
    /// The texture the alpha comes from, if any.
    pub texture: Option<TextureRef>,
    /// Which of the texture's values is read.
    pub source: AlphaSource,
    /// Rays pass where `alpha < cutoff`.
    pub cutoff: f32,
}

impl AlphaTest {
    /// The cutoff of Blender's former "Alpha Clip" blend mode and of glTF's MASK default.
    pub const DEFAULT_CUTOFF: f32 = 0.5;

    /// A constant alpha.
    #[must_use]
    pub const fn constant(alpha: f32) -> Self {
        Self {
            offset: alpha,
            scale: 0.0,
            texture: None,
            source: AlphaSource::Alpha,
            cutoff: Self::DEFAULT_CUTOFF,
        }
    }

    /// The alpha channel of a texture.
    #[must_use]
    pub const fn texture(map: TextureRef) -> Self {
        Self {
            offset: 0.0,
            scale: 1.0,
            texture: Some(map),
            source: AlphaSource::Alpha,
            cutoff: Self::DEFAULT_CUTOFF,
        }
    }

    /// The alpha at `uv`.
    #[inline]
    #[must_use]
    pub fn alpha(&self, textures: &[Texture], uv: Vec2) -> f32 {
        match &self.texture {
            None => self.offset,
            Some(map) => {
                let t = map.sample(textures, uv);
                let value = match self.source {
                    AlphaSource::Alpha => t.w,
                    AlphaSource::Luminance => luminance(t.truncate()),
                };
                self.offset + self.scale * value
            }
        }
    }

    /// True where a ray passes through the surface at `uv`.
    #[inline]
    #[must_use]
    pub fn cut(&self, textures: &[Texture], uv: Vec2) -> bool {
        self.alpha(textures, uv) < self.cutoff
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2 x 2 texture: red, green (top row), blue, white (bottom row), alpha 0, 1, 1, 0.
    fn quad() -> Texture {
        #[rustfmt::skip]
        let v = [
            1., 0., 0., 0.,   0., 1., 0., 1.,
            0., 0., 1., 1.,   1., 1., 1., 0.,
        ];
        Texture::new("t", 2, 2, 4, &v).unwrap()
    }

    #[test]
    fn blender_pixels_flip_decode_and_average() {
        // 2 x 1 RGBA, Blender's bottom row first: codes 0 and 255, 51 and 102, alpha 0.2/0.6.
        #[rustfmt::skip]
        let v = [
            0.0, 51.0 / 255.0, 1.0, 0.2,
            1.0, 102.0 / 255.0, 0.0, 0.6,
        ];
        let mut table = [0.0f32; 256];
        for (c, t) in table.iter_mut().enumerate() {
            *t = c as f32 * 2.0; // a table whose entries name their codes
        }
        let (out, mean) = linear_rgba("t", 1, 2, 4, &v, Some(&table), true).unwrap();
        // Row 0 is the top: Blender's last row.
        assert_eq!(out, [510.0, 204.0, 0.0, 0.6, 0.0, 102.0, 510.0, 0.2]);
        assert_eq!(
            mean,
            [255.0, 153.0, 255.0, (0.6f32 as f64 + 0.2f32 as f64) / 2.0]
        );
        // Without the table RGB is kept; without alpha it is 1.
        let (plain, _) = linear_rgba("t", 1, 2, 4, &v, None, false).unwrap();
        assert_eq!(&plain[..4], &[1.0, 102.0 / 255.0, 0.0, 1.0]);
        // One channel is grey; halfway codes round to even.
        let (grey, _) = linear_rgba(
            "t",
            2,
            1,
            1,
            &[0.5 / 255.0, 1.5 / 255.0],
            Some(&table),
            true,
        )
        .unwrap();
        assert_eq!(grey, [0.0, 0.0, 0.0, 1.0, 4.0, 4.0, 4.0, 1.0]);
    }

    #[test]
    fn blender_pixels_errors() {
        assert!(matches!(
            linear_rgba("t", 0, 1, 4, &[], None, true),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            linear_rgba("t", 2, 2, 4, &[0.0; 15], None, true),
            Err(VplaceError::Shape { .. })
        ));
    }

    #[test]
    fn texel_centres_read_their_texel_exactly() {
        let t = quad();
        let at = |u: f32, v: f32| t.sample(Vec2::new(u, v), Wrap::Repeat);
        assert_eq!(at(0.25, 0.75), Vec4::new(1., 0., 0., 0.)); // top left
        assert_eq!(at(0.75, 0.75), Vec4::new(0., 1., 0., 1.)); // top right
        assert_eq!(at(0.25, 0.25), Vec4::new(0., 0., 1., 1.)); // bottom left
        assert_eq!(at(0.75, 0.25), Vec4::new(1., 1., 1., 0.)); // bottom right
        assert_eq!(t.mean(), Vec4::new(0.5, 0.5, 0.5, 0.5));
    }

    #[test]
    fn bilinear_between_centres() {
        let t = quad();
        // Midway between the two top texels: half red, half green.
        let mid = t.sample(Vec2::new(0.5, 0.75), Wrap::Extend);
        assert!((mid - Vec4::new(0.5, 0.5, 0.0, 0.5)).abs().max_element() < 1e-6);
        // The centre of the image: the mean of all four.
        let c = t.sample(Vec2::new(0.5, 0.5), Wrap::Extend);
        assert!((c - t.mean()).abs().max_element() < 1e-6);
        // A quarter of the way from the top-left centre to the top-right one.
        let q = t.sample(Vec2::new(0.375, 0.75), Wrap::Extend);
        assert!((q - Vec4::new(0.75, 0.25, 0.0, 0.25)).abs().max_element() < 1e-6);
    }

    #[test]
    fn repeat_tiles_and_extend_clamps() {
        let t = quad();
        for (u, v) in [(0.1, 0.3), (0.6, 0.9), (0.93, 0.07)] {
            let base = t.sample(Vec2::new(u, v), Wrap::Repeat);
            for (du, dv) in [(1.0, 0.0), (-3.0, 2.0), (17.0, -5.0)] {
                let moved = t.sample(Vec2::new(u + du, v + dv), Wrap::Repeat);
                assert!(
                    (moved - base).abs().max_element() < 1e-4,
                    "{u} {v} {du} {dv}"
                );
            }
        }
        // At u = 0 the repeat blends the left column with the right one (across the seam);
        // extend reads the left column only.
        let seam = t.sample(Vec2::new(0.0, 0.75), Wrap::Repeat);
        assert!((seam - Vec4::new(0.5, 0.5, 0.0, 0.5)).abs().max_element() < 1e-6);
        let edge = t.sample(Vec2::new(0.0, 0.75), Wrap::Extend);
        assert_eq!(edge, Vec4::new(1., 0., 0., 0.));
        assert_eq!(
            t.sample(Vec2::new(-7.0, 9.0), Wrap::Extend),
            t.texel(0, 0, Wrap::Extend)
        );
        // Huge and non-finite coordinates stay inside the image.
        let big = t.sample(Vec2::new(1e30, -1e30), Wrap::Repeat);
        assert!(big.is_finite());
        assert_eq!(
            t.sample(Vec2::new(f32::NAN, 0.0), Wrap::Repeat),
            t.sample(Vec2::ZERO, Wrap::Repeat)
        );
    }

    #[test]
    fn rgb_gets_alpha_one_and_bad_input_is_an_error() {
        let t = Texture::new("rgb", 1, 1, 3, &[0.2, 0.4, 0.6]).unwrap();
        assert_eq!(t.mean(), Vec4::new(0.2, 0.4, 0.6, 1.0));
        assert!(matches!(
            Texture::new("t", 0, 1, 3, &[]),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            Texture::new("t", 1, 1, 2, &[0.0, 0.0]),
            Err(VplaceError::Shape { .. })
        ));
        assert!(matches!(
            Texture::new("t", 2, 1, 3, &[0.0; 3]),
            Err(VplaceError::Shape { .. })
        ));
        assert!(matches!(
            Texture::new("t", 1, 1, 3, &[0.0, f32::INFINITY, 0.0]),
            Err(VplaceError::NonFinite { index: 1, .. })
        ));
    }

    #[test]
    fn uv_transform_and_alpha_tests() {
        let textures = [quad()];
        let map = TextureRef {
            uv_scale: Vec2::splat(0.5),
            uv_offset: Vec2::new(0.5, 0.0),
            ..TextureRef::new(0)
        };
        // uv (0.5, 0.5) -> (0.75, 0.25): the bottom-right texel.
        assert_eq!(
            map.sample(&textures, Vec2::new(0.5, 0.5)),
            Vec4::new(1., 1., 1., 0.)
        );
        let test = AlphaTest::texture(TextureRef::new(0));
        assert!(test.cut(&textures, Vec2::new(0.25, 0.75)));
        assert!(!test.cut(&textures, Vec2::new(0.75, 0.75)));
        let inverted = AlphaTest {
            offset: 1.0,
            scale: -1.0,
            ..test
        };
        assert!(!inverted.cut(&textures, Vec2::new(0.25, 0.75)));
        assert!(inverted.cut(&textures, Vec2::new(0.75, 0.75)));
        let lum = AlphaTest {
            source: AlphaSource::Luminance,
            ..test
        };
        // Red has luminance 0.2126 < 0.5, white 1.
        assert!(lum.cut(&textures, Vec2::new(0.25, 0.75)));
        assert!(!lum.cut(&textures, Vec2::new(0.75, 0.25)));
        assert!(AlphaTest::constant(0.3).cut(&textures, Vec2::ZERO));
        assert!(!AlphaTest::constant(0.7).cut(&textures, Vec2::ZERO));
    }
}
