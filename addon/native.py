"""The one module of the add-on that imports the ``vplace`` package.

When the add-on is installed as an extension, Blender installs the bundled ``vplace`` wheel
(``wheels/`` in the manifest); in development the package comes from the virtual environment.
Every other module reaches the native library through this one: the ``vplace`` package itself,
and the conversions from the add-on's exported scene and captures to ``vplace`` objects.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import vplace
import vplace.bench_par2d as bench_par2d

if TYPE_CHECKING:
    from .capture import Capture
    from .export import AlphaInfo, ExportedScene, LightInfo, TextureInfo, WorldInfo

__all__ = [
    "bench_par2d",
    "build_scene",
    "gloss_mask",
    "native_light",
    "native_world",
    "view_of",
    "vplace",
]


def native_light(info: LightInfo) -> vplace.Light:
    """The core light for an exported Blender light, with every parameter Cycles uses."""
    if info.type == "POINT":
        return vplace.Light.point(
            info.position, info.power, radius=info.radius, soft_falloff=info.soft_falloff
        )
    if info.type == "SPOT":
        return vplace.Light.spot(
            info.position,
            info.direction,
            info.spot_half_angle,
            info.power,
            blend=info.spot_blend,
            radius=info.radius,
            soft_falloff=info.soft_falloff,
        )
    if info.type == "AREA":
        return vplace.Light.area(
            info.position,
            info.direction,
            info.tangent,
            "ellipse" if info.area_disk else "rectangle",
            info.size_x,
            info.size_y,
            info.power,
            spread=info.spread,
        )
    if info.type == "SUN":
        return vplace.Light.sun(info.direction, info.power, angle=info.angle)
    raise vplace.InputError(f"light {info.name!r} has an unsupported type {info.type!r}")


def native_world(info: WorldInfo) -> vplace.Light:
    """The core's world light for an exported Blender world."""
    return vplace.Light.world(
        info.color,
        1.0,
        image=info.image,
        rotation=None if info.rotation is None else info.rotation.tolist(),
    )


def _texture_map(info: TextureInfo) -> vplace.TextureMap:
    return vplace.TextureMap(
        info.index, uv_scale=info.uv_scale, uv_offset=info.uv_offset, wrap=info.wrap
    )


def _alpha_test(info: AlphaInfo | None) -> vplace.AlphaTest | None:
    if info is None:
        return None
    texture = _texture_map(info.texture) if info.texture is not None else None
    return vplace.AlphaTest(
        info.offset, info.scale, texture, source=info.source, cutoff=info.cutoff
    )


def build_scene(exported: ExportedScene) -> vplace.Scene:
    """A ``vplace.Scene`` (with its BVH) from an exported Blender scene: its lights, its world
    when that sends light, its materials' emission; per material its albedo, or its base-colour
    texture (``albedo_offset + texture_tint * rgb``) and alpha cut-out, read through the
    exported UVs."""
    lights = [native_light(light) for light in exported.lights]
    if exported.world is not None and exported.world.emits:
        lights.append(native_world(exported.world))
    mats = exported.materials
    textured = any(m.texture is not None or m.alpha is not None for m in mats)
    if not textured:
        return vplace.Scene(
            exported.vertices,
            exported.triangles,
            exported.material_ids,
            exported.albedo,
            lights,
            emission=exported.emission,
        )
    albedo = np.array(
        [m.albedo_offset if m.texture is not None else m.albedo for m in mats], dtype=np.float32
    ).reshape(-1, 3)
    return vplace.Scene(
        exported.vertices,
        exported.triangles,
        exported.material_ids,
        albedo,
        lights,
        emission=exported.emission,
        uvs=exported.uvs,
        textures=exported.textures,
        base_textures=[_texture_map(m.texture) if m.texture is not None else None for m in mats],
        texture_tint=np.array([m.texture_tint for m in mats], dtype=np.float32).reshape(-1, 3),
        alpha_tests=[_alpha_test(m.alpha) for m in mats],
    )


def gloss_mask(scene: vplace.Scene, exported: ExportedScene, cap: Capture) -> np.ndarray | None:
    """(H, W) float32: 1 where the pixel's surface has a glossy layer vplace models (rough:
    ``export.ROUGH_GLOSS``), 0 where it is left to EEVEE's ray tracing; None when no material
    has a rough glossy layer. A surface without a glossy layer has a black Glossy Color pass, so
    only a scene with sharp layers needs to know which surface each pixel sees: a short ray
    along the view direction finds it in ``scene``."""
    rough, sharp = exported.rough_gloss, exported.sharp_gloss
    if not rough.any():
        return None
    mask = cap.covered.astype(np.float32)
    if not sharp.any():
        return mask
    ys, xs = np.nonzero(cap.covered)
    target = cap.position[ys, xs].astype(np.float32)
    look = target - np.asarray(cap.camera_position, dtype=np.float32)
    look /= np.maximum(np.linalg.norm(look, axis=1, keepdims=True), 1e-12)
    back = np.float32(1e-3 * scene.diagonal)
    _, tri, _ = scene.intersect(
        np.ascontiguousarray(target - back * look), np.ascontiguousarray(look)
    )
    hit = tri >= 0
    mat = exported.material_ids[np.where(hit, tri, 0)]
    mask[ys, xs] = np.where(hit & sharp[mat], 0.0, 1.0)
    return mask


def view_of(
    cap: Capture, *, held_out: bool = False, gloss: np.ndarray | None = None
) -> vplace.View:
    """The ``vplace.View`` of a capture; ``held_out`` leaves out its global-illumination passes
    (what a view the model has not seen provides). ``gloss`` (:func:`gloss_mask`) adds the
    rough glossy layers to the receivers' reflectance and to the indirect light to match."""
    return vplace.View(
        position=cap.position,
        normal=cap.normal,
        albedo=cap.reflectance(gloss),
        covered=cap.covered,
        depth=cap.depth,
        direct=cap.direct,
        diffuse_direct=cap.diffuse_direct,
        diffuse_indirect=None if held_out else cap.diffuse_indirect,
        indirect=None if held_out else cap.modelled_indirect(gloss),
        specular=cap.glossy_color,
        camera_position=cap.camera_position,
        world_to_clip=cap.world_to_clip,
        name=cap.camera,
    )
