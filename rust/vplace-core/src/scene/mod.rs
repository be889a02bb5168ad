//! The scene model: world-space triangles with per-triangle albedo, the scene's lights, and an
//! obvhs compressed-wide BVH for closest-hit and shadow rays.
//!
//! **Materials.** A [`Material`] is diffuse: its albedo is a constant, or, with a base-colour
//! [`TextureRef`], `albedo + texture_tint * rgb(texture at the hit's UV)` (clamped to
//! `[0, 1]`; [`Scene::albedo_at`]). UVs come per triangle corner ([`SceneInput::uvs`]) and are
//! interpolated with the hit's barycentric coordinates ([`Hit::barycentrics`]). A material with
//! an [`AlphaTest`] is cut where its alpha is below the cutoff: closest-hit queries
//! ([`Scene::closest_hit`], so light paths and the RSM rays) and shadow rays
//! ([`Scene::occluded`] and the evaluator's batched rays) pass through it there, an any-hit
//! filter in the traversal. A scene without any texture or alpha test keeps no per-hit material
//! data at all and traverses exactly as before.

pub mod emitters;
mod light;
mod material;
pub mod region;
mod shadow_bvh;
pub mod texture;

use glam::{UVec2, Vec2, Vec3, Vec3A};
use obvhs::{
    cwbvh::{
        builder::build_cwbvh_from_tris,
        node::{extract_byte64, CwBvhNode},
        CwBvh, Traversal,
    },
    ray::{Ray, RayHit},
    triangle::Triangle,
    BvhBuildParams,
};
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Duration;

use crate::error::{check_finite, Result, VplaceError};
use crate::scene::emitters::{EmissiveMesh, EnvironmentMap};
use crate::scene::texture::{AlphaTest, Texture, TextureRef};

/// The default near-field radius `radius` as a fraction of the scene's working scale
/// ([`Scene::near_field_radius`]; the shading kernel, `shade::shading`, bounds
/// the `1 / r^2` of a cosine VPL with the disk of this radius): VPL spacing grows with the scene, so the radius
/// within which a VPL's `1 / r^2` is bounded does too.
pub const NEAR_FIELD_FRACTION: f32 = 0.01;
/// obvhs's `medium_build` with the full PLOC search distance from the first pass
/// (`search_depth_threshold: 0`; the preset uses distance 1 for the first 3 passes). On rooms of
/// large coplanar triangles (walls subdivided in grids: the Cornell box, the layout benchmark)
/// the preset pairs triangles across walls early and its boxes span the empty room: a shadow ray
/// then visited 27 to 100 nodes; with the full search it visits 1.4 to 1.7, 15 to 60 times
/// faster. On Sponza (262k triangles) traversal and build time are the same within noise.
const BVH_BUILD: BvhBuildParams = BvhBuildParams {
    search_depth_threshold: 0,
    ..BvhBuildParams::medium_build()
};

pub use light::{Light, LightKind};
pub use material::{Gloss, Material};
use shadow_bvh::ShadowBvh;

/// No triangle named by a [`Scene::occluded_ray_hinted`] hint.
pub(crate) const NO_HINT: u32 = u32::MAX;

/// A surface hit: distance along the ray and the original triangle index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Index into the triangles passed to [`Scene::build`].
    pub triangle: u32,
    /// Barycentric coordinates `(b1, b2)` of the hit: the weights of the triangle's second and
    /// third vertex (the first has `1 - b1 - b2`), each in `[0, 1]` up to rounding.
    pub barycentrics: Vec2,
}

/// Triangles, materials and lights with a BVH over the triangles.
///
/// Invariants: at least one triangle; every material id indexes `albedo`; every value finite;
/// albedo channels in `[0, 1]`.
pub struct Scene {
    /// Triangles in BVH leaf order (`bvh.primitive_indices` order), for cache-friendly traversal.
    bvh_triangles: Vec<Triangle>,
    /// Original triangle index of each entry of `bvh_triangles`.
    bvh_ids: Vec<u32>,
    bvh: CwBvh,
    /// The BVH's nodes with their child planes converted to `f32` once, for shadow rays.
    shadow: ShadowBvh,
    /// Unit geometric normal per original triangle (zero for degenerate triangles).
    normals: Vec<Vec3>,
    /// Albedo per original triangle.
    triangle_albedo: Vec<Vec3>,
    /// Glossy layer per original triangle: reflectance (of the texture's mean colour) and
    /// roughness ([`Scene::gloss_at`]).
    triangle_gloss: Vec<Option<(Vec3, f32)>>,
    /// The glossy layer of every material, for textured hits.
    material_gloss: Vec<Option<Gloss>>,
    /// The scene's lights.
    pub lights: Vec<Light>,
    bounds_min: Vec3,
    bounds_max: Vec3,
    /// The working scale ([`Scene::scale`]).
    scale: f32,
    /// The box of the region the cameras see, where it sets the scale ([`Scene::region`]).
    region: Option<(Vec3, Vec3)>,
    /// Number of zero-area triangles (kept, never hit).
    pub degenerate_triangles: usize,
    /// The triangles whose material emits, sampled by power ([`crate::scene::emitters`]).
    emissive: EmissiveMesh,
    /// Textures, UVs and alpha tests; `None` when no material has a texture or an alpha test
    /// (then nothing per hit is looked up).
    surfaces: Option<Box<Surfaces>>,
    /// The reflections the renderer the scene is scored against follows
    /// ([`Scene::light_bounces`]).
    light_bounces: LightBounces,
}

/// The most surface hits a light path follows ([`LightBounces::ALL`]; Russian roulette ends
/// most paths long before it).
pub const MAX_BOUNCES: usize = 16;

/// The reflections a renderer follows along a path from the camera (Cycles' Light Paths > Max
/// Bounces): at most `diffuse` diffuse and `glossy` glossy reflections, `total` in all, before
/// the path's last surface, which is lit by a light directly (Cycles' Diffuse 0 shows direct
/// light only). A VPL at the `k`-th surface hit of a light path stands for the camera paths that
/// reflect diffusely at the surface they see and at the VPL, and at each of the hits between
/// the VPL and the first as the light path did there (the first hit is lit by the light
/// directly): such a VPL is within the limits when `k <= total` and, for `k >= 2`,
/// `2 + (diffuse reflections at hits 2..k-1) <= diffuse` and `(glossy ones there) <= glossy`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LightBounces {
    /// Diffuse reflections, `>= 1`.
    pub diffuse: usize,
    /// Glossy reflections.
    pub glossy: usize,
    /// Reflections in all, `>= 1`.
    pub total: usize,
}

impl LightBounces {
    /// Every bounce that carries light ([`MAX_BOUNCES`] of each kind).
    pub const ALL: Self = Self {
        diffuse: MAX_BOUNCES,
        glossy: MAX_BOUNCES,
        total: MAX_BOUNCES,
    };

    /// Whether a VPL at the `hit`-th surface hit (1 for the first) of a light path that went on
    /// diffusely `diffuse_between` times and glossily `glossy_between` times at hits
    /// `2..hit-1` is within the limits (see the type's docs).
    #[must_use]
    pub fn admit(&self, hit: usize, diffuse_between: usize, glossy_between: usize) -> bool {
        hit >= 1
            && hit <= self.total
            && (hit == 1 || (2 + diffuse_between <= self.diffuse && glossy_between <= self.glossy))
    }
}

