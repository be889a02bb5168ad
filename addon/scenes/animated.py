"""Two animated built-in scenes built from code (issue 23), for ``demo --animate``:

- ``cornell_moving``: the Cornell box (``registry.build_cornell_moving``: the box, then
  :func:`key_cornell_lamp`) with its ceiling lamp keyed to slide from the left half of the
  ceiling to the right (:data:`CORNELL_LAMP_PATH`, x in metres) while its power falls to
  :data:`CORNELL_LAMP_DIM` of the original over frames :data:`FRAMES`.
- ``skyroom_afternoon``: the sky-lit room (:func:`.rooms.build_skyroom`) with the Sky
  Texture's sun keyed to sweep from the south, high, to the west, low
  (:data:`SKY_SUN_ROTATIONS`, :data:`SKY_SUN_ELEVATIONS`) over the same frames, so its
  patches through the south windows cross the floor and climb the north wall.

Every key is linear, so the lighting changes evenly from frame to frame. The scene's frame
range is set to :data:`FRAMES`; the file is saved at its first frame.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy

from ..compat import make_keys_linear
from .rooms import REPO, _write, build_skyroom

CORNELL_MOVING_BLEND = REPO / "blend_scenes" / "cornell_moving" / "cornell_moving.blend"
SKYROOM_AFTERNOON_BLEND = REPO / "blend_scenes" / "skyroom_afternoon" / "skyroom_afternoon.blend"
#: The animation's first and last frame (both scenes).
FRAMES = (1, 24)
#: The Cornell lamp's x (metres) at the first and the last frame; it stays under the ceiling.
CORNELL_LAMP_PATH = (-0.55, 0.55)
#: The Cornell lamp's power at the last frame, as a fraction of its power at the first.
CORNELL_LAMP_DIM = 0.4
#: The sky's sun at the first and the last frame (radians): rotation (about +Z; 180 degrees
#: puts the sun in the south of this room) and elevation.
SKY_SUN_ROTATIONS = (math.radians(185.0), math.radians(250.0))
SKY_SUN_ELEVATIONS = (math.radians(45.0), math.radians(18.0))
#: The names of what is keyed.
CORNELL_LAMP = "light"
SKY_NODE = "Sky Texture"


def _frame_range(scene: bpy.types.Scene) -> None:
    scene.frame_start, scene.frame_end = FRAMES
    scene.frame_set(FRAMES[0])


def key_cornell_lamp(scene: bpy.types.Scene) -> bpy.types.Object:
    """Keys the Cornell box's lamp in ``scene`` (built by ``registry.build_cornell_box``) to
    move and dim over :data:`FRAMES` (see the module docs); returns the lamp."""
    lamp = scene.objects[CORNELL_LAMP]
    power = lamp.data.energy
    for frame, x, energy in zip(
        FRAMES, CORNELL_LAMP_PATH, (power, power * CORNELL_LAMP_DIM), strict=True
    ):
        lamp.location.x = x
        lamp.keyframe_insert("location", index=0, frame=frame)
        lamp.data.energy = energy
        lamp.data.keyframe_insert("energy", frame=frame)
    make_keys_linear(lamp)
    make_keys_linear(lamp.data)
    _frame_range(scene)
    return lamp


def build_skyroom_afternoon(scene: bpy.types.Scene | None = None) -> bpy.types.Scene:
    """Adds the sky-lit room with its sun sweeping (see the module docs)."""
    scene = build_skyroom(scene)
    tree = scene.world.node_tree
    sky = tree.nodes[SKY_NODE]
    for frame, rotation, elevation in zip(
        FRAMES, SKY_SUN_ROTATIONS, SKY_SUN_ELEVATIONS, strict=True
    ):
        sky.sun_rotation = rotation
        sky.sun_elevation = elevation
        sky.keyframe_insert("sun_rotation", frame=frame)
        sky.keyframe_insert("sun_elevation", frame=frame)
    make_keys_linear(tree)
    _frame_range(scene)
    return scene


def write_skyroom_afternoon_blend(blend_path: Path = SKYROOM_AFTERNOON_BLEND) -> Path:
    """Builds ``skyroom_afternoon`` in a fresh file and saves it to ``blend_path``."""
    return _write(build_skyroom_afternoon, blend_path)
