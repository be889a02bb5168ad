//! One captured view (DESIGN: Capture, Views): the G-buffer, the lighting passes and the
//! camera of one render, checked once when the view is made.
//!
//! Every later stage (features, layout, iteration, refit, evaluator) reads views and never
//! checks their arrays again. The checks:
//! - every array has the size of the image (`H x W x 3`, or `H x W` for `depth` and `covered`);
//! - the G-buffer (`position`, `normal`, `albedo`, `depth`) is finite on covered pixels: a
//!   non-finite value there is an error naming the pass and the pixel (a renderer's G-buffer is
//!   never NaN, so it is a bug upstream);
//! - a covered pixel whose *lighting* passes (`direct`, `diffuse_direct`, `diffuse_indirect`,
//!   `indirect`, `specular`, `diffuse_color`) hold NaN or inf is *masked*: it becomes uncovered
//!   and is counted in [`View::masked_pixels`] (a path tracer's rare firefly should not abort a
//!   run, and the count is reported so that it cannot go unnoticed);
//! - the camera is finite and its matrix invertible.

use glam::{Mat4, Vec3};

use crate::error::{check_finite, Result, VplaceError};

mod gbuffer;
pub use gbuffer::{check_len, GBuffer};

/// The camera of a view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// World position of the eye.
    pub position: Vec3,
    /// World to clip matrix, OpenGL conventions: NDC x to the right, y up, both in `[-1, 1]`
    /// over the image (in Blender: `camera.calc_matrix_camera(depsgraph, x=W, y=H) @
    /// camera.matrix_world.inverted()`). Invertible.
    pub world_to_clip: Mat4,
}

impl Camera {
    /// Pixel coordinates `(x, y)` of world point `p` (x right, y down, pixel centres at `+0.5`),
    /// or `None` behind the camera.
    #[must_use]
    pub fn to_pixel(&self, p: Vec3, width: usize, height: usize) -> Option<(f32, f32)> {
        let c = self.world_to_clip * p.extend(1.0);
        if c.w <= 0.0 {
            return None;
        }
        let (x, y) = (c.x / c.w, c.y / c.w);
        Some((
            (x + 1.0) * 0.5 * width as f32,
            (1.0 - y) * 0.5 * height as f32,
        ))
    }
}

/// The arrays of a view as a caller holds them (borrowed, unchecked): the input of [`View::new`],
/// its [`GBuffer`] and the lighting passes.
/// Images are flat, row-major, row 0 at the top.
#[derive(Debug, Clone, Copy)]
pub struct ViewInput<'a> {
    /// A name for messages and reports (the camera's name, say).
    pub name: &'a str,
    /// The G-buffer: image size (`>= 1` each way), world position, shading normal (need not be
    /// unit length: a pixel that straddles two surfaces averages their normals), diffuse albedo
    /// (Cycles `DiffCol`) and coverage.
    pub gbuffer: GBuffer<'a>,
    /// Planar camera depth, Cycles `Z` (`H x W`).
    pub depth: &'a [f32],
    /// The direct image `D` (`H x W x 3`).
    pub direct: &'a [f32],
    /// Cycles `DiffDir`: direct irradiance / pi (`H x W x 3`).
    pub diffuse_direct: &'a [f32],
    /// Cycles `DiffInd`: indirect irradiance / pi (`H x W x 3`); `None` for a view without a
    /// global-illumination render.
    pub diffuse_indirect: Option<&'a [f32]>,
    /// The indirect light the VPLs should reproduce (`H x W x 3`), or `None`.
    pub indirect: Option<&'a [f32]>,
    /// Cycles `GlossCol` (`H x W x 3`), or `None`.
    pub specular: Option<&'a [f32]>,
    /// Cycles `DiffCol` (`H x W x 3`) where `gbuffer.albedo` is more than it: a receiver's
    /// reflectance that adds the glossy layers the VPLs light (the add-on's
    /// `Capture.reflectance`); `None`: the albedo is `DiffCol`. What the surface's diffuse layer
    /// reflects ([`View::diffuse_color_at`]).
    pub diffuse_color: Option<&'a [f32]>,
    /// The camera.
    pub camera: Camera,
}

