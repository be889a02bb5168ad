//! Procedural scenes, views and inputs shared by the tests, the benches and the examples.
//!
//! Compiled for the crate's own tests and with the `test-util` feature (the benches and the
//! examples get it through the crate's dev-dependency on itself). Everything here is
//! deterministic; the fixtures are fixed data, so a failed build of one is a bug in this module
//! and panics.

use glam::{Mat4, Vec2, Vec3, Vec4};
use std::f32::consts::PI;

use crate::fit::features::{FeatureInput, StrongestLight, FEATURE_COUNT};
use crate::rng::Rng;
use crate::scene::texture::{Texture, TextureRef};
use crate::scene::{Light, Material, Scene, SceneInput};
use crate::shade::shading::irradiance_per_flux;
use crate::view::{Camera, GBuffer, View, ViewInput};
use crate::vpl::{Profile, Vpl};

/// An open box `[-1, 1]^2 x [0, 2]` (floor, four walls, ceiling) with inward-facing
/// triangles, albedo 0.5, and `lights`.
#[must_use]
pub fn closed_box(lights: Vec<Light>) -> Scene {
    box_with(lights, &[])
}

/// [`closed_box`]'s geometry (albedo 0.5) around a closed emissive cube (albedo 0.8, radiance
/// 2) whose normals face out, as Blender's do: the scene, the cube's centre and half size.
#[must_use]
pub fn emissive_cube_in_box() -> (Scene, Vec3, f32) {
    let (mut v, mut t) = box_geometry(&[]);
    let (c, h) = (Vec3::new(0.1, -0.2, 1.0), 0.15);
    let p = |x: f32, y: f32, z: f32| c + Vec3::new(x, y, z) * h;
    let faces = [
        [
            p(-1., -1., 1.),
            p(1., -1., 1.),
            p(1., 1., 1.),
            p(-1., 1., 1.),
        ],
        [
            p(-1., -1., -1.),
            p(-1., 1., -1.),
            p(1., 1., -1.),
            p(1., -1., -1.),
        ],
        [
            p(1., -1., -1.),
            p(1., 1., -1.),
            p(1., 1., 1.),
            p(1., -1., 1.),
        ],
        [
            p(-1., -1., -1.),
            p(-1., -1., 1.),
            p(-1., 1., 1.),
            p(-1., 1., -1.),
        ],
        [
            p(-1., 1., -1.),
            p(-1., 1., 1.),
            p(1., 1., 1.),
            p(1., 1., -1.),
        ],
        [
            p(-1., -1., -1.),
            p(1., -1., -1.),
            p(1., -1., 1.),
            p(-1., -1., 1.),
        ],
    ];
    let mut ids = vec![0; t.len()];
    for [a, b, q, d] in faces {
        let base = v.len() as u32;
        assert!(
            (b - a).cross(q - a).dot(a - c) > 0.0,
            "the cube's normals face out"
        );
        v.extend([a, b, q, d]);
        t.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        ids.extend([1, 1]);
    }
    let lamp = Material::diffuse(Vec3::splat(0.8)).with_emission(Vec3::splat(2.0));
    let scene = Scene::new(SceneInput {
        vertices: &v,
        triangles: &t,
        material_ids: &ids,
        materials: &[Material::diffuse(Vec3::splat(0.5)), lamp],
        ..Default::default()
    })
    .expect("the emissive cube in the box is a valid scene");
    (scene, c, h)
}

/// A horizontal quad over the middle of the floor of [`closed_box`], 0.5 above it.
pub const BLOCKER: [Vec3; 4] = [
    Vec3::new(-0.4, -0.3, 0.5),
    Vec3::new(0.3, -0.3, 0.5),
    Vec3::new(0.3, 0.4, 0.5),
    Vec3::new(-0.4, 0.4, 0.5),
];

