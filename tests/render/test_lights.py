"""Every light source: the direct-light estimator (``vplace.direct_light``) against Cycles'
Diffuse Direct pass on a small scene per kind, within 5 % relative RMSE.

Each scene is a floor, two walls and a box casting a shadow, diffuse albedo 0.7, seen from
above at 32 x 32 pixels, lit by one kind of light as Blender exports it (``export.py``,
``world.py``): point lights with and without a radius (soft falloff and sphere), a spot with
blend and radius, area lights of every shape and a spread, suns with and without an angle, a
uniform world, an environment image with a Mapping rotation, a Sky Texture (baked), a world
seen through a window of a closed room, and emissive meshes (an Emission shader and a
Principled BSDF's emission). Cycles renders with a point pixel filter (:data:`POINT_FILTER`):
each pixel then holds the light at the point its Position pass names, as the estimator computes
it. Compared: the covered pixels with a diffuse colour that lie on one
surface: not a box-filtered mix of two normals, and not at a silhouette (a pixel whose position
jumps to a neighbour's by more than 3 times the median step: Cycles' pixel there covers a near
and a far surface while its Position pass names one point). Cycles' noise is measured from two
renders with different seeds; it must be well below the bound. Relative RMSE =
``|ours - cycles| / |cycles|`` over those pixels (Frobenius norms).

Run ``pytest tests/render/test_lights.py -m slow -s`` for the table of measured numbers.
"""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from blender_util import add_lamp, empty_file

from addon.capture import passes as capture
from addon.capture.native_view import view_of
from addon.compat import new_material, new_world
from addon.native import vplace
from addon.scene import export
from addon.scene.convert import build_scene

RES = (32, 32)
ALBEDO = 0.7
#: Samples per pixel of the estimator (per emitter, for the sampled kinds).
OURS_SAMPLES = 512


def diffuse(name: str, color=(ALBEDO, ALBEDO, ALBEDO)) -> bpy.types.Material:
    mat = new_material(name)
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    mat.node_tree.links.new(bsdf.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat


def add_mesh(scene, name, verts, faces, mat) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def box(scene, name, lo, hi, mat) -> bpy.types.Object:
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    f = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return add_mesh(scene, name, v, f, mat)


def set_world(scene, color=(0, 0, 0), strength=0.0) -> bpy.types.World:
    world = new_world("world")
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    scene.world = world
    return world


def stage(*, room: bool = False) -> bpy.types.Scene:
    """The floor, walls and shadowing box; ``room`` closes it into a 4 x 4 x 3 m room with a
    window in the +X wall and a hole in the ceiling, the camera inside."""
    empty_file()
    scene = bpy.context.scene
    mat = diffuse("grey")
    add_mesh(scene, "floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [(0, 1, 2, 3)], mat)
    add_mesh(scene, "back", [(-2, 2, 0), (2, 2, 0), (2, 2, 3), (-2, 2, 3)], [(0, 1, 2, 3)], mat)
    add_mesh(scene, "left", [(-2, -2, 0), (-2, 2, 0), (-2, 2, 3), (-2, -2, 3)], [(0, 1, 2, 3)], mat)
    box(scene, "box", (-0.2, -0.1, 0.0), (0.5, 0.6, 0.8), mat)
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    if room:
        # +X wall with a 1.6 x 1.2 window, the front wall, a ceiling with a 1 x 1 hole.
        verts = [(2, -2, 0), (2, 2, 0), (2, 2, 3), (2, -2, 3)]
        verts += [(2, -0.8, 0.9), (2, 0.8, 0.9), (2, 0.8, 2.1), (2, -0.8, 2.1)]
        faces = [(0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
        add_mesh(scene, "right", verts, faces, mat)
        add_mesh(
            scene, "front", [(-2, -2, 0), (2, -2, 0), (2, -2, 3), (-2, -2, 3)], [(0, 1, 2, 3)], mat
        )
        verts = [(-2, -2, 3), (2, -2, 3), (2, 2, 3), (-2, 2, 3)]
        verts += [(-0.5, 0.5, 3), (0.5, 0.5, 3), (0.5, 1.5, 3), (-0.5, 1.5, 3)]
        add_mesh(
            scene, "ceiling", verts, [(0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)], mat
        )
        cam_data.lens = 14
        cam.location = (0.0, -1.9, 2.8)
        cam.rotation_euler = (math.radians(40), 0.0, 0.0)
    else:
        cam_data.lens = 45
        cam.location = (0.0, -5.0, 4.5)
        cam.rotation_euler = (math.radians(48), 0.0, 0.0)
    set_world(scene)
    return scene


def sky_image(w=64, h=32) -> bpy.types.Image:
    """A float equirectangular sky: a blue-to-white gradient and a bright patch (a sun)."""
    img = bpy.data.images.new("sky", w, h, float_buffer=True)
    v = (np.arange(h) + 0.5) / h  # 0 at the bottom row (Blender stores bottom-first)
    u = (np.arange(w) + 0.5) / w
    px = np.zeros((h, w, 4), np.float32)
    up = np.clip((v - 0.5) * 2.0, 0.0, 1.0)[:, None]
    px[..., 0] = 0.3 + 0.5 * up
    px[..., 1] = 0.35 + 0.45 * up
    px[..., 2] = 0.5 + 0.6 * up
    px[v < 0.5] *= 0.3  # a darker ground
    sun = (np.abs(v[:, None] - 0.78) < 0.06) & (np.abs(u[None, :] - 0.3) < 0.04)
    px[sun, :3] = (60.0, 55.0, 45.0)
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.ravel())
    img.pack()
    return img


def env_world(scene, *, rotation_z: float = 0.0) -> None:
    world = set_world(scene, strength=1.0)
    nt = world.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = sky_image()
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    if rotation_z:
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, rotation_z)
        coords = nt.nodes.new("ShaderNodeTexCoord")
        nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])