/// One checked view. Invariants: every array has the image's size; covered pixels are finite
/// in every pass; `camera` is finite with an invertible matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// A name for messages and reports.
    pub name: String,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// World position (`H x W x 3`).
    pub position: Vec<f32>,
    /// World shading normal (`H x W x 3`).
    pub normal: Vec<f32>,
    /// Diffuse albedo (`H x W x 3`).
    pub albedo: Vec<f32>,
    /// Covered pixels after masking (`H x W`).
    pub covered: Vec<bool>,
    /// Planar camera depth (`H x W`).
    pub depth: Vec<f32>,
    /// The direct image `D` (`H x W x 3`).
    pub direct: Vec<f32>,
    /// Direct irradiance / pi (`H x W x 3`).
    pub diffuse_direct: Vec<f32>,
    /// Indirect irradiance / pi (`H x W x 3`), when the view was rendered with it.
    pub diffuse_indirect: Option<Vec<f32>>,
    /// The target indirect image (`H x W x 3`), when known.
    pub indirect: Option<Vec<f32>>,
    /// Specular colour (`H x W x 3`), when given.
    pub specular: Option<Vec<f32>>,
    /// The diffuse layer's colour (`H x W x 3`) where `albedo` is more than it, when given
    /// ([`ViewInput::diffuse_color`]).
    pub diffuse_color: Option<Vec<f32>>,
    /// The camera.
    pub camera: Camera,
    /// Covered pixels the caller gave that were masked for a non-finite lighting pass.
    pub masked_pixels: usize,
}

impl View {
    /// Checks and copies `input` (see the module docs for what is checked).
    pub fn new(input: &ViewInput<'_>) -> Result<Self> {
        let g = input.gbuffer;
        let (w, h) = (g.width, g.height);
        if w == 0 || h == 0 {
            return Err(VplaceError::Empty {
                what: format!("view {:?}", input.name),
                hint: "width and height must be at least 1".into(),
            });
        }
        let rgb = [
            ("position", Some(g.position)),
            ("normal", Some(g.normal)),
            ("albedo", Some(g.albedo)),
            ("direct", Some(input.direct)),
            ("diffuse_direct", Some(input.diffuse_direct)),
            ("diffuse_indirect", input.diffuse_indirect),
            ("indirect", input.indirect),
            ("specular", input.specular),
            ("diffuse_color", input.diffuse_color),
        ];
        for (what, arr) in rgb {
            if let Some(a) = arr {
                check_len(what, a.len(), w, h, 3)?;
            }
        }
        check_len("covered", g.covered.len(), w, h, 1)?;
        check_len("depth", input.depth.len(), w, h, 1)?;
        check_finite("camera_position", &input.camera.position.to_array())?;
        check_finite("world_to_clip", &input.camera.world_to_clip.to_cols_array())?;
        if input.camera.world_to_clip.determinant().abs() < 1e-30 {
            return Err(VplaceError::Invalid {
                what: "world_to_clip".into(),
                reason: "the camera matrix is singular".into(),
            });
        }
        let mut covered = g.covered.to_vec();
        let mut masked = 0;
        for (p, c) in covered.iter_mut().enumerate().filter(|(_, c)| **c) {
            let px = 3 * p..3 * p + 3;
            for (what, arr) in &rgb[..3] {
                let a = arr.expect("the G-buffer is always given");
                if !a[px.clone()].iter().all(|v| v.is_finite()) {
                    return Err(VplaceError::NonFinite {
                        what: format!("{what} (covered pixel {p} of view {:?})", input.name),
                        index: 3 * p,
                    });
                }
            }
            if !input.depth[p].is_finite() {
                return Err(VplaceError::NonFinite {
                    what: format!("depth (covered pixel {p} of view {:?})", input.name),
                    index: p,
                });
            }
            let lit = rgb[3..]
                .iter()
                .filter_map(|(_, a)| *a)
                .all(|a| a[px.clone()].iter().all(|v| v.is_finite()));
            if !lit {
                *c = false;
                masked += 1;
            }
        }
        Ok(Self {
            name: input.name.to_owned(),
            width: w,
            height: h,
            position: g.position.to_vec(),
            normal: g.normal.to_vec(),
            albedo: g.albedo.to_vec(),
            covered,
            depth: input.depth.to_vec(),
            direct: input.direct.to_vec(),
            diffuse_direct: input.diffuse_direct.to_vec(),
            diffuse_indirect: input.diffuse_indirect.map(<[f32]>::to_vec),
            indirect: input.indirect.map(<[f32]>::to_vec),
            specular: input.specular.map(<[f32]>::to_vec),
            diffuse_color: input.diffuse_color.map(<[f32]>::to_vec),
            camera: input.camera,
            masked_pixels: masked,
        })
    }

