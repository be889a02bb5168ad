"""The exported Blender scene as ``vplace`` objects: lights, the world and the ``vplace.Scene``;
and the scene stage of a job (:func:`export_native`: export, check, BVH)."""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING

import bpy
import numpy as np

from ..errors import ExportError
from ..native import vplace
from .export import ExportedScene, MaterialInfo, export_scene

if TYPE_CHECKING:
    from .export import AlphaInfo, LightInfo, TextureInfo, WorldInfo


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


def build_scene(
    exported: ExportedScene, eyes: np.ndarray | None = None, looks: np.ndarray | None = None
) -> vplace.Scene:
    """A ``vplace.Scene`` (with its BVH) from an exported Blender scene: its lights, its world
    when that sends light, its materials' emission; per material its albedo, or its base-colour
    texture (``albedo_offset + texture_tint * rgb``) and alpha cut-out, read through the
    exported UVs; light paths stay within the bounces Cycles follows (``light_bounces``; at
    least the first diffuse one). ``eyes`` (N x 3), the cameras' positions, and ``looks``
    (N x 3), where they look, give its working scale (``vplace.Scene.scale``: the region seen
    from them, not a ground plane no camera sees, nor a sky dome)."""
    lights = [native_light(light) for light in exported.lights]
    if exported.world is not None and exported.world.emits:
        lights.append(native_world(exported.world))
    mats = exported.materials
    textured = any(m.texture is not None or m.alpha is not None for m in mats)
    bounces = None
    if exported.light_bounces is not None:
        diffuse, glossy, total = (min(b, vplace.MAX_BOUNCES) for b in exported.light_bounces)
        bounces = (max(diffuse, 1), glossy, max(total, 1))
    if not textured:
        return vplace.Scene(
            exported.vertices,
            exported.triangles,
            exported.material_ids,
            exported.albedo,
            lights,
            emission=exported.emission,
            light_bounces=bounces,
            eyes=eyes,
            looks=looks,
            **_gloss(mats, textured=False),
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
        light_bounces=bounces,
        eyes=eyes,
        looks=looks,
        **_gloss(mats, textured=True),
    )


def _gloss(mats: list[MaterialInfo], *, textured: bool) -> dict[str, np.ndarray]:
    """``vplace.Scene``'s ``gloss``, ``gloss_tint`` and ``gloss_roughness`` (the glossy layers the
    light paths reflect off), or nothing when no material has one."""
    if all(m.gloss is None for m in mats):
        return {}
    const, tint, rough = [], [], []
    for m in mats:
        tex = textured and m.texture is not None
        if m.gloss is None:
            const.append((0.0, 0.0, 0.0))
            tint.append((0.0, 0.0, 0.0))
        else:
            const.append(m.gloss_offset if tex else m.gloss)
            tint.append(m.gloss_tint if tex else (0.0, 0.0, 0.0))
        r = m.gloss_roughness if m.gloss_roughness is not None else 0.5
        rough.append(min(max(r, 0.0), 1.0))
    return {
        "gloss": np.array(const, dtype=np.float32).reshape(-1, 3),
        "gloss_tint": np.array(tint, dtype=np.float32).reshape(-1, 3),
        "gloss_roughness": np.array(rough, dtype=np.float32),
    }


def check_lights(exported: ExportedScene) -> None:
    """Refuses a scene where nothing emits light: no light with power, a black world (or none)
    and no emissive material. A scene lit by the world or by emissive meshes alone is fine."""
    if exported.emitters():
        return
    if exported.lights:
        raise ExportError(
            "every light has zero power, the world is black and no material emits: "
            "there is no light to bounce"
        )
    raise ExportError(
        "the scene has no lights that render: no light object, a black world and no emissive "
        "material (add a light, a world colour or texture, or an Emission shader)"
    )


def export_native(
    bl_scene: bpy.types.Scene,
    stage: Callable[[str], AbstractContextManager[None]],
    log: Callable[[str], None],
    eyes: np.ndarray | None = None,
    looks: np.ndarray | None = None,
) -> tuple[ExportedScene, vplace.Scene]:
    """The scene stage: the exported scene (its warnings logged), refused when nothing emits,
    and its ``vplace.Scene`` with the BVH and the working scale of the region seen from
    ``eyes``, the cameras' positions, looking along ``looks`` (:func:`build_scene`; logged
    where it is less than the bounds'). ``stage`` is the job timer's ``stage``."""
    with stage("export scene"):
        exported = export_scene(bl_scene)
    for warning in exported.warnings:
        log(f"[vplace] warning: {warning}")
    check_lights(exported)
    with stage("build BVH"):
        scene = build_scene(exported, eyes, looks)
    if scene.scale < scene.diagonal:
        m = exported.unit_scale
        log(
            f"[vplace] VPL sizes and the sun's and the world's light follow the region the "
            f"cameras see ({scene.scale * m:.3g} m), not the scene's bounds "
            f"({scene.diagonal * m:.3g} m across: geometry no camera sees)"
        )
    return exported, scene
