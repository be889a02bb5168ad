"""The world's light as export reads it (``world.py``): a colour, an environment image with its
rotation, what is baked, and the native world light built from it."""

import math

import bpy
import numpy as np
import pytest
from blender_util import empty_file

from addon.compat import new_world
from addon.scene import world as world_mod
from addon.scene.convert import native_world


@pytest.fixture
def world():
    empty_file()
    w = new_world("w")
    bpy.context.scene.world = w
    return w


def background(w):
    return w.node_tree.nodes["Background"]


def env_image(w, h=8, width=16):
    img = bpy.data.images.new("env", width, h, float_buffer=True)
    px = np.zeros((h, width, 4), np.float32)
    px[..., 0] = np.arange(h)[:, None]  # red = Blender's row (bottom first)
    px[..., 1] = np.arange(width)[None, :]
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.ravel())
    nt = w.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = img
    nt.links.new(env.outputs["Color"], background(w).inputs["Color"])
    return env


def test_no_world_and_uniform_colour(world):
    assert world_mod.world_info(None) is None
    background(world).inputs["Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    background(world).inputs["Strength"].default_value = 2.5
    info = world_mod.world_info(world)
    assert info.source == "color" and info.image is None and info.emits
    np.testing.assert_allclose(info.color, (0.5, 1.0, 1.5), rtol=1e-6)
    assert native_world(info).kind == "world"
    background(world).inputs["Strength"].default_value = 0.0
    assert not world_mod.world_info(world).emits


def test_environment_image_rows_strength_and_rotation(world):
    env = env_image(world)
    background(world).inputs["Strength"].default_value = 3.0
    info = world_mod.world_info(world)
    assert info.source == "image" and info.rotation is None and info.warnings == []
    assert info.image.shape == (8, 16, 3) and info.color == (3.0, 3.0, 3.0)
    # Row 0 is the top (+Z): Blender's last row.
    np.testing.assert_array_equal(info.image[0, :, 0], 7.0)
    np.testing.assert_array_equal(info.image[:, 5, 1], 5.0)
    assert native_world(info).kind == "world"
    # A Mapping rotation about Z (Point type, fed by Generated coordinates) is read exactly.
    nt = world.node_tree
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30))
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    info = world_mod.world_info(world)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    np.testing.assert_allclose(info.rotation, [[c, -s, 0], [s, c, 0], [0, 0, 1]], atol=1e-6)
    # A location cannot be a rotation: baked (or, without baking, the viewport colour).
    mapping.inputs["Location"].default_value = (1.0, 0.0, 0.0)
    info = world_mod.world_info(world, bake=False)
    assert info.source == "color" and "Mapping node with a location" in info.warnings[0]


def test_environment_image_without_pixels_or_image(world):
    env = env_image(world)
    env.image = None
    info = world_mod.world_info(world)
    assert not info.emits  # Cycles renders it black
    missing = bpy.data.images.new("missing", 4, 4, float_buffer=True)
    missing.source = "FILE"
    missing.filepath = "/nonexistent/sky.exr"
    missing.reload()
    env.image = missing
    info = world_mod.world_info(world)
    assert info.color[1] == 0.0 and "no pixels" in info.warnings[0]  # magenta, as Cycles


def test_other_node_trees_are_baked_or_named(world):
    nt = world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    nt.links.new(sky.outputs["Color"], background(world).inputs["Color"])
    info = world_mod.world_info(world, bake=False)
    assert "Sky Texture" in info.warnings[0] and info.image is None
    # Bakes are cached by the node tree: a change of any input is a new bake key.
    before = world_mod._tree_signature(world)
    sky.sun_elevation += 0.1
    assert world_mod._tree_signature(world) != before


def test_native_world_rejects_what_the_core_cannot_use(world):
    env_image(world)
    info = world_mod.world_info(world)
    info.image[0, 0, 0] = np.nan
    with pytest.raises(Exception, match="image"):
        native_world(info)


def sky_world(world, elevation_deg, rotation_deg):
    nt = world.node_tree
    sky = nt.nodes.get("Sky") or nt.nodes.new("ShaderNodeTexSky")
    sky.name = "Sky"
    sky.sun_elevation = math.radians(elevation_deg)
    sky.sun_rotation = math.radians(rotation_deg)
    nt.links.new(sky.outputs["Color"], background(world).inputs["Color"])
    return sky


def solid_angles(h, w, r0=0, r1=None):
    """Solid angle of each row's pixels of an (h, w) equirectangular map, rows r0..r1."""
    r1 = h if r1 is None else r1
    theta = (np.arange(r0, r1) + 0.5) / h * math.pi
    return (np.sin(theta) * (math.pi / h) * (2 * math.pi / w))[:, None]