    /// The view without its global-illumination passes (`diffuse_indirect`, `indirect`): what a
    /// view the model has not seen provides.
    #[must_use]
    pub fn without_indirect(&self) -> Self {
        Self {
            diffuse_indirect: None,
            indirect: None,
            ..self.clone()
        }
    }

    /// The view with only the covered pixels that `mask` (`H x W`) marks still covered: what
    /// the evaluator then shades, the rest left black.
    ///
    /// # Errors
    /// [`VplaceError::Shape`] when `mask` is not the view's size.
    pub fn restricted(&self, mask: &[bool]) -> Result<Self> {
        if mask.len() != self.width * self.height {
            return Err(VplaceError::Shape {
                what: "mask".into(),
                expected: format!("({}, {})", self.height, self.width),
                got: format!("{} values", mask.len()),
            });
        }
        let covered = self
            .covered
            .iter()
            .zip(mask)
            .map(|(&c, &m)| c && m)
            .collect();
        Ok(Self {
            covered,
            ..self.clone()
        })
    }

    /// The G-buffer of the view, for the feature extraction, the evaluator and the refit.
    #[must_use]
    pub fn gbuffer(&self) -> GBuffer<'_> {
        GBuffer {
            width: self.width,
            height: self.height,
            position: &self.position,
            normal: &self.normal,
            albedo: &self.albedo,
            covered: &self.covered,
        }
    }

    /// Number of covered pixels.
    #[must_use]
    pub fn covered_count(&self) -> usize {
        self.covered.iter().filter(|&&c| c).count()
    }

    /// The colour of the diffuse layer of pixel `p`'s surface (Cycles `DiffCol`): the
    /// `diffuse_color` where given, else the albedo.
    #[inline]
    #[must_use]
    pub fn diffuse_color_at(&self, p: usize) -> Vec3 {
        let a = self.diffuse_color.as_deref().unwrap_or(&self.albedo);
        Vec3::from_slice(&a[3 * p..3 * p + 3])
    }

    /// World position of pixel `p`.
    #[inline]
    #[must_use]
    pub fn position_at(&self, p: usize) -> Vec3 {
        Vec3::from_slice(&self.position[3 * p..3 * p + 3])
    }

    /// True when the view sees world point `x` itself: `x` projects inside the image onto a
    /// covered pixel and `occluded(camera, x)` is false.
    pub fn sees(&self, x: Vec3, occluded: impl Fn(Vec3, Vec3) -> bool) -> bool {
        let (w, h) = (self.width, self.height);
        self.camera.to_pixel(x, w, h).is_some_and(|(px, py)| {
            px >= 0.0
                && py >= 0.0
                && px < w as f32
                && py < h as f32
                && self.covered[py as usize * w + px as usize]
                && !occluded(self.camera.position, x)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// An OpenGL camera at `eye` looking down -Z (+Y up), 2:1 image, 90 degrees vertically.
    fn looking_down(eye: Vec3) -> Mat4 {
        let (f, aspect, near, far) = (1.0, 2.0, 0.1f32, 10.0f32);
        let proj = Mat4::from_cols(
            Vec4::new(f / aspect, 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, (far + near) / (near - far), -1.0),
            Vec4::new(0.0, 0.0, 2.0 * far * near / (near - far), 0.0),
        );
        proj * Mat4::from_translation(-eye)
    }

    fn input<'a>(
        pos: &'a [f32],
        nrm: &'a [f32],
        alb: &'a [f32],
        cov: &'a [bool],
        dep: &'a [f32],
        lit: &'a [f32],
    ) -> ViewInput<'a> {
        ViewInput {
            name: "test",
            gbuffer: GBuffer {
                width: 2,
                height: 1,
                position: pos,
                normal: nrm,
                albedo: alb,
                covered: cov,
            },
            depth: dep,
            direct: lit,
            diffuse_direct: lit,
            diffuse_indirect: Some(lit),
            indirect: None,
            specular: None,
            diffuse_color: None,
            camera: Camera {
                position: Vec3::new(0.0, 0.0, 2.0),
                world_to_clip: looking_down(Vec3::new(0.0, 0.0, 2.0)),
            },
        }
    }

    #[test]
    fn masks_non_finite_lighting_and_refuses_a_non_finite_gbuffer() {
        let pos = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0];
        let nrm = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
        let alb = [0.5; 6];
        let cov = [true, true];
        let dep = [2.0, 2.0];
        let lit = [0.1, 0.1, 0.1, f32::NAN, 0.1, 0.1];
        let v = View::new(&input(&pos, &nrm, &alb, &cov, &dep, &lit)).unwrap();
        assert_eq!(v.covered, vec![true, false]);
        assert_eq!(v.masked_pixels, 1);
        assert_eq!(v.covered_count(), 1);
        let held = v.without_indirect();
        assert!(held.diffuse_indirect.is_none() && held.indirect.is_none());

        let bad = [0.0, f32::INFINITY, 0.0, 1.0, 0.0, 0.0];
        let lit = [0.1; 6];
        let err = View::new(&input(&bad, &nrm, &alb, &cov, &dep, &lit)).unwrap_err();
        assert!(
            matches!(err, VplaceError::NonFinite { index: 0, .. }),
            "{err}"
        );
        // Uncovered pixels may hold anything.
        let cov = [false, true];
        assert!(View::new(&input(&bad, &nrm, &alb, &cov, &dep, &lit)).is_ok());
    }

    #[test]
    fn refuses_wrong_sizes_and_a_singular_camera() {
        let pos = [0.0; 6];
        let short = [0.0; 5];
        let cov = [true, true];
        let dep = [1.0, 1.0];
        let err = View::new(&input(&pos, &short, &pos, &cov, &dep, &pos)).unwrap_err();
        assert!(matches!(err, VplaceError::Shape { .. }), "{err}");
        let mut i = input(&pos, &pos, &pos, &cov, &dep, &pos);
        i.camera.world_to_clip = Mat4::ZERO;
        assert!(matches!(View::new(&i), Err(VplaceError::Invalid { .. })));
        i.camera.world_to_clip = Mat4::IDENTITY;
        i.gbuffer.width = 0;
        assert!(matches!(View::new(&i), Err(VplaceError::Empty { .. })));
    }

    #[test]
    fn sees_what_projects_onto_a_covered_pixel() {
        let pos = [0.0; 6];
        let cov = [true, false];
        let dep = [1.0, 1.0];
        let v = View::new(&input(&pos, &pos, &pos, &cov, &dep, &pos)).unwrap();
        let open = |_: Vec3, _: Vec3| false;
        // The left half of the image is pixel 0 (covered), the right half pixel 1.
        assert!(v.sees(Vec3::new(-0.1, 0.0, 0.0), open));
        assert!(!v.sees(Vec3::new(0.1, 0.0, 0.0), open));
        assert!(!v.sees(Vec3::new(-0.1, 0.0, 0.0), |_, _| true));
        assert!(!v.sees(Vec3::new(0.0, 0.0, 5.0), open)); // behind the camera
    }
}