/// Panics if a VPL lies inside the cube of centre `centre` and half size `half`
/// ([`emissive_cube_in_box`]).
pub fn assert_none_inside(vpls: &[Vpl], centre: Vec3, half: f32) {
    for vpl in vpls {
        let d = (vpl.position - centre).abs().max_element();
        assert!(
            d > half * 0.999,
            "a VPL inside the emitter: {:?}",
            vpl.position
        );
    }
}

/// [`closed_box`]'s geometry with one `material` on every face, and `lights`.
#[must_use]
pub fn box_of(material: Material, lights: Vec<Light>) -> Scene {
    let (v, t) = box_geometry(&[]);
    Scene::new(SceneInput {
        vertices: &v,
        triangles: &t,
        material_ids: &vec![0; t.len()],
        materials: &[material],
        lights,
        ..Default::default()
    })
    .expect("the test box is a valid scene")
}

/// [`closed_box`] with extra quads (corners in order) inside it, e.g. occluders.
#[must_use]
pub fn box_with(lights: Vec<Light>, extra: &[[Vec3; 4]]) -> Scene {
    let (v, t) = box_geometry(extra);
    let ids = vec![0; t.len()];
    Scene::build(&v, &t, &ids, &[Vec3::splat(0.5)], lights).expect("the test box is a valid scene")
}

