"""Materials against Cycles on the light-test stage (``test_lights.py``), 32 x 32 pixels with a
point pixel filter:

- a textured floor (an 8-bit sRGB checker image through a Mapping scale, so it repeats): the
  albedo the core looks up at each camera ray's hit (``Scene.albedo_at`` through the exported
  UVs) against Cycles' Diffuse Color pass;
- an alpha-cut card (a texture's alpha into the Principled Alpha) between a sun and the floor:
  ``vplace.direct_light`` against Cycles' Diffuse Direct pass, the card's shadow with holes.

Both within 5 % relative RMSE over the compared pixels of ``test_lights.compare``.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from blender_util import add_lamp
from test_lights import (
    OURS_SAMPLES,
    RES,
    point_pixels,  # noqa: F401 (a fixture)
    relative_rmse,
    silhouettes,
    stage,
)

from addon.capture import passes as capture
from addon.capture.native_view import view_of
from addon.compat import new_material
from addon.native import vplace
from addon.scene import export
from addon.scene.convert import build_scene


def checker(name: str, n: int = 4, *, alpha: bool = False, texels: int = 64) -> bpy.types.Image:
    """An 8-bit sRGB checker of ``n`` x ``n`` squares of ``texels`` x ``texels`` texels in two
    colours; with ``alpha``, the dark squares are cut (alpha 0). Texels in a square are equal,
    so interpolation blends colours only at a square's edge (Cycles interpolates 8-bit sRGB
    images before it linearizes them, the core after)."""
    size = n * texels
    img = bpy.data.images.new(name, size, size, alpha=alpha)
    i, j = np.indices((size, size)) // texels
    dark = (i + j) % 2 == 0
    px = np.ones((size, size, 4), np.float32)
    px[dark, :3] = (0.2, 0.35, 0.6)
    px[~dark, :3] = (0.9, 0.7, 0.3)
    if alpha:
        px[dark, 3] = 0.0
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def textured(name: str, image: bpy.types.Image, scale: float, *, cut: bool) -> bpy.types.Material:
    mat = new_material(name)
    nt = mat.node_tree
    p = nt.nodes["Principled BSDF"]
    p.inputs["Roughness"].default_value = 1.0
    p.inputs["Specular IOR Level"].default_value = 0.0
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (scale, scale, 1.0)
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    if cut:
        nt.links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
    return mat


def uv_quad(scene, name, corners, mat) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, co in zip(mesh.loops, [(0, 0), (1, 0), (1, 1), (0, 1)], strict=True):
        uv.data[loop.index].uv = co
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def textured_floor(scene) -> None:
    floor = bpy.data.objects["floor"]
    mat = textured("checker floor", checker("floor checker"), 2.0, cut=False)
    floor.data.materials.clear()
    floor.data.materials.append(mat)
    uv = floor.data.uv_layers.new(name="UVMap")
    for loop in floor.data.loops:
        co = floor.data.vertices[loop.vertex_index].co
        uv.data[loop.index].uv = ((co.x + 2) / 4, (co.y + 2) / 4)


def mask(cap: capture.Capture) -> np.ndarray:
    mixed = np.abs(np.linalg.norm(cap.normal, axis=-1) - 1.0) > 1e-3
    return cap.covered & ~mixed & ~silhouettes(cap.position, cap.covered)


@pytest.mark.slow
def test_textured_albedo_per_hit_matches_cycles(point_pixels):  # noqa: F811
    scene = stage()
    add_lamp(scene, "SUN", (0, 0, 5), 3.0, (0.6, 0.3, 0.4))
    textured_floor(scene)
    bpy.context.view_layer.update()
    exported = export.export_scene(scene)
    native = build_scene(exported)
    assert native.texture_count == 1
    cap = capture.capture(scene, resolution=RES, samples=16, seed=1)
    floor_px = mask(cap) & (np.abs(cap.position[..., 2]) < 1e-3) & (cap.normal[..., 2] > 0.99)
    cam = np.array(scene.camera.matrix_world.translation, np.float32)
    targets = cap.position[floor_px].astype(np.float32)
    dirs = (targets - cam).astype(np.float32)
    origins = np.tile(cam, (len(dirs), 1)).astype(np.float32)
    _, tri, bary = native.intersect(origins, dirs)
    assert (tri >= 0).all()
    ours = native.albedo_at(tri.astype(np.uint32), bary)
    cycles = cap.diffuse_color[floor_px]
    error = relative_rmse(ours, cycles, np.ones(len(ours), bool))
    print(f"\n| textured albedo per hit | {error:.4f} | {len(ours)} px |")
    assert len(ours) > 0.25 * RES[0] * RES[1]
    # Both colours of the checker are seen, not its mean.
    assert np.ptp(ours[:, 0]) > 0.5
    assert error < 0.05, f"relative RMSE {error:.4f}"


@pytest.mark.slow
def test_alpha_cut_shadow_matches_cycles(point_pixels):  # noqa: F811
    scene = stage()
    add_lamp(scene, "SUN", (0, 0, 5), 3.0, (math.radians(20), 0.0, math.radians(30)))
    mat = textured("leaf", checker("leaf checker", alpha=True), 1.0, cut=True)
    corners = [(-1.5, -1.6, 1.2), (0.2, -1.6, 1.2), (0.2, 0.0, 1.2), (-1.5, 0.0, 1.2)]
    uv_quad(scene, "card", corners, mat)
    bpy.context.view_layer.update()
    exported = export.export_scene(scene)
    native = build_scene(exported)
    assert native.has_alpha_tests
    a = capture.capture(scene, resolution=RES, samples=256, seed=1)
    b = capture.capture(scene, resolution=RES, samples=256, seed=2)
    # The floor and walls (grey, albedo 0.7) outside the card.
    m = mask(a) & (np.abs(a.diffuse_color - 0.7).max(axis=-1) < 0.05)
    cycles = 0.5 * (a.diffuse_direct + b.diffuse_direct)
    noise = relative_rmse(a.diffuse_direct, b.diffuse_direct, m) / 2.0
    ours = vplace.direct_light(native, view_of(a), samples=OURS_SAMPLES, seed=3)
    error = relative_rmse(ours, cycles, m)
    print(f"\n| alpha-cut card shadow | {error:.4f} | {noise:.4f} | {int(m.sum())} px |")
    assert m.sum() > 0.3 * RES[0] * RES[1] and noise < 0.02
    assert error < 0.05, f"relative RMSE {error:.4f} (Cycles noise {noise:.4f})"