/// What textured and alpha-tested materials need at a hit.
#[derive(PartialEq)]
struct Surfaces {
    textures: Vec<Texture>,
    materials: Vec<Material>,
    /// Material of each original triangle.
    triangle_material: Vec<u32>,
    /// UV of each corner of each original triangle (zero when the input had none and no
    /// material reads a texture).
    uvs: Vec<[Vec2; 3]>,
    /// Per triangle in BVH leaf order: the material's index when it is alpha-tested, else
    /// [`Surfaces::OPAQUE`]. Empty when no material is alpha-tested.
    bvh_alpha: Vec<u32>,
}

impl Surfaces {
    const OPAQUE: u32 = u32::MAX;

    /// The UV at barycentrics `b` of original triangle `t`.
    #[inline]
    fn uv(&self, t: u32, b: Vec2) -> Vec2 {
        let [a, p, q] = self.uvs[t as usize];
        a * (1.0 - b.x - b.y) + p * b.x + q * b.y
    }

    /// The textured glossy reflectance at `b` of triangle `t` (clamped to `[0, 1]`), `None`
    /// for a material without a texture.
    #[inline]
    fn gloss_at(&self, t: u32, b: Vec2, g: &Gloss) -> Option<Vec3> {
        let m = &self.materials[self.triangle_material[t as usize] as usize];
        let map = m.texture.as_ref()?;
        let rgb = map.sample(&self.textures, self.uv(t, b)).truncate();
        Some((g.constant + g.tint * rgb).clamp(Vec3::ZERO, Vec3::ONE))
    }

    /// The textured albedo at `b` of triangle `t`, `None` for a constant material.
    #[inline]
    fn albedo_at(&self, t: u32, b: Vec2) -> Option<Vec3> {
        let m = &self.materials[self.triangle_material[t as usize] as usize];
        let map = m.texture.as_ref()?;
        let rgb = map.sample(&self.textures, self.uv(t, b)).truncate();
        Some((m.albedo + m.texture_tint * rgb).clamp(Vec3::ZERO, Vec3::ONE))
    }
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("triangles", &self.normals.len())
            .field("lights", &self.lights.len())
            .field("bounds_min", &self.bounds_min)
            .field("bounds_max", &self.bounds_max)
            .finish()
    }
}

/// What a [`Scene`] is built from: indexed triangles, one material per triangle, lights.
///
/// `SceneInput { vertices, triangles, material_ids, materials, ..Default::default() }` leaves
/// out everything optional.
#[derive(Debug, Clone, Default)]
pub struct SceneInput<'a> {
    /// Vertex positions, world space.
    pub vertices: &'a [Vec3],
    /// Vertex indices of every triangle.
    pub triangles: &'a [[u32; 3]],
    /// Index into `materials` of every triangle.
    pub material_ids: &'a [u32],
    /// The materials.
    pub materials: &'a [Material],
    /// The lights.
    pub lights: Vec<Light>,
    /// UV of each corner of each triangle (same order as `triangles`); required when a
    /// material reads a texture.
    pub uvs: Option<&'a [[Vec2; 3]]>,
    /// The textures the materials refer to by index.
    pub textures: Vec<Texture>,
}

impl Scene {
    /// Builds a scene of diffuse materials: `material_ids[t]` indexes `albedo` for triangle `t`
    /// (see [`Scene::new`]).
    pub fn build(
        vertices: &[Vec3],
        triangles: &[[u32; 3]],
        material_ids: &[u32],
        albedo: &[Vec3],
        lights: Vec<Light>,
    ) -> Result<Self> {
        let materials: Vec<Material> = albedo.iter().map(|&a| Material::diffuse(a)).collect();
        Self::new(SceneInput {
            vertices,
            triangles,
            material_ids,
            materials: &materials,
            lights,
            ..Default::default()
        })
    }

    /// Builds a scene: checks the input, then builds the BVH.
    ///
    /// Errors: no triangles, or only zero-area ones; a material id or vertex index out of
    /// range; no materials; non-finite vertices; an albedo outside `[0, 1]`; a non-finite or
    /// negative emission; an invalid light; a texture index out of range, a negative or
    /// non-finite tint, a non-finite UV, UV transform or alpha test; UVs of the wrong length,
    /// or none while a material reads a texture.
    pub fn new(input: SceneInput<'_>) -> Result<Self> {
        check_input(&input)?;
        let SceneInput {
            vertices,
            triangles,
            material_ids,
            materials,
            lights,
            uvs,
            textures,
        } = input;
        let Geometry {
            tris,
            normals,
            triangle_albedo,
            triangle_gloss,
            degenerate,
            lo,
            hi,
        } = geometry(vertices, triangles, material_ids, materials, &textures)?;
        let emissive = EmissiveMesh::build(vertices, triangles, material_ids, materials)?;
        let bvh = build_cwbvh_from_tris(&tris, BVH_BUILD, &mut Duration::default());
        let shadow = ShadowBvh::new(&bvh);
        let bvh_ids = bvh.primitive_indices.clone();
        let bvh_triangles = bvh_ids.iter().map(|&i| tris[i as usize]).collect();
        let surfaces = Surfaces::new(materials, material_ids, uvs, textures, &bvh_ids);
        Ok(Self {
            bvh_triangles,
            bvh_ids,
            bvh,
            shadow,
            normals,
            triangle_albedo,
            triangle_gloss,
            material_gloss: materials.iter().map(|m| m.gloss).collect(),
            lights,
            bounds_min: lo,
            bounds_max: hi,
            scale: (hi - lo).length().max(1e-6),
            region: None,
            degenerate_triangles: degenerate,
            emissive,
            surfaces,
            light_bounces: LightBounces::ALL,
        })
    }

    /// The scene with the reflections the renderer it is scored against follows (see
    /// [`LightBounces`]; Cycles' Light Paths > Max Bounces). Light paths
    /// ([`crate::vpl::light_path_vpls`]) leave VPLs only within them, so a room that light
    /// reaches only after many reflections is not lit brighter than that renderer lights it.
    /// The default is [`LightBounces::ALL`].
    ///
    /// Errors: `diffuse` or `total` outside `1..=MAX_BOUNCES`, `glossy` above it.
    pub fn with_light_bounces(mut self, bounces: LightBounces) -> Result<Self> {
        for (what, value, low) in [
            ("diffuse bounces", bounces.diffuse, 1),
            ("glossy bounces", bounces.glossy, 0),
            ("total bounces", bounces.total, 1),
        ] {
            if !(low..=MAX_BOUNCES).contains(&value) {
                return Err(VplaceError::OutOfRange {
                    what: what.into(),
                    value: value.to_string(),
                    expected: format!("{low}..={MAX_BOUNCES}"),
                });
            }
        }
        self.light_bounces = bounces;
        Ok(self)
    }

    /// The reflections the renderer the scene is scored against follows
    /// ([`Scene::with_light_bounces`]; default [`LightBounces::ALL`]).
    #[must_use]
    pub fn light_bounces(&self) -> LightBounces {
        self.light_bounces
    }