/// The vertices and triangles of [`box_with`]: two triangles per quad, `[a, b, c]` and
/// `[a, c, d]`, the box's six quads first (12 triangles), then `extra`'s.
#[must_use]
pub fn box_geometry(extra: &[[Vec3; 4]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut v = Vec::new();
    let mut t = Vec::new();
    let mut quad = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| {
        let base = v.len() as u32;
        v.extend([a, b, c, d]);
        t.push([base, base + 1, base + 2]);
        t.push([base, base + 2, base + 3]);
    };
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    quad(
        p(-1., -1., 0.),
        p(1., -1., 0.),
        p(1., 1., 0.),
        p(-1., 1., 0.),
    ); // floor
    quad(
        p(-1., -1., 2.),
        p(-1., 1., 2.),
        p(1., 1., 2.),
        p(1., -1., 2.),
    ); // ceiling
    quad(
        p(-1., -1., 0.),
        p(-1., 1., 0.),
        p(-1., 1., 2.),
        p(-1., -1., 2.),
    ); // x = -1
    quad(p(1., -1., 0.), p(1., -1., 2.), p(1., 1., 2.), p(1., 1., 0.)); // x = +1
    quad(p(-1., 1., 0.), p(1., 1., 0.), p(1., 1., 2.), p(-1., 1., 2.)); // y = +1
    quad(
        p(-1., -1., 0.),
        p(-1., -1., 2.),
        p(1., -1., 2.),
        p(1., -1., 0.),
    ); // y = -1
    for &[a, b, c, d] in extra {
        quad(a, b, c, d);
    }
    (v, t)
}

/// The arrays of a G-buffer, owned; [`GBufferArrays::gbuffer`] borrows them.
#[derive(Debug, Clone, PartialEq)]
pub struct GBufferArrays {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// World position per pixel (`H x W x 3`).
    pub position: Vec<f32>,
    /// Shading normal per pixel (`H x W x 3`).
    pub normal: Vec<f32>,
    /// Diffuse albedo per pixel (`H x W x 3`).
    pub albedo: Vec<f32>,
    /// Coverage per pixel (`H x W`).
    pub covered: Vec<bool>,
}

impl GBufferArrays {
    /// The G-buffer view of the arrays.
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
}

/// A `w x w` G-buffer of the floor of [`closed_box`]: pixel centres on a regular grid over
/// `[-1, 1]^2` (row 0 at `y = 1`), `z = 0`, normal `+Z`, albedo 0.5, every pixel covered.
#[must_use]
pub fn floor_gbuffer(w: usize) -> GBufferArrays {
    let mut position = Vec::new();
    for y in 0..w {
        for x in 0..w {
            let fx = (x as f32 + 0.5) / w as f32 * 2.0 - 1.0;
            let fy = 1.0 - (y as f32 + 0.5) / w as f32 * 2.0;
            position.extend([fx, fy, 0.0]);
        }
    }
    GBufferArrays {
        width: w,
        height: w,
        position,
        normal: [0.0, 0.0, 1.0].repeat(w * w),
        albedo: [0.5, 0.5, 0.5].repeat(w * w),
        covered: vec![true; w * w],
    }
}

/// Arrays of a `w x w` view of the test box's floor from `(0, 0, 1.9)` straight down,
/// with DiffDir from a point light at `light` of power `power` (no shadows: the floor
/// sees it entirely).
#[derive(Debug, Clone, PartialEq)]
pub struct FloorView {
    /// `w x w` pixels: positions on the floor `z = 0`, normal `+Z`, albedo red
    /// `(0.8, 0.2, 0.2)` where `x < 0` and grey 0.5 elsewhere, every pixel covered.
    pub gbuffer: GBufferArrays,
    /// Cycles' DiffDir of the point light: irradiance / pi (`w x w x 3`).
    pub diffuse_direct: Vec<f32>,
    /// Camera position, `(0, 0, 1.9)`.
    pub camera: Vec3,
    /// World to clip matrix of the camera (OpenGL conventions, square image).
    pub world_to_clip: Mat4,
}

impl FloorView {
    /// The view, `w x w` pixels, lit by a point light at `light` of `power` watts (grey).
    #[must_use]
    pub fn new(w: usize, light: Vec3, power: f32) -> Self {
        let camera = Vec3::new(0.0, 0.0, 1.9);
        let fov = 2.0 * (1.0f32 / 1.9).atan();
        // OpenGL perspective (aspect 1, near 0.1, far 10) and a view looking down -Z, up +Y.
        let (f, near, far) = (1.0 / (0.5 * fov).tan(), 0.1f32, 10.0f32);
        let proj = Mat4::from_cols(
            Vec4::new(f, 0.0, 0.0, 0.0),
            Vec4::new(0.0, f, 0.0, 0.0),
            Vec4::new(0.0, 0.0, (far + near) / (near - far), -1.0),
            Vec4::new(0.0, 0.0, 2.0 * far * near / (near - far), 0.0),
        );
        let view = Mat4::from_translation(-camera);
        let world_to_clip = proj * view;
        let inv = world_to_clip.inverse();
        let mut s = Self {
            gbuffer: GBufferArrays {
                width: w,
                height: w,
                position: Vec::new(),
                normal: [0.0, 0.0, 1.0].repeat(w * w),
                albedo: Vec::new(),
                covered: vec![true; w * w],
            },
            diffuse_direct: Vec::new(),
            camera,
            world_to_clip,
        };
        for y in 0..w {
            for x in 0..w {
                let ndc = Vec3::new(
                    (x as f32 + 0.5) / w as f32 * 2.0 - 1.0,
                    1.0 - (y as f32 + 0.5) / w as f32 * 2.0,
                    0.0,
                );
                let d = (inv.project_point3(ndc) - camera).normalize();
                let p = camera + d * (camera.z / -d.z);
                s.gbuffer.position.extend(p.to_array());
                // Red on the left half, grey elsewhere.
                let a = if p.x < 0.0 {
                    [0.8, 0.2, 0.2]
                } else {
                    [0.5, 0.5, 0.5]
                };
                s.gbuffer.albedo.extend(a);
                let l = light - p;
                let irr = power / (4.0 * PI) * l.z / l.length().powi(3);
                s.diffuse_direct.extend([irr / PI; 3]);
            }
        }
        s
    }

    /// The view without an indirect image: direct light `DiffDir * albedo`, depth 1.9.
    #[must_use]
    pub fn view(&self) -> View {
        self.view_with(None)
    }

    /// The view with the indirect image `indirect` (`w x w x 3`), or without one.
    #[must_use]
    pub fn view_with(&self, indirect: Option<&[f32]>) -> View {
        self.view_of(&self.gbuffer.albedo, indirect, None, None)
    }

    /// The view with `albedo` in place of the G-buffer's (the receivers' reflectance), the
    /// indirect image `indirect`, the Glossy Color `specular` and the Diffuse Color
    /// `diffuse_color`, each `w x w x 3` or none. The direct image is the G-buffer's albedo
    /// times `DiffDir`.
    #[must_use]
    pub fn view_of(
        &self,
        albedo: &[f32],
        indirect: Option<&[f32]>,
        specular: Option<&[f32]>,
        diffuse_color: Option<&[f32]>,
    ) -> View {
        let g = &self.gbuffer;
        let direct: Vec<f32> = self
            .diffuse_direct
            .iter()
            .zip(&g.albedo)
            .map(|(d, a)| d * a)
            .collect();
        let depth = vec![self.camera.z; g.width * g.height];
        View::new(&ViewInput {
            name: "floor",
            gbuffer: GBuffer {
                albedo,
                ..g.gbuffer()
            },
            depth: &depth,
            direct: &direct,
            diffuse_direct: &self.diffuse_direct,
            diffuse_indirect: None,
            indirect,
            specular,
            diffuse_color,
            camera: Camera {
                position: self.camera,
                world_to_clip: self.world_to_clip,
            },
        })
        .expect("the floor view is a valid view")
    }
}

/// The render passes the feature extraction reads, owned; [`Passes::input`] borrows them.
#[derive(Debug, Clone, PartialEq)]
pub struct Passes {
    /// Position, normal, albedo and coverage.
    pub gbuffer: GBufferArrays,
    /// Depth (`H x W`), `1e10` on the background.
    pub depth: Vec<f32>,
    /// Direct light (`H x W x 3`).
    pub direct: Vec<f32>,
    /// Indirect light (`H x W x 3`), the label's source.
    pub indirect: Vec<f32>,
    /// The strongest light.
    pub light: StrongestLight,
}

impl Passes {
    /// Nothing covered: zero position, normal, light passes, depth `1e10`, grey `albedo`, a
    /// point light at `light`.
    fn background(w: usize, h: usize, albedo: f32, light: Vec3) -> Self {
        let n = w * h;
        Self {
            gbuffer: GBufferArrays {
                width: w,
                height: h,
                position: vec![0.0; 3 * n],
                normal: vec![0.0; 3 * n],
                albedo: vec![albedo; 3 * n],
                covered: vec![false; n],
            },
            depth: vec![1e10; n],
            direct: vec![0.0; 3 * n],
            indirect: vec![0.0; 3 * n],
            light: StrongestLight::Position(light),
        }
    }

    /// A flat grid: pixel `(x, y)` at world `(x, y, 0)`, normal `+Z`, albedo 0.5, depth
    /// `2 + y`, direct 0.25, indirect `0.01 x`; covered where `x < w / 2` or `y < h / 2`; a
    /// point light at `(0, 0, 10)`. Values simple enough to check cell means by hand.
    #[must_use]
    pub fn grid(w: usize, h: usize) -> Self {
        let mut b = Self::background(w, h, 0.5, Vec3::new(0.0, 0.0, 10.0));
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                b.gbuffer.covered[i] = x < w / 2 || y < h / 2;
                b.gbuffer.position[3 * i] = x as f32;
                b.gbuffer.position[3 * i + 1] = y as f32;
                b.gbuffer.normal[3 * i + 2] = 1.0;
                b.depth[i] = 2.0 + y as f32;
                b.direct[3 * i..3 * i + 3].fill(0.25);
                b.indirect[3 * i..3 * i + 3].fill(0.01 * x as f32);
            }
        }
        b
    }

    /// A synthetic room view: a floor (lower 40 %), a back wall, a checker albedo of 64-pixel
    /// squares, 8 % background (top right), direct and indirect light with a little noise from a fixed seed;
    /// a point light at `(0, 1, 2.5)`. The features benchmark's input.
    #[must_use]
    pub fn room(w: usize, h: usize) -> Self {
        let mut rng = Rng::new(42, 1);
        let mut p = Self::background(w, h, 0.0, Vec3::new(0.0, 1.0, 2.5));
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                if u > 0.92 && v < 0.5 {
                    continue; // background
                }
                p.gbuffer.covered[i] = true;
                let floor = v > 0.6;
                let nrm = if floor {
                    Vec3::Z
                } else {
                    Vec3::new(0.0, -1.0, 0.0)
                };
                let pos = if floor {
                    Vec3::new(u * 4.0 - 2.0, 4.0 * (v - 0.6), 0.0)
                } else {
                    Vec3::new(u * 4.0 - 2.0, 3.0, 3.0 * (1.0 - v))
                };
                let alb = if (x / 64 + y / 64) % 2 == 0 { 0.8 } else { 0.3 };
                let d = 0.5 * alb * nrm.z.max(0.2) + 0.05 * rng.next_f32();
                let g = d + 0.1 * alb * (1.0 - v) + 0.02 * rng.next_f32();
                p.gbuffer.position[3 * i..3 * i + 3].copy_from_slice(&pos.to_array());
                p.gbuffer.normal[3 * i..3 * i + 3].copy_from_slice(&nrm.to_array());
                p.gbuffer.albedo[3 * i..3 * i + 3].fill(alb);
                p.depth[i] = 1.0 + 5.0 * (1.0 - v) + u;
                p.direct[3 * i..3 * i + 3].fill(d);
                p.indirect[3 * i..3 * i + 3].fill(g - d);
            }
        }
        p
    }

    /// The feature extraction's view of the passes (indirect given, no specular pass).
    #[must_use]
    pub fn input(&self) -> FeatureInput<'_> {
        FeatureInput {
            gbuffer: self.gbuffer.gbuffer(),
            depth: &self.depth,
            direct: &self.direct,
            indirect: Some(&self.indirect),
            specular: None,
            light: Some(self.light),
        }
    }
}

