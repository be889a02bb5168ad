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