    /// The emissive triangles of the scene (possibly none).
    #[must_use]
    pub fn emissive(&self) -> &EmissiveMesh {
        &self.emissive
    }

    /// True when something can emit light: a light, or an emissive triangle.
    #[must_use]
    pub fn has_emitters(&self) -> bool {
        !self.lights.is_empty() || !self.emissive.is_empty()
    }

    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.normals.len()
    }

    /// Axis-aligned bounds of the geometry, `(min, max)`.
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.bounds_min, self.bounds_max)
    }

    /// Length of the bounds' diagonal: the distance that takes a ray out of the scene.
    #[must_use]
    pub fn diagonal(&self) -> f32 {
        (self.bounds_max - self.bounds_min).length().max(1e-6)
    }

    /// The working scale, metres: the size of the region the cameras work in
    /// ([`Scene::with_eyes`], [`region`]), or the bounds' diagonal. VPL sizes and offsets and
    /// ray offsets are fractions of it.
    #[must_use]
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// The box `(min, max)` of the region the cameras see ([`Scene::with_eyes`]) where it sets
    /// the working scale (it is less than the bounds); else `None`.
    #[must_use]
    pub fn region(&self) -> Option<(Vec3, Vec3)> {
        self.region
    }

    /// The default near-field radius of the scene's VPLs: [`NEAR_FIELD_FRACTION`] of the
    /// working scale (VPL spacing grows with the scene; see `shade::shading::near_field`).
    #[must_use]
    pub fn near_field_radius(&self) -> f32 {
        NEAR_FIELD_FRACTION * self.scale
    }

    /// Ray offset used to leave a surface without hitting it again (a fraction of the working
    /// scale).
    #[must_use]
    pub fn ray_epsilon(&self) -> f32 {
        1e-4 * self.scale
    }

    /// True when every shadow ray is blocked in `other` exactly where it is here: the same
    /// triangles in the same BVH order, the same textured and alpha-tested surfaces, the same
    /// ray offset ([`Scene::ray_epsilon`]). The lights may differ. (A frame of an animation
    /// whose sun or lamp moves keeps its occluders; one whose objects move does not.)
    #[must_use]
    pub fn same_occluders(&self, other: &Scene) -> bool {
        let same_triangle =
            |a: &Triangle, b: &Triangle| a.v0 == b.v0 && a.v1 == b.v1 && a.v2 == b.v2;
        self.scale == other.scale
            && self.bvh_ids == other.bvh_ids
            && self.bvh_triangles.len() == other.bvh_triangles.len()
            && self
                .bvh_triangles
                .iter()
                .zip(&other.bvh_triangles)
                .all(|(a, b)| same_triangle(a, b))
            && self.surfaces == other.surfaces
    }

    /// Unit geometric normal of triangle `t` (zero if degenerate).
    #[must_use]
    pub fn normal(&self, t: u32) -> Vec3 {
        self.normals[t as usize]
    }

    /// Albedo of triangle `t`: its material's constant albedo, or for a textured material the
    /// albedo of the texture's mean colour (see [`Scene::albedo_at`] for the albedo at a point).
    #[must_use]
    pub fn albedo(&self, t: u32) -> Vec3 {
        self.triangle_albedo[t as usize]
    }

    /// Albedo of triangle `t` at barycentrics `b` (see [`Hit::barycentrics`]): the material's
    /// texture at the interpolated UV (`albedo + tint * rgb`, clamped to `[0, 1]`), or its
    /// constant albedo. The albedo the light paths, the RSM and the layout's off-screen emitters
    /// reflect with.
    #[inline]
    #[must_use]
    pub fn albedo_at(&self, t: u32, b: Vec2) -> Vec3 {
        if let Some(s) = &self.surfaces {
            if let Some(a) = s.albedo_at(t, b) {
                return a;
            }
        }
        self.triangle_albedo[t as usize]
    }

    /// The glossy layer of triangle `t` at barycentrics `b` ([`Material::gloss`]): its
    /// reflectance there (the texture at the interpolated UV for a textured material, clamped
    /// to `[0, 1]`) and its roughness; `None` without one.
    #[inline]
    #[must_use]
    pub fn gloss_at(&self, t: u32, b: Vec2) -> Option<(Vec3, f32)> {
        let (mean, roughness) = self.triangle_gloss[t as usize]?;
        if let Some(s) = &self.surfaces {
            let m = s.triangle_material[t as usize] as usize;
            if let Some(g) = &self.material_gloss[m] {
                if let Some(r) = s.gloss_at(t, b, g) {
                    return Some((r, roughness));
                }
            }
        }
        Some((mean, roughness))
    }

    /// The UV at barycentrics `b` of triangle `t`; `None` when the scene has no UVs (no
    /// material reads a texture).
    #[must_use]
    pub fn uv_at(&self, t: u32, b: Vec2) -> Option<Vec2> {
        self.surfaces
            .as_ref()
            .filter(|s| !s.uvs.is_empty())
            .map(|s| s.uv(t, b))
    }

    /// Number of textures.
    #[must_use]
    pub fn texture_count(&self) -> usize {
        self.surfaces.as_ref().map_or(0, |s| s.textures.len())
    }

    /// True when some material is alpha-tested (rays then run the any-hit filter).
    #[must_use]
    pub fn has_alpha_tests(&self) -> bool {
        self.surfaces
            .as_ref()
            .is_some_and(|s| !s.bvh_alpha.is_empty())
    }

    /// True when `ray`, meeting BVH-order triangle `i` at distance `ray.tmax`, passes through
    /// it: its material is alpha-tested and cut at the hit. `s` is `self.surfaces`.
    #[inline]
    fn cut(&self, s: &Surfaces, i: usize, ray: &Ray) -> bool {
        let m = s.bvh_alpha[i];
        if m == Surfaces::OPAQUE {
            return false;
        }
        let Some(test) = &s.materials[m as usize].alpha_test else {
            return false;
        };
        let b = barycentrics(&self.bvh_triangles[i], ray);
        test.cut(&s.textures, s.uv(self.bvh_ids[i], b))
    }

    /// The alpha-test data when some material is alpha-tested.
    #[inline(always)]
    fn alpha_surfaces(&self) -> Option<&Surfaces> {
        self.surfaces.as_deref().filter(|s| !s.bvh_alpha.is_empty())
    }

    /// Closest hit along `origin + t * dir` for `t` in `(tmin, tmax)`; `dir` must be unit length.
    /// Alpha-tested surfaces are skipped where they are cut.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let ray = Ray::new(
            Vec3A::from(origin),
            Vec3A::from(positive_zeros(dir)),
            tmin,
            tmax,
        );
        let mut hit = RayHit::none();
        let found = match self.alpha_surfaces() {
            None => self
                .bvh
                .ray_traverse(ray, &mut hit, |r, id| self.bvh_triangles[id].intersect(r)),
            Some(s) => self.bvh.ray_traverse(ray, &mut hit, |r, id| {
                let t = self.bvh_triangles[id].intersect(r);
                if t < r.tmax && self.cut(s, id, &Ray { tmax: t, ..*r }) {
                    f32::INFINITY
                } else {
                    t
                }
            }),
        };
        found.then(|| {
            let i = hit.primitive_id as usize;
            let at = Ray { tmax: hit.t, ..ray };
            Hit {
                t: hit.t,
                triangle: self.bvh_ids[i],
                barycentrics: barycentrics(&self.bvh_triangles[i], &at),
            }
        })
    }

    /// [`Scene::closest_hit`] of each ray `origins[i] + t * directions[i]` for `t` in
    /// `(tmin, inf)`, the rays traced in parallel, the answers in their order. The directions
    /// are normalized here; a zero direction (or one that does not normalize) hits nothing.
    ///
    /// # Panics
    /// When `origins` and `directions` differ in length.
    #[must_use]
    pub fn closest_hits(
        &self,
        origins: &[Vec3],
        directions: &[Vec3],
        tmin: f32,
    ) -> Vec<Option<Hit>> {
        assert_eq!(origins.len(), directions.len(), "one direction per origin");
        origins
            .par_iter()
            .zip(directions)
            .map(|(&o, &d)| {
                let d = d.normalize_or_zero();
                (d != Vec3::ZERO)
                    .then(|| self.closest_hit(o, d, tmin, f32::INFINITY))
                    .flatten()
            })
            .collect()
    }

    /// [`Scene::occluded`] of each segment `from[i]` to `to[i]`, traced in parallel, the
    /// answers in their order.
    ///
    /// # Panics
    /// When `from` and `to` differ in length.
    #[must_use]
    pub fn occluded_segments(&self, from: &[Vec3], to: &[Vec3]) -> Vec<bool> {
        assert_eq!(from.len(), to.len(), "one end per start");
        from.par_iter()
            .zip(to)
            .map(|(&a, &b)| self.occluded(a, b))
            .collect()
    }

    /// True when any triangle lies on the open segment from `from` to `to` (an any-hit shadow ray),
    /// alpha-tested surfaces counting only where they are not cut.
    /// The caller offsets both ends off their surfaces.
    #[must_use]
    pub fn occluded(&self, from: Vec3, to: Vec3) -> bool {
        let d = to - from;
        let len = d.length();
        if len <= 0.0 {
            return false;
        }
        let ray = Ray::new(Vec3A::from(from), Vec3A::from(d / len), 0.0, len);
        self.occluded_ray(&mut self.shadow_state(), &ray)
    }

    /// A traversal state for [`Scene::occluded_ray`], reused from ray to ray (a fresh one per
    /// ray zeroes its stack every time).
    pub(crate) fn shadow_state(&self) -> Traversal {
        self.bvh.new_traversal(Vec3A::X)
    }

    /// [`Scene::occluded`] for a prepared shadow ray (unit direction, `tmin` 0, `tmax` the
    /// segment's length), with a reused traversal state: the same answer as `occluded`.
    #[inline]
    pub(crate) fn occluded_ray(&self, state: &mut Traversal, ray: &Ray) -> bool {
        self.blocker(state, ray).is_some()
    }

    /// [`Scene::occluded_ray`] that first tests the triangle `hint` names (the blocker of an
    /// earlier ray close to this one; [`NO_HINT`]: none) and, where the traversal finds a
    /// blocker, stores it in `hint`. The same answer as `occluded_ray`: the hinted triangle
    /// counts only where the traversal would meet it, a hit at or past the node tests' entry
    /// clamp and before `tmax`, where it is not cut. A shadow ray from a pixel toward a VPL is
    /// mostly blocked by what blocked the previous pixel's ray toward the same VPL.
    #[inline]
    pub(crate) fn occluded_ray_hinted(
        &self,
        state: &mut Traversal,
        ray: &Ray,
        hint: &mut u32,
    ) -> bool {
        if *hint != NO_HINT {
            let i = *hint as usize;
            let t = self.bvh_triangles[i].intersect(ray);
            if (shadow_bvh::NODE_TMIN..ray.tmax).contains(&t)
                && !self
                    .alpha_surfaces()
                    .is_some_and(|s| self.cut(s, i, &Ray { tmax: t, ..*ray }))
            {
                return true;
            }
        }
        match self.blocker(state, ray) {
            Some(i) => {
                *hint = i;
                true
            }
            None => false,
        }
    }

    /// The BVH-order index of a triangle that blocks the shadow ray `ray`, the first the
    /// traversal meets; None when it reaches `tmax`.
    #[inline]
    fn blocker(&self, state: &mut Traversal, ray: &Ray) -> Option<u32> {
        match self.alpha_surfaces() {
            None => self.occluded_ray_with::<false>(state, ray, None),
            Some(s) => self.occluded_ray_with::<true>(state, ray, Some(s)),
        }
    }

    /// [`Scene::blocker`] with (`ALPHA`) or without the alpha-test filter at each hit.
    #[inline(always)]
    fn occluded_ray_with<const ALPHA: bool>(
        &self,
        state: &mut Traversal,
        ray: &Ray,
        surfaces: Option<&Surfaces>,
    ) -> Option<u32> {
        state.reinit(ray.direction);
        let mut node;
        let mut hit = None;
        'any: {
            obvhs::traverse!(
                self.shadow,
                node,
                *state,
                node.intersect(ray, state.oct_inv4),
                {
                    let i = state.primitive_id as usize;
                    let t = self.bvh_triangles[i].intersect(ray);
                    if t < ray.tmax {
                        let cut = ALPHA
                            && surfaces.is_some_and(|s| self.cut(s, i, &Ray { tmax: t, ..*ray }));
                        if !cut {
                            hit = Some(state.primitive_id);
                            break 'any;
                        }
                    }
                }
            );
        }
        hit
    }

    /// [`Scene::occluded_ray`] testing every triangle (see [`Scene::occluded_brute_force`]).
    pub(crate) fn occluded_ray_brute_force(&self, ray: &Ray) -> bool {
        let surfaces = self.alpha_surfaces();
        self.bvh_triangles.iter().enumerate().any(|(i, t)| {
            let h = t.intersect(ray);
            h > ray.tmin
                && h < ray.tmax
                && !surfaces.is_some_and(|s| self.cut(s, i, &Ray { tmax: h, ..*ray }))
        })
    }

    /// [`Scene::occluded`] without the BVH: tests every triangle. A baseline for benchmarks.
    #[must_use]
    pub fn occluded_brute_force(&self, from: Vec3, to: Vec3) -> bool {
        let d = to - from;
        let len = d.length();
        if len <= 0.0 {
            return false;
        }
        let ray = Ray::new(Vec3A::from(from), Vec3A::from(d / len), 0.0, len);
        self.occluded_ray_brute_force(&ray)
    }
}