/// A random `n x FEATURE_COUNT` design (row-major, values in `[0, 1)`) and a label linear in
/// it plus noise in `[0, 0.1)`, from a fixed seed: the regression benchmark's input.
#[must_use]
pub fn linear_design(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Rng::new(7, 2);
    let x: Vec<f64> = (0..n * FEATURE_COUNT)
        .map(|_| f64::from(rng.next_f32()))
        .collect();
    let y = x
        .chunks_exact(FEATURE_COUNT)
        .map(|r| {
            r.iter()
                .enumerate()
                .map(|(j, v)| v * (j % 4) as f64)
                .sum::<f64>()
                + 0.1 * f64::from(rng.next_f32())
        })
        .collect();
    (x, y)
}

/// The shading of one (receiver, VPL) pair written as a plain scalar formula: the reference
/// that the evaluator, the refit's matrix and the view efficiency are tested against.
///
/// The receiver is at `position` with the unit (or zero) normal `n`. Returns
/// `Phi * K * V` (before the BRDF), `K` the kernel [`irradiance_per_flux`] of the VPL's light
/// with near-field radius `radius`, `V` one shadow ray from the receiver pushed off its surface
/// by [`Scene::ray_epsilon`] to the VPL, traced against every triangle
/// ([`Scene::occluded_brute_force`]) when `scene` is given; without a scene `V = 1`. `None`
/// when the pair gives nothing without a ray (a zero kernel or product). `Some` means exactly
/// one ray (the value is zero when it was blocked).
#[must_use]
pub fn reference_incident(
    scene: Option<&Scene>,
    position: Vec3,
    n: Vec3,
    vpl: &Vpl,
    profile: Profile,
    radius: f32,
) -> Option<Vec3> {
    let e = vpl.position - position;
    let k = irradiance_per_flux(
        profile,
        e.length_squared(),
        n.dot(e),
        -vpl.normal.dot(e),
        n.dot(vpl.normal),
        radius * radius,
    );
    let c = vpl.flux * k;
    if k <= 0.0 || c == Vec3::ZERO {
        return None;
    }
    let blocked = scene.is_some_and(|s| {
        let origin = position + n * s.ray_epsilon();
        s.occluded_brute_force(origin, vpl.position)
    });
    Some(if blocked { Vec3::ZERO } else { c })
}

