//! The G-buffer contract: the borrowed per-pixel surface arrays every stage after the capture
//! reads (the feature extraction, the evaluator, the refit, the direct-light estimator), and the
//! one shape check of an image. A [`crate::view::View`] lends its own ([`View::gbuffer`]); tests
//! and benches build one from `test_util::GBufferArrays`.
//!
//! [`View::gbuffer`]: crate::view::View::gbuffer

use glam::Vec3;

use crate::error::{check_finite, Result, VplaceError};

/// A G-buffer view: `width x height` pixels, row 0 at the top, flat `H x W x 3` arrays.
#[derive(Debug, Clone, Copy)]
pub struct GBuffer<'a> {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// World position per pixel (`H x W x 3`).
    pub position: &'a [f32],
    /// World-space shading normal per pixel (`H x W x 3`); need not be unit length (a pixel that
    /// straddles two surfaces averages their normals; the shading normalizes it).
    pub normal: &'a [f32],
    /// Diffuse albedo per pixel (`H x W x 3`).
    pub albedo: &'a [f32],
    /// True where the pixel sees geometry (`H x W`); uncovered pixels stay zero.
    pub covered: &'a [bool],
}

impl GBuffer<'_> {
    /// Checks that the image is not empty and every array has its size.
    pub fn check_shape(&self) -> Result<()> {
        if self.width * self.height == 0 {
            return Err(VplaceError::Empty {
                what: "G-buffer".into(),
                hint: "width and height must be at least 1".into(),
            });
        }
        for (what, arr) in [
            ("position", self.position),
            ("normal", self.normal),
            ("albedo", self.albedo),
        ] {
            check_len(what, arr.len(), self.width, self.height, 3)?;
        }
        check_len("covered", self.covered.len(), self.width, self.height, 1)
    }

    /// [`GBuffer::check_shape`], and the covered pixels finite (what a [`crate::view::View`]
    /// guarantees; the evaluator, the refit and the direct-light estimator need it).
    pub fn validate(&self) -> Result<()> {
        self.check_shape()?;
        for (what, arr) in [
            ("position", self.position),
            ("normal", self.normal),
            ("albedo", self.albedo),
        ] {
            for (p, _) in self.covered.iter().enumerate().filter(|(_, &c)| c) {
                check_finite(what, &arr[3 * p..3 * p + 3]).map_err(|_| VplaceError::NonFinite {
                    what: format!("{what} (covered pixel)"),
                    index: 3 * p,
                })?;
            }
        }
        Ok(())
    }

    /// The 3-vector of pixel `p` of the flat `H x W x 3` array `arr`.
    #[inline]
    #[must_use]
    pub(crate) fn vec3(arr: &[f32], p: usize) -> Vec3 {
        Vec3::new(arr[3 * p], arr[3 * p + 1], arr[3 * p + 2])
    }
}

/// Checks that a flat array of `len` values is a `height x width x channels` image (`channels
/// == 1`: `height x width`); the error names `what` and the expected shape. The one shape check
/// of every image the core takes.
pub fn check_len(
    what: &str,
    len: usize,
    width: usize,
    height: usize,
    channels: usize,
) -> Result<()> {
    if len == width * height * channels {
        return Ok(());
    }
    Err(VplaceError::Shape {
        what: what.into(),
        expected: if channels == 1 {
            format!("({height}, {width})")
        } else {
            format!("({height}, {width}, {channels})")
        },
        got: format!("{len} values"),
    })
}