/// `v` with each `-0.0` component made `+0.0`. obvhs's traversal takes a ray's octant from
/// `d < 0.0` (false for `-0.0`) but its slabs from the inverse, which `safe_inverse` makes
/// negative for `-0.0`: the two disagree and the ray misses boxes it crosses (a window's
/// reveals along `-tangent`, a negated axis, were missed at every depth).
#[inline(always)]
fn positive_zeros(v: Vec3) -> Vec3 {
    Vec3::select(v.cmpeq(Vec3::ZERO), Vec3::ZERO, v)
}

/// The barycentric coordinates `(b1, b2)` (weights of `v1` and `v2`) where `ray` meets the
/// plane of `tri` at distance `ray.tmax`.
#[inline]
fn barycentrics(tri: &Triangle, ray: &Ray) -> Vec2 {
    let p = ray.origin + ray.direction * ray.tmax;
    let (e1, e2) = (tri.v1 - tri.v0, tri.v2 - tri.v0);
    let n = e1.cross(e2);
    let n2 = n.length_squared();
    if n2 <= 0.0 {
        return Vec2::ZERO;
    }
    let d = p - tri.v0;
    Vec2::new(d.cross(e2).dot(n) / n2, e1.cross(d).dot(n) / n2)
}

/// The albedo of a material's mean colour: its constant albedo, or `albedo + tint * mean rgb`
/// of its texture (clamped to `[0, 1]`). `textures` holds every index (validated).
fn mean_albedo(m: &Material, textures: &[Texture]) -> Vec3 {
    match &m.texture {
        None => m.albedo,
        Some(map) => {
            let mean = textures[map.texture as usize].mean().truncate();
            (m.albedo + m.texture_tint * mean).clamp(Vec3::ZERO, Vec3::ONE)
        }
    }
}