/// The evaluator's image by brute force: a plain loop over the covered pixels and the VPLs,
/// each pixel `albedo / pi` times the sum of [`reference_incident`] (the G-buffer normal
/// normalized, zero staying zero; shadow rays against every triangle) in VPL order; and the
/// number of shadow rays.
#[must_use]
pub fn reference_image(
    scene: &Scene,
    g: &GBuffer<'_>,
    vpls: &[Vpl],
    profile: Profile,
    radius: f32,
) -> (Vec<f32>, u64) {
    let vec3 = |a: &[f32], p: usize| Vec3::from_slice(&a[3 * p..3 * p + 3]);
    let mut image = vec![0.0f32; 3 * g.width * g.height];
    let mut rays = 0;
    let radii = crate::vpl::near_field_radii(vpls, radius);
    for p in (0..g.width * g.height).filter(|&p| g.covered[p]) {
        let (position, normal) = (vec3(g.position, p), vec3(g.normal, p).normalize_or_zero());
        let mut sum = Vec3::ZERO;
        for (v, &r) in vpls.iter().zip(&radii) {
            if let Some(c) = reference_incident(Some(scene), position, normal, v, profile, r) {
                rays += 1;
                sum += c;
            }
        }
        let pixel = vec3(g.albedo, p) / PI * sum;
        image[3 * p..3 * p + 3].copy_from_slice(&pixel.to_array());
    }
    (image, rays)
}