def sky_world(scene) -> None:
    world = set_world(scene, strength=0.3)
    nt = world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sun_elevation = math.radians(35)
    sky.sun_rotation = math.radians(60)
    nt.links.new(sky.outputs["Color"], nt.nodes["Background"].inputs["Color"])


def emissive_panel(scene, *, principled: bool) -> None:
    mat = new_material("panel")
    nodes = mat.node_tree.nodes
    if principled:
        p = nodes["Principled BSDF"]
        p.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        p.inputs["Emission Color"].default_value = (1.0, 0.8, 0.5, 1.0)
        p.inputs["Emission Strength"].default_value = 6.0
    else:
        nodes.remove(nodes["Principled BSDF"])
        em = nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = (0.6, 0.8, 1.0, 1.0)
        em.inputs["Strength"].default_value = 8.0
        mat.node_tree.links.new(em.outputs[0], nodes["Material Output"].inputs["Surface"])
    # A tilted 1.2 x 0.6 panel above the floor, and a small cube emitting on every side.
    add_mesh(
        scene,
        "panel",
        [(-1.2, -0.6, 1.9), (0.0, -0.6, 2.2), (0.0, 0.0, 2.2), (-1.2, 0.0, 1.9)],
        [(0, 1, 2, 3)],
        mat,
    )
    box(scene, "glow", (1.2, -0.8, 0.3), (1.5, -0.5, 0.6), mat)


def _down(pitch_deg: float, yaw_deg: float = 0.0) -> tuple[float, float, float]:
    return (math.radians(pitch_deg), 0.0, math.radians(yaw_deg))


#: kind -> (set-up, Cycles samples per render). Lamps sit at 2-3 m over the 4 m floor.
KINDS = {
    "point": (lambda s: add_lamp(s, "POINT", (0.8, -0.6, 2.4), 400.0, shadow_soft_size=0.0), 256),
    "point radius (soft falloff)": (
        lambda s: add_lamp(s, "POINT", (0.8, -0.6, 2.0), 400.0, shadow_soft_size=0.5),
        512,
    ),
    "point radius (sphere)": (
        lambda s: add_lamp(
            s, "POINT", (0.8, -0.6, 2.0), 400.0, shadow_soft_size=0.5, use_soft_falloff=False
        ),
        512,
    ),
    "spot blend radius": (
        lambda s: add_lamp(
            s,
            "SPOT",
            (-0.6, -1.2, 2.6),
            900.0,
            _down(35, -20),
            spot_size=math.radians(70),
            spot_blend=0.5,
            shadow_soft_size=0.15,
        ),
        512,
    ),
    "area square": (lambda s: add_lamp(s, "AREA", (0.3, -0.4, 2.4), 500.0, size=1.0), 512),
    "area rectangle": (
        lambda s: add_lamp(
            s,
            "AREA",
            (0.3, -0.4, 2.4),
            500.0,
            (0.3, 0.0, 0.5),
            shape="RECTANGLE",
            size=1.4,
            size_y=0.4,
        ),
        512,
    ),
    "area disk": (
        lambda s: add_lamp(s, "AREA", (0.3, -0.4, 2.4), 500.0, shape="DISK", size=1.0),
        512,
    ),
    "area ellipse": (
        lambda s: add_lamp(
            s,
            "AREA",
            (0.3, -0.4, 2.4),
            500.0,
            (0.0, -0.3, 0.7),
            shape="ELLIPSE",
            size=1.5,
            size_y=0.5,
        ),
        512,
    ),
    "area spread": (
        lambda s: add_lamp(
            s,
            "AREA",
            (0.0, -0.6, 2.2),
            500.0,
            (0.4, 0.0, 0.0),
            shape="RECTANGLE",
            size=1.6,
            size_y=0.8,
            spread=math.radians(50),
        ),
        1024,
    ),
    "sun": (lambda s: add_lamp(s, "SUN", (0, 0, 5), 3.0, (0.6, 0.3, 0.4), angle=0.0), 128),
    "sun angle": (
        lambda s: add_lamp(s, "SUN", (0, 0, 5), 3.0, (0.6, 0.3, 0.4), angle=math.radians(15)),
        512,
    ),
    "world color": (lambda s: set_world(s, (0.6, 0.7, 1.0), 1.5), 512),
    "world image": (lambda s: env_world(s, rotation_z=math.radians(40)), 1024),
    "world sky (baked)": (sky_world, 1024),
    "emission shader": (lambda s: emissive_panel(s, principled=False), 1024),
    "principled emission": (lambda s: emissive_panel(s, principled=True), 1024),
}
#: Kinds seen from inside the closed room (light through its window and ceiling hole).
ROOM_KINDS = {
    "world image through a window": (lambda s: env_world(s, rotation_z=math.radians(-30)), 2048),
}