/// The glossy layer of a material: its reflectance of the texture's mean colour when it has one
/// (see [`Scene::gloss_at`]) and its roughness.
fn mean_gloss(m: &Material, textures: &[Texture]) -> Option<(Vec3, f32)> {
    let g = m.gloss?;
    let mean = m.texture.map_or(Vec3::ZERO, |map| {
        textures[map.texture as usize].mean().truncate()
    });
    Some((
        (g.constant + g.tint * mean).clamp(Vec3::ZERO, Vec3::ONE),
        g.roughness,
    ))
}

impl Surfaces {
    /// The per-hit data of `materials`; `None` when no material has a texture or an alpha test.
    fn new(
        materials: &[Material],
        material_ids: &[u32],
        uvs: Option<&[[Vec2; 3]]>,
        textures: Vec<Texture>,
        bvh_ids: &[u32],
    ) -> Option<Box<Self>> {
        let any = materials
            .iter()
            .any(|m| m.texture.is_some() || m.alpha_test.is_some());
        if !any {
            return None;
        }
        let bvh_alpha = if materials.iter().any(|m| m.alpha_test.is_some()) {
            bvh_ids
                .iter()
                .map(|&t| {
                    let m = material_ids[t as usize];
                    if materials[m as usize].alpha_test.is_some() {
                        m
                    } else {
                        Self::OPAQUE
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        Some(Box::new(Self {
            textures,
            materials: materials.to_vec(),
            triangle_material: material_ids.to_vec(),
            uvs: uvs.map_or_else(|| vec![[Vec2::ZERO; 3]; material_ids.len()], <[_]>::to_vec),
            bvh_alpha,
        }))
    }
}

/// The checks of [`Scene::new`] before any triangle is read: counts, finite vertices, albedo
/// in `[0, 1]`, valid lights and materials, UVs when a material reads a texture.
fn check_input(input: &SceneInput<'_>) -> Result<()> {
    let SceneInput {
        vertices,
        triangles,
        material_ids,
        materials,
        uvs,
        ..
    } = *input;
    let (lights, textures) = (&input.lights, &input.textures);
    if triangles.is_empty() {
        return Err(VplaceError::Empty {
            what: "scene triangles".into(),
            hint: "the scene needs at least one mesh triangle".into(),
        });
    }
    if material_ids.len() != triangles.len() {
        return Err(VplaceError::Shape {
            what: "material_ids".into(),
            expected: format!("({},) (one per triangle)", triangles.len()),
            got: format!("({},)", material_ids.len()),
        });
    }
    if materials.is_empty() {
        return Err(VplaceError::Empty {
            what: "albedo".into(),
            hint: "pass at least one material".into(),
        });
    }
    let flat: Vec<f32> = vertices.iter().flat_map(|v| v.to_array()).collect();
    check_finite("vertices", &flat)?;
    let flat: Vec<f32> = materials.iter().flat_map(|m| m.albedo.to_array()).collect();
    check_finite("albedo", &flat)?;
    if let Some(i) = flat.iter().position(|a| !(0.0..=1.0).contains(a)) {
        return Err(VplaceError::OutOfRange {
            what: format!("albedo[{}]", i / 3),
            value: flat[i].to_string(),
            expected: "[0, 1] in every channel".into(),
        });
    }
    for (i, l) in lights.iter().enumerate() {
        l.validate(i)?;
    }
    for (i, m) in materials.iter().enumerate() {
        m.validate(i, textures.len())?;
    }
    if let Some(uv) = uvs {
        if uv.len() != triangles.len() {
            return Err(VplaceError::Shape {
                what: "uvs".into(),
                expected: format!("({}, 3, 2) (one UV per triangle corner)", triangles.len()),
                got: format!("({}, 3, 2)", uv.len()),
            });
        }
        let corners = uv.iter().flatten();
        if let Some(i) = corners
            .flat_map(|c| c.to_array())
            .position(|x| !x.is_finite())
        {
            return Err(VplaceError::NonFinite {
                what: "uvs".into(),
                index: i,
            });
        }
    } else if let Some(i) = materials.iter().position(Material::reads_uvs) {
        return Err(VplaceError::Invalid {
            what: format!("materials[{i}]"),
            reason: "it reads a texture, but the scene has no UVs: pass uvs".into(),
        });
    }
    Ok(())
}

/// The triangles of a scene as the BVH takes them, with their normals, mean albedo, the
/// degenerate count and the bounds.
struct Geometry {
    tris: Vec<Triangle>,
    normals: Vec<Vec3>,
    triangle_albedo: Vec<Vec3>,
    triangle_gloss: Vec<Option<(Vec3, f32)>>,
    degenerate: usize,
    lo: Vec3,
    hi: Vec3,
}

/// [`Geometry`] of checked input; errors on an index out of bounds or when every triangle is
/// degenerate.
fn geometry(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    material_ids: &[u32],
    materials: &[Material],
    textures: &[Texture],
) -> Result<Geometry> {
    let nv = vertices.len();
    let mut tris = Vec::with_capacity(triangles.len());
    let mut normals = Vec::with_capacity(triangles.len());
    let mut triangle_albedo = Vec::with_capacity(triangles.len());
    let mut triangle_gloss = Vec::with_capacity(triangles.len());
    let mut degenerate = 0;
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (t, (idx, &m)) in triangles.iter().zip(material_ids).enumerate() {
        for &i in idx {
            if i as usize >= nv {
                return Err(VplaceError::IndexOutOfBounds {
                    what: format!("triangles[{t}]"),
                    index: i as usize,
                    len: nv,
                });
            }
        }
        if m as usize >= materials.len() {
            return Err(VplaceError::IndexOutOfBounds {
                what: format!("material_ids[{t}]"),
                index: m as usize,
                len: materials.len(),
            });
        }
        let [a, b, c] = idx.map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a);
        if n.length_squared() == 0.0 {
            degenerate += 1;
        }
        for p in [a, b, c] {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        normals.push(n.normalize_or_zero());
        triangle_albedo.push(mean_albedo(&materials[m as usize], textures));
        triangle_gloss.push(mean_gloss(&materials[m as usize], textures));
        tris.push(Triangle {
            v0: a.into(),
            v1: b.into(),
            v2: c.into(),
        });
    }
    if degenerate == tris.len() {
        return Err(VplaceError::Invalid {
            what: "scene triangles".into(),
            reason: "every triangle has zero area".into(),
        });
    }
    Ok(Geometry {
        tris,
        normals,
        triangle_albedo,
        triangle_gloss,
        degenerate,
        lo,
        hi,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::{box_geometry, box_with, card_scene, closed_box, extend};

    /// A direction with `-0.0` components finds what the same direction with `+0.0` finds.
    #[test]
    fn closest_hit_along_negative_zeros() {
        let s = closed_box(vec![]);
        let o = Vec3::new(0.1, -0.2, 0.3);
        for d in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::NEG_X,
            Vec3::NEG_Y,
            Vec3::NEG_Z,
        ] {
            let want = s
                .closest_hit(o, d, 0.0, f32::INFINITY)
                .expect("a closed box");
            for signs in 1..8u32 {
                let flip = |k: u32, c: f32| {
                    if c == 0.0 && signs & (1 << k) != 0 {
                        -0.0
                    } else {
                        c
                    }
                };
                let neg = Vec3::new(flip(0, d.x), flip(1, d.y), flip(2, d.z));
                let got = s.closest_hit(o, neg, 0.0, f32::INFINITY);
                assert_eq!(got.map(|h| h.t), Some(want.t), "{neg:?}");
            }
        }
    }

    #[test]
    fn closest_hit_and_occlusion() {
        let s = closed_box(vec![]);
        let h = s
            .closest_hit(Vec3::new(0., 0., 1.), Vec3::NEG_Z, 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-5);
        assert!(s.normal(h.triangle).z.abs() > 0.999);
        assert!(!s.occluded(Vec3::new(0., 0., 0.5), Vec3::new(0., 0., 1.5)));
        assert!(s.occluded(Vec3::new(0., 0., 0.5), Vec3::new(0., 0., -0.5)));
        for (a, b) in [
            (Vec3::new(0., 0., 0.5), Vec3::new(0., 0., 1.5)),
            (Vec3::new(0., 0., 0.5), Vec3::new(0., 0., -0.5)),
            (Vec3::new(0.3, 0.2, 0.5), Vec3::new(1.5, -0.2, 1.0)),
            (Vec3::new(-0.3, 0.2, 1.5), Vec3::new(0.5, -0.9, 0.1)),
        ] {
            assert_eq!(s.occluded(a, b), s.occluded_brute_force(a, b), "{a} {b}");
        }
        assert!((s.diagonal() - (4.0f32 + 4.0 + 4.0).sqrt()).abs() < 1e-5);
    }

    /// The batched, parallel queries answer each ray as the single queries do, in order; a
    /// zero direction hits nothing.
    #[test]
    fn batched_queries_answer_as_single_ones() {
        let plate = [
            Vec3::new(-0.5, -0.5, 1.0),
            Vec3::new(0.5, -0.5, 1.0),
            Vec3::new(0.5, 0.5, 1.0),
            Vec3::new(-0.5, 0.5, 1.0),
        ];
        let s = box_with(vec![], &[plate]);
        let mut rng = crate::rng::Rng::new(7, 0);
        let mut point = || {
            Vec3::new(
                rng.next_f32() * 1.8 - 0.9,
                rng.next_f32() * 1.8 - 0.9,
                rng.next_f32() * 1.8 + 0.1,
            )
        };
        let n = 300;
        let from: Vec<Vec3> = (0..n).map(|_| point()).collect();
        let mut to: Vec<Vec3> = (0..n).map(|_| point()).collect();
        to[5] = from[5];
        let mut dirs: Vec<Vec3> = from.iter().zip(&to).map(|(a, b)| (*b - *a) * 3.0).collect();
        dirs[5] = Vec3::ZERO;
        let hits = s.closest_hits(&from, &dirs, 0.0);
        let blocked = s.occluded_segments(&from, &to);
        assert_eq!((hits.len(), blocked.len()), (n, n));
        for i in 0..n {
            let d = dirs[i].normalize_or_zero();
            let want = (d != Vec3::ZERO)
                .then(|| s.closest_hit(from[i], d, 0.0, f32::INFINITY))
                .flatten();
            assert_eq!(hits[i], want, "ray {i}");
            assert_eq!(blocked[i], s.occluded(from[i], to[i]), "segment {i}");
        }
        assert!(hits[5].is_none() && hits.iter().filter(|h| h.is_some()).count() == n - 1);
        let count = blocked.iter().filter(|&&b| b).count();
        assert!(count > 10 && count < n - 10, "{count} of {n} blocked");
    }

    #[test]
    fn bad_input_is_an_error() {
        let v = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let a = [Vec3::splat(0.5)];
        assert!(matches!(
            Scene::build(&v, &[], &[], &a, vec![]),
            Err(VplaceError::Empty { .. })
        ));
        assert!(matches!(
            Scene::build(&v, &[[0, 1, 3]], &[0], &a, vec![]),
            Err(VplaceError::IndexOutOfBounds { .. })
        ));
        assert!(matches!(
            Scene::build(&v, &[[0, 1, 2]], &[1], &a, vec![]),
            Err(VplaceError::IndexOutOfBounds { .. })
        ));
        let nan = [Vec3::ZERO, Vec3::new(f32::NAN, 0., 0.), Vec3::Y];
        assert!(matches!(
            Scene::build(&nan, &[[0, 1, 2]], &[0], &a, vec![]),
            Err(VplaceError::NonFinite { index: 3, .. })
        ));
        assert!(matches!(
            Scene::build(&v, &[[0, 0, 0]], &[0], &a, vec![]),
            Err(VplaceError::Invalid { .. })
        ));
        let bad = Light::point(Vec3::ZERO, Vec3::new(-1., 0., 0.));
        assert!(Scene::build(&v, &[[0, 1, 2]], &[0], &a, vec![bad]).is_err());
        assert!(Scene::build(&v, &[[0, 1, 2]], &[0], &[Vec3::splat(1.5)], vec![]).is_err());
    }

    #[test]
    fn shadow_traversal_agrees_with_obvhs_and_brute_force() {
        // Random triangles of all sizes in the box, random segments: the converted-plane node
        // test visits what obvhs's does, so every answer is the same.
        let mut rng = crate::rng::Rng::new(12, 1);
        let mut r = || rng.next_f32();
        let mut extra = Vec::new();
        for k in 0..400 {
            let size = [0.01, 0.1, 0.6][k % 3];
            let c = Vec3::new(2.0 * r() - 1.0, 2.0 * r() - 1.0, 2.0 * r());
            let mut corner = || c + (Vec3::new(r(), r(), r()) - 0.5) * size;
            let (a, b, d) = (corner(), corner(), corner());
            extra.push([a, b, d, d]);
        }
        let s = box_with(vec![], &extra);
        let (mut blocked, mut open) = (0, 0);
        let mut state = s.shadow_state();
        let mut hint = NO_HINT;
        for _ in 0..4000 {
            let mut point = || Vec3::new(2.2 * r() - 1.1, 2.2 * r() - 1.1, 2.2 * r() - 0.1);
            let (a, b) = (point(), point());
            let got = s.occluded(a, b);
            assert_eq!(got, s.occluded_brute_force(a, b), "{a} {b}");
            let d = b - a;
            let ray = Ray::new(Vec3A::from(a), Vec3A::from(d / d.length()), 0.0, d.length());
            let obvhs_hit = !s
                .bvh
                .ray_traverse_miss(ray, |r, id| s.bvh_triangles[id].intersect(r));
            assert_eq!(got, obvhs_hit, "{a} {b}");
            // No hint, the last blocked ray's, any triangle: the same answer; a blocked ray
            // leaves a hint.
            let any = (7919 * blocked % s.bvh_triangles.len()) as u32;
            for start in [NO_HINT, hint, any] {
                let mut h = start;
                assert_eq!(
                    s.occluded_ray_hinted(&mut state, &ray, &mut h),
                    got,
                    "{a} {b}"
                );
                assert!(!got || h != NO_HINT);
                if got && start == hint {
                    hint = h;
                }
            }
            if got {
                blocked += 1;
            } else {
                open += 1;
            }
        }
        assert!(blocked > 500 && open > 500, "{blocked} {open}");
    }

    #[test]
    fn axis_rays_with_negative_zero_components_are_blocked() {
        // The negated direction of a sun straight down is (-0, -0, 1): the ceiling blocks it
        // as it blocks (0, 0, 1), whatever the signs of the zeros.
        let s = closed_box(vec![]);
        let mut state = s.shadow_state();
        for x in [0.0f32, -0.0] {
            for y in [0.0f32, -0.0] {
                let up = Ray::new(Vec3A::new(0.1, -0.05, 0.5), Vec3A::new(x, y, 1.0), 0.0, 9.0);
                assert!(s.occluded_ray(&mut state, &up), "{x} {y}");
                assert!(s.occluded_ray_brute_force(&up), "{x} {y}");
                let down = Ray::new(
                    Vec3A::new(0.1, -0.05, 0.5),
                    Vec3A::new(x, y, -1.0),
                    0.0,
                    9.0,
                );
                assert!(s.occluded_ray(&mut state, &down), "{x} {y}");
            }
        }
    }
    /// The test box (albedo 0.5) with a 1 x 1 card at height 1 over the floor's middle, corners
    /// `(-0.5, -0.5)`, `(0.5, -0.5)`, `(0.5, 0.5)`, `(-0.5, 0.5)`, its UVs the unit square
    /// (`u` along x, `v` along y), material 1 = `card`; box UVs zero. Texture 0: 2 x 1 texels,
    /// left (u < 0.5) red with alpha 0, right green with alpha 1, read with `Extend`.
    #[test]
    fn albedo_at_hits_reads_the_texture() {
        let card = Material::textured(extend(0), Vec3::new(0.8, 0.6, 1.0));
        let s = card_scene(card, vec![]);
        for x in [-0.45f32, -0.3, -0.1, 0.0, 0.2, 0.4] {
            let h = s
                .closest_hit(Vec3::new(x, 0.1, 1.5), Vec3::NEG_Z, 0.0, f32::INFINITY)
                .unwrap();
            assert!((h.t - 0.5).abs() < 1e-5);
            let uv = s.uv_at(h.triangle, h.barycentrics).unwrap();
            assert!(
                (uv - Vec2::new(x + 0.5, 0.6)).abs().max_element() < 1e-5,
                "{uv}"
            );
            // Red at u <= 0.25, green at u >= 0.75, linear between (Extend).
            let g = ((x + 0.5 - 0.25) / 0.5).clamp(0.0, 1.0);
            let expect = Vec3::new(0.8 * (1.0 - g), 0.6 * g, 0.0);
            let got = s.albedo_at(h.triangle, h.barycentrics);
            assert!(
                (got - expect).abs().max_element() < 1e-5,
                "{x}: {got} {expect}"
            );
        }
        // The constant path: the box's own triangles, and the mean for `albedo`.
        let floor = s
            .closest_hit(Vec3::new(0.8, 0.8, 1.5), Vec3::NEG_Z, 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!(
            s.albedo_at(floor.triangle, floor.barycentrics),
            Vec3::splat(0.5)
        );
        assert_eq!(s.albedo(12), Vec3::new(0.4, 0.3, 0.0));
        // Barycentrics name the triangle's vertices in input order.
        assert!((s.albedo_at(12, Vec2::ZERO) - Vec3::new(0.8, 0.0, 0.0)).length() < 1e-6);
        assert!((s.albedo_at(12, Vec2::X) - Vec3::new(0.0, 0.6, 0.0)).length() < 1e-6);
        assert_eq!(s.texture_count(), 1);
        assert!(!s.has_alpha_tests());
        // A constant plus a tinted texture, clamped to [0, 1].
        let card = Material {
            albedo: Vec3::new(0.5, 0.1, 0.2),
            ..Material::textured(extend(0), Vec3::ONE)
        };
        let s = card_scene(card, vec![]);
        assert_eq!(s.albedo_at(12, Vec2::ZERO), Vec3::new(1.0, 0.1, 0.2));
    }

    #[test]
    fn gloss_at_reads_the_layer_and_its_texture() {
        // A metal-like card: no diffuse albedo, its glossy layer the tinted texture plus a
        // constant.
        let card = Material::textured(extend(0), Vec3::ZERO).with_gloss(
            Vec3::splat(0.05),
            Vec3::new(0.9, 0.5, 1.0),
            0.3,
        );
        let s = card_scene(card, vec![]);
        // Texel red (u <= 0.25), then green (u >= 0.75).
        assert_eq!(s.albedo_at(12, Vec2::ZERO), Vec3::ZERO);
        let (red, r) = s.gloss_at(12, Vec2::ZERO).unwrap();
        assert!((red - Vec3::new(0.95, 0.05, 0.05)).length() < 1e-6, "{red}");
        assert_eq!(r, 0.3);
        let (green, _) = s.gloss_at(12, Vec2::X).unwrap();
        assert!(
            (green - Vec3::new(0.05, 0.55, 0.05)).length() < 1e-6,
            "{green}"
        );
        // The box's plain material has none.
        assert_eq!(s.gloss_at(0, Vec2::ZERO), None);
        // A constant material's, clamped to [0, 1].
        let (v, t) = box_geometry(&[]);
        let ids = vec![0; t.len()];
        let build = |m: Material| {
            Scene::new(SceneInput {
                vertices: &v,
                triangles: &t,
                material_ids: &ids,
                materials: &[m],
                ..Default::default()
            })
        };
        let plain = Material::diffuse(Vec3::new(0.2, 0.7, 0.5)).with_gloss(
            Vec3::new(0.1, 1.4, 0.0),
            Vec3::ONE,
            1.0,
        );
        let s = build(plain).unwrap();
        assert_eq!(s.albedo_at(3, Vec2::ZERO), Vec3::new(0.2, 0.7, 0.5));
        assert_eq!(
            s.gloss_at(3, Vec2::ZERO),
            Some((Vec3::new(0.1, 1.0, 0.0), 1.0))
        );
        // A negative or non-finite layer, a roughness outside [0, 1]: refused.
        let half = Vec3::splat(0.5);
        for (gloss, roughness) in [
            (Vec3::new(-0.1, 0.0, 0.0), 0.5),
            (Vec3::new(f32::NAN, 0.0, 0.0), 0.5),
            (Vec3::ZERO, 1.5),
            (Vec3::ZERO, f32::NAN),
        ] {
            let m = Material::diffuse(half).with_gloss(gloss, Vec3::ZERO, roughness);
            let err = build(m).unwrap_err();
            assert!(err.to_string().contains("gloss"), "{err}");
        }
    }

    #[test]
    fn alpha_tested_shadow_rays_pass_cut_texels_only() {
        let card = Material {
            alpha_test: Some(AlphaTest::texture(extend(0))),
            ..Material::diffuse(Vec3::splat(0.5))
        };
        let s = card_scene(card, vec![]);
        assert!(s.has_alpha_tests());
        let below = |x: f32| Vec3::new(x, 0.0, 0.2);
        let above = |x: f32| Vec3::new(x, 0.0, 1.8);
        // Cut (alpha 0) where u < 0.25, i.e. x < -0.25; opaque where x > 0.
        for x in [-0.45, -0.3] {
            assert!(!s.occluded(below(x), above(x)), "{x}");
            assert!(!s.occluded_brute_force(below(x), above(x)), "{x}");
        }
        for x in [0.05, 0.3, 0.45] {
            assert!(s.occluded(below(x), above(x)), "{x}");
            assert!(s.occluded_brute_force(below(x), above(x)), "{x}");
        }
        // The card's triangle, remembered from its opaque half, blocks nothing through the
        // cut half.
        let ray = |x: f32| Ray::new(Vec3A::new(x, 0.0, 0.2), Vec3A::Z, 0.0, 1.6);
        let mut state = s.shadow_state();
        for x in [0.05, 0.3, 0.45] {
            let mut hint = NO_HINT;
            assert!(s.occluded_ray_hinted(&mut state, &ray(x), &mut hint));
            for cut in [-0.45, -0.3] {
                let mut stale = hint;
                assert!(
                    !s.occluded_ray_hinted(&mut state, &ray(cut), &mut stale),
                    "{cut}"
                );
                assert_eq!(stale, hint);
            }
        }
        // Closest hits go through the cut half to the floor and stop at the opaque half.
        let down = |x: f32| s.closest_hit(above(x), Vec3::NEG_Z, 0.0, f32::INFINITY);
        assert!((down(-0.4).unwrap().t - 1.8).abs() < 1e-5);
        assert!((down(0.4).unwrap().t - 0.8).abs() < 1e-5);
        // Random segments: the BVH's any-hit filter agrees with the brute force.
        let mut rng = crate::rng::Rng::new(5, 2);
        let mut r = || rng.next_f32();
        let mut passed = 0;
        for _ in 0..3000 {
            let mut point = || Vec3::new(1.8 * r() - 0.9, 1.8 * r() - 0.9, 1.9 * r() + 0.05);
            let (a, b) = (point(), point());
            let got = s.occluded(a, b);
            assert_eq!(got, s.occluded_brute_force(a, b), "{a} {b}");
            let crosses = (a.z - 1.0) * (b.z - 1.0) < 0.0;
            passed += usize::from(crosses && !got);
        }
        assert!(passed > 100, "{passed}");
        // A constant alpha below the cutoff removes the card; above it, keeps it.
        for (alpha, blocked) in [(0.3, false), (0.7, true)] {
            let card = Material {
                alpha_test: Some(AlphaTest::constant(alpha)),
                ..Material::diffuse(Vec3::splat(0.5))
            };
            let s = card_scene(card, vec![]);
            assert_eq!(s.occluded(below(0.3), above(0.3)), blocked, "{alpha}");
        }
    }

    #[test]
    fn bad_materials_are_errors() {
        let (v, t) = crate::test_util::box_geometry(&[]);
        let ids = vec![0u32; t.len()];
        let uvs = vec![[Vec2::ZERO; 3]; t.len()];
        let tex = || vec![Texture::new("t", 1, 1, 3, &[0.5; 3]).unwrap()];
        let build = |m: Material, uvs: Option<&[[Vec2; 3]]>| {
            Scene::new(SceneInput {
                vertices: &v,
                triangles: &t,
                material_ids: &ids,
                materials: &[m],
                uvs,
                textures: tex(),
                ..Default::default()
            })
        };
        assert!(build(
            Material::textured(TextureRef::new(0), Vec3::ONE),
            Some(&uvs)
        )
        .is_ok());
        assert!(matches!(
            build(
                Material::textured(TextureRef::new(1), Vec3::ONE),
                Some(&uvs)
            ),
            Err(VplaceError::IndexOutOfBounds {
                index: 1,
                len: 1,
                ..
            })
        ));
        assert!(matches!(
            build(Material::textured(TextureRef::new(0), Vec3::ONE), None),
            Err(VplaceError::Invalid { .. })
        ));
        assert!(matches!(
            build(
                Material::textured(TextureRef::new(0), Vec3::ONE),
                Some(&uvs[1..])
            ),
            Err(VplaceError::Shape { .. })
        ));
        let mut nan = uvs.clone();
        nan[2][1].y = f32::NAN;
        assert!(matches!(
            build(
                Material::textured(TextureRef::new(0), Vec3::ONE),
                Some(&nan)
            ),
            Err(VplaceError::NonFinite { index: 15, .. })
        ));
        assert!(matches!(
            build(
                Material::textured(TextureRef::new(0), Vec3::NEG_ONE),
                Some(&uvs)
            ),
            Err(VplaceError::OutOfRange { .. })
        ));
        let scaled = TextureRef {
            uv_scale: Vec2::new(f32::INFINITY, 1.0),
            ..TextureRef::new(0)
        };
        assert!(matches!(
            build(Material::textured(scaled, Vec3::ONE), Some(&uvs)),
            Err(VplaceError::NonFinite { .. })
        ));
        let alpha = Material {
            alpha_test: Some(AlphaTest::texture(TextureRef::new(3))),
            ..Material::diffuse(Vec3::ONE)
        };
        assert!(matches!(
            build(alpha, Some(&uvs)),
            Err(VplaceError::IndexOutOfBounds { index: 3, .. })
        ));
        let alpha = Material {
            alpha_test: Some(AlphaTest::constant(f32::NAN)),
            ..Material::diffuse(Vec3::ONE)
        };
        assert!(build(alpha, None).is_err());
        // A constant alpha test needs no UVs.
        let alpha = Material {
            alpha_test: Some(AlphaTest::constant(0.2)),
            ..Material::diffuse(Vec3::ONE)
        };
        assert!(build(alpha, None).is_ok());
    }
}