/// A random point 0.01 inside the ceiling or the walls `x = 1`, `y = -1` of [`closed_box`]
/// (one of the three with equal odds, uniform over it) and the normal there facing into the
/// box: a VPL's position and normal.
#[must_use]
pub fn inward_point(rng: &mut Rng) -> (Vec3, Vec3) {
    let mut r = || rng.next_f32();
    let (a, b, c) = (2.0 * r() - 1.0, 2.0 * r() - 1.0, r());
    match (3.0 * c) as u32 {
        0 => (Vec3::new(a, b, 1.99), Vec3::NEG_Z),
        1 => (Vec3::new(0.99, a, 1.0 + b), Vec3::NEG_X),
        _ => (Vec3::new(a, -0.99, 1.0 + b), Vec3::Y),
    }
}

/// Degenerate shading cases in one scene: the test box with [`BLOCKER`], a `12 x 12`
/// G-buffer and VPLs. The G-buffer holds floor pixels (rows 0 to 7) and pixels on the wall
/// `x = -1` (rows 8 to 11), coloured albedo; among them a zero normal, a short (box-filtered)
/// normal, a tilted unnormalized one, and two uncovered pixels. The VPLs: 40 random ones on
/// the ceiling and the walls facing into the box (many of them shadowed by the blocker for the
/// floor pixels below it), one exactly at a floor pixel's position (`r = 0` for that pixel), one
/// 1 mm above another floor pixel facing down (inside any near-field radius), one below the
/// floor (behind the floor pixels; the wall pixels see it through the floor, occluded), one on
/// the ceiling facing up (the receivers are behind it: dark for the cosine profile, not for
/// `omni`), one without flux, and one straight above the blocker.
#[must_use]
pub fn shading_cases() -> (Scene, GBufferArrays, Vec<Vpl>) {
    let scene = box_with(vec![], &[BLOCKER]);
    let (w, h) = (12, 12);
    let mut g = GBufferArrays {
        width: w,
        height: h,
        position: Vec::new(),
        normal: Vec::new(),
        albedo: Vec::new(),
        covered: vec![true; w * h],
    };
    for y in 0..h {
        for x in 0..w {
            let u = (x as f32 + 0.5) / w as f32 * 1.9 - 0.95;
            if y < 8 {
                let v = 0.95 - (y as f32 + 0.5) / 8.0 * 1.9;
                g.position.extend([u, v, 0.0]);
                g.normal.extend([0.0, 0.0, 1.0]);
            } else {
                let z = 0.1 + (y - 8) as f32 / 4.0 * 1.8;
                g.position.extend([-1.0, u, z]);
                g.normal.extend([1.0, 0.0, 0.0]);
            }
            g.albedo
                .extend([0.2 + 0.05 * x as f32, 0.5, 0.9 - 0.06 * y as f32]);
        }
    }
    g.normal[3 * 14..3 * 14 + 3].fill(0.0);
    g.normal[3 * 27..3 * 27 + 3].copy_from_slice(&[0.0, 0.0, 0.6]);
    g.normal[3 * 40..3 * 40 + 3].copy_from_slice(&[0.3, -0.2, 0.8]);
    g.covered[5] = false;
    g.covered[100] = false;
    let at = |p: usize| Vec3::from_slice(&g.position[3 * p..3 * p + 3]);
    let mut rng = Rng::new(15, 0);
    let mut vpls: Vec<Vpl> = (0..40)
        .map(|_| {
            let (position, normal) = inward_point(&mut rng);
            Vpl {
                position,
                normal,
                flux: Vec3::new(0.5 + rng.next_f32(), 0.7, 1.5 * rng.next_f32()),
            }
        })
        .collect();
    let vpl = |position: Vec3, normal: Vec3, flux: Vec3| Vpl {
        position,
        normal,
        flux,
    };
    vpls.extend([
        vpl(at(30), Vec3::Z, Vec3::new(1.0, 0.5, 0.25)),
        vpl(at(50) + Vec3::new(0.0, 0.0, 1e-3), Vec3::NEG_Z, Vec3::ONE),
        vpl(Vec3::new(0.1, 0.2, -0.3), Vec3::Z, Vec3::splat(2.0)),
        vpl(
            Vec3::new(0.2, -0.3, 1.99),
            Vec3::Z,
            Vec3::new(0.3, 0.6, 0.9),
        ),
        vpl(Vec3::new(-0.5, 0.5, 1.99), Vec3::NEG_Z, Vec3::ZERO),
        vpl(Vec3::new(0.0, 0.0, 1.99), Vec3::NEG_Z, Vec3::splat(1.5)),
    ]);
    (scene, g, vpls)
}