def silhouettes(position: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Pixels whose position jumps to a 4-neighbour's by more than 3 median steps."""
    h, w = covered.shape
    jump = np.zeros((h, w))
    for dy, dx in ((0, 1), (1, 0)):
        step = np.linalg.norm(position[: h - dy, : w - dx] - position[dy:, dx:], axis=-1)
        both = covered[: h - dy, : w - dx] & covered[dy:, dx:]
        step = np.where(both, step, np.inf)
        jump[: h - dy, : w - dx] = np.maximum(jump[: h - dy, : w - dx], step)
        jump[dy:, dx:] = np.maximum(jump[dy:, dx:], step)
    median = np.median(jump[covered & np.isfinite(jump)])
    return jump > 3.0 * median


def relative_rmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    return float(np.linalg.norm((a - b)[mask]) / np.linalg.norm(b[mask]))


#: Cycles' pixel filter width in the comparison renders: a point, so that each pixel's light is
#: that of the point its Position pass names (with the capture's 1-pixel box, a pixel on a sharp
#: shadow edge averages lit and shadowed floor while the estimator shades one point).
POINT_FILTER = 0.01


@pytest.fixture
def point_pixels(monkeypatch):
    """Captures with a point pixel filter (:data:`POINT_FILTER`) instead of the 1-pixel box."""
    configure = capture._configure

    def point_configure(g, scene, *args, **kwargs):
        configure(g, scene, *args, **kwargs)
        # Cycles' box filter is always one pixel wide; a narrow Gaussian is a point.
        g.set(scene.cycles, "pixel_filter_type", "GAUSSIAN")
        g.set(scene.cycles, "filter_width", POINT_FILTER)

    monkeypatch.setattr(capture, "_configure", point_configure)


def compare(kind: str, setup, samples: int, room: bool) -> tuple[float, float, int]:
    scene = stage(room=room)
    setup(scene)
    bpy.context.view_layer.update()
    exported = export.export_scene(scene)
    native = build_scene(exported)
    a = capture.capture(scene, resolution=RES, samples=samples, seed=1)
    b = capture.capture(scene, resolution=RES, samples=samples, seed=2)
    mixed = np.abs(np.linalg.norm(a.normal, axis=-1) - 1.0) > 1e-3
    diffuse_px = a.diffuse_color.max(axis=-1) > 0.5 * ALBEDO
    mask = a.covered & diffuse_px & ~mixed & ~silhouettes(a.position, a.covered)
    cycles = 0.5 * (a.diffuse_direct + b.diffuse_direct)
    noise = relative_rmse(a.diffuse_direct, b.diffuse_direct, mask) / 2.0
    ours = vplace.direct_light(native, view_of(a), samples=OURS_SAMPLES, seed=3)
    error = relative_rmse(ours, cycles, mask)
    print(
        f"\n| {kind} | {error:.4f} | {noise:.4f} | {int(mask.sum())} | {samples} x 2 |"
        f" {exported.warnings or ''}"
    )
    return error, noise, int(mask.sum())


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kind", "room"), [(k, False) for k in KINDS] + [(k, True) for k in ROOM_KINDS]
)
def test_direct_light_matches_cycles(kind, room, point_pixels):
    setup, samples = (ROOM_KINDS if room else KINDS)[kind]
    error, noise, pixels = compare(kind, setup, samples, room)
    assert pixels > 0.4 * RES[0] * RES[1], f"only {pixels} pixels compared"
    assert noise < 0.02, f"Cycles noise {noise:.3f} too high to test a 5% agreement"
    assert error < 0.05, f"{kind}: relative RMSE {error:.4f} (Cycles noise {noise:.4f})"