def window_render(world, shape, rows, cols, factor, samples):
    """Baked-map pixels rows x cols of a map of ``shape`` rendered ``factor`` times finer,
    box-filtered back (columns may run past the edges)."""
    h, w = shape
    (r0, r1), (c0, c1) = rows, cols
    lat = (math.pi / 2 - math.pi * r1 / h, math.pi / 2 - math.pi * r0 / h)
    lon = (-math.pi + 2 * math.pi * c0 / w, -math.pi + 2 * math.pi * c1 / w)
    fine = world_mod._render_world(
        world, ((c1 - c0) * factor, (r1 - r0) * factor), samples, (*lat, *lon)
    )
    return fine.reshape(r1 - r0, factor, c1 - c0, factor, 3).mean(axis=(1, 3))


def test_a_window_of_the_bake_is_the_same_pixels_also_across_the_seam(world):
    """The restricted camera's latitudes and longitudes land on the bake's own pixels: a
    window of sky rendered again finer matches the bake's pixels there, and one across the
    map's left and right edge matches both ends."""
    sky_world(world, 30.0, 90.0)  # the sun far from both windows
    world_mod._BAKED.clear()
    image = world_mod.bake_world(world)
    h, w = image.shape[:2]
    inner = window_render(world, (h, w), (100, 104), (300, 306), 2, 16)
    np.testing.assert_allclose(inner, image[100:104, 300:306], rtol=0.02)
    seam = window_render(world, (h, w), (110, 113), (-3, 3), 2, 16)
    np.testing.assert_allclose(seam, image[110:113, np.arange(-3, 3) % w], rtol=0.02)


@pytest.mark.parametrize(
    ("elevation", "rotation"), [(45.0, 185.0), (31.0, 222.0), (24.0, 236.0), (20.0, 270.0)]
)
def test_the_baked_sun_carries_its_power_on_every_sun_position(world, elevation, rotation):
    """A Sky Texture's sun disc (0.55 deg) is smaller than a baked pixel (0.70 deg): the bake
    renders its pixels again finer, so the sun's light in the map is that of a render 16 times
    finer at 64 samples within 1 % wherever the sun stands (at 64 samples a pixel, the former
    bake, it was off by up to 5 % as the sun moved). (20, 270) puts the sun on the map's seam.
    The sun is where ``sky_sun_directions`` says."""
    sky_world(world, elevation, rotation)
    world_mod._BAKED.clear()
    image = world_mod.bake_world(world)
    h, w = image.shape[:2]
    lum = image @ np.array([0.2126, 0.7152, 0.0722])
    ((d, diameter),) = world_mod.sky_sun_directions(world)
    assert diameter == pytest.approx(world.node_tree.nodes["Sky"].sun_size)
    row, col = world_mod._direction_pixel(d, (w, h))
    top = np.unravel_index(np.argmax(lum), lum.shape)
    assert (
        abs(int(top[0]) - row) <= 1 and min((int(top[1]) - col) % w, (col - int(top[1])) % w) <= 1
    )
    rows = (row - 3, row + 4)
    cols = (col - 5, col + 6)
    ref = window_render(world, (h, w), rows, cols, 16, 64) @ np.array([0.2126, 0.7152, 0.0722])
    got = lum[rows[0] : rows[1], np.arange(*cols) % w]
    omega = solid_angles(h, w, *rows)
    assert (got * omega).sum() == pytest.approx((ref * omega).sum(), rel=0.01)


def test_a_sun_the_tree_does_not_name_is_found_by_its_brightness(world):
    """A Sky Texture behind a Mapping node (so its sun's direction is not read from the node):
    the bake finds the sun as its brightest pixel and renders it again finer all the same."""
    sky = sky_world(world, 31.0, 222.0)
    nt = world.node_tree
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(40))
    coords = nt.nodes.new("ShaderNodeTexCoord")
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], sky.inputs[0])
    assert world_mod.sky_sun_directions(world) == []
    world_mod._BAKED.clear()
    image = world_mod.bake_world(world)
    h, w = image.shape[:2]
    lum = image @ np.array([0.2126, 0.7152, 0.0722])
    row, col = (int(i) for i in np.unravel_index(np.argmax(lum), lum.shape))
    rows, cols = (row - 3, row + 4), (col - 5, col + 6)
    ref = window_render(world, (h, w), rows, cols, 16, 64) @ np.array([0.2126, 0.7152, 0.0722])
    got = lum[rows[0] : rows[1], np.arange(*cols) % w]
    omega = solid_angles(h, w, *rows)
    assert (got * omega).sum() == pytest.approx((ref * omega).sum(), rel=0.01)