/// [`box_geometry`] with a card (the unit square at height 1, material 1 `card`, UVs over
/// it) and a 2 x 1 texture: red then green, alpha 0 then 1.
#[must_use]
pub fn card_scene(card: Material, lights: Vec<Light>) -> Scene {
    let corners = [
        Vec3::new(-0.5, -0.5, 1.0),
        Vec3::new(0.5, -0.5, 1.0),
        Vec3::new(0.5, 0.5, 1.0),
        Vec3::new(-0.5, 0.5, 1.0),
    ];
    let (v, t) = box_geometry(&[corners]);
    let mut ids = vec![0u32; t.len()];
    let mut uvs = vec![[Vec2::ZERO; 3]; t.len()];
    let (a, b, c, d) = (Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y);
    ids[12..].fill(1);
    uvs[12] = [a, b, c];
    uvs[13] = [a, c, d];
    let texture = Texture::new("t", 2, 1, 4, &[1., 0., 0., 0., 0., 1., 0., 1.]).unwrap();
    Scene::new(SceneInput {
        vertices: &v,
        triangles: &t,
        material_ids: &ids,
        materials: &[Material::diffuse(Vec3::splat(0.5)), card],
        lights,
        uvs: Some(&uvs),
        textures: vec![texture],
    })
    .unwrap()
}

/// A texture reference with Extend wrapping.
#[must_use]
pub fn extend(texture: u32) -> TextureRef {
    TextureRef {
        wrap: crate::scene::texture::Wrap::Extend,
        ..TextureRef::new(texture)
    }
}
